"""Frozen pure-Python reference of Magnetorquer-v0's control step (the implementation before
the compiled kernel of :mod:`attitude_envs.plants.magnetorquer_kernels`), kept to test the
kernel against: same equations, written independently with NumPy and Python floats.

:class:`ReferenceStepper` mirrors a freshly reset env (its state, orbit, field, reference,
inertia and disturbance) and advances it with the old code path: Kepler's equation, the
dipole field, the smooth bang-bang reference, the gyrostat equations with one wheel, RK4
with the stage cost as an extra state, quaternion renormalization after every sub-step.
"""

from __future__ import annotations

import numpy as np

from attitude_envs import quaternion
from attitude_envs.disturbances import Disturbance
from attitude_envs.plants import magnetorquer_kernels as kernels

E_Y = np.array([0.0, 1.0, 0.0])


def _horner(coefs, x: float) -> float:
    acc = 0.0
    for c in coefs:
        acc = acc * x + c
    return acc


def _orbital_to_body(q):
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)],
            [2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)],
            [2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _derivative(y, inertia, inertia_eff_inv, j_w, t_w, torque, nu_dot, nu_ddot):
    x, yq, z, s, w0, w1, w2, om = (float(v) for v in y[:8])
    r0, r1, r2 = 2 * (x * yq + z * s), 1 - 2 * (x * x + z * z), 2 * (yq * z - x * s)
    a0, a1, a2 = -nu_dot * r0, -nu_dot * r1, -nu_dot * r2
    b0, b1, b2 = w0 + a0, w1 + a1, w2 + a2
    (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = inertia.tolist()
    h0 = i00 * b0 + i01 * b1 + i02 * b2
    h1 = i10 * b0 + i11 * b1 + i12 * b2 + j_w * om
    h2 = i20 * b0 + i21 * b1 + i22 * b2
    t0, t1, t2 = (float(v) for v in torque)
    c0 = -(b1 * h2 - b2 * h1) + t0
    c1 = -(b2 * h0 - b0 * h2) + t1 + t_w
    c2 = -(b0 * h1 - b1 * h0) + t2
    (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = inertia_eff_inv.tolist()
    d0 = e00 * c0 + e01 * c1 + e02 * c2
    d1 = e10 * c0 + e11 * c1 + e12 * c2
    d2 = e20 * c0 + e21 * c1 + e22 * c2
    return np.array(
        [
            0.5 * (s * w0 + yq * w2 - z * w1),
            0.5 * (s * w1 + z * w0 - x * w2),
            0.5 * (s * w2 + x * w1 - yq * w0),
            -0.5 * (x * w0 + yq * w1 + z * w2),
            d0 + (w1 * a2 - w2 * a1) + nu_ddot * r0,
            d1 + (w2 * a0 - w0 * a2) + nu_ddot * r1,
            d2 + (w0 * a1 - w1 * a0) + nu_ddot * r2,
            -t_w / j_w - d1,
        ]
    )


class ReferenceStepper:
    """The old Python step of a reset ``MagnetorquerEnv`` (``env.unwrapped``).

    The random-walk disturbance is evaluated per stage from the current walk value (the
    kernel's reading: the value is held over the control step that drew it).
    """

    def __init__(self, env) -> None:
        self.env = env
        o = env.orbit
        self.orbit = o
        self.y = env.state_row.copy()
        self.steps = 0
        ref = env.model.reference
        self.ref = ref
        inertia = env.episode_constants[kernels.EN_INERTIA : kernels.EN_INERTIA + 9]
        self.inertia = inertia.reshape(3, 3).copy()  # this episode's drawn inertia, without ΔJ(t)
        self.delta_j = env.time_varying_inertia
        p = env.model.params
        self.j_w, self.h_max = p.wheel_inertia_kg_m2, p.max_wheel_momentum_nms
        eff = self.inertia.copy()
        eff[1, 1] -= self.j_w
        self.eff_inv_const = np.linalg.inv(eff)
        self.Q, self.R = env.model.cost.Q, env.model.cost.R

    # ------------------------------------------------------------------ time-only context
    def true_anomaly(self, t):
        o = self.orbit
        mean = o.mean_anomaly0_rad + o.mean_motion_rad_s * t
        if o.e == 0.0:
            return float(mean)
        ecc = mean + o.e * np.sin(mean)
        for _ in range(30):
            step = (ecc - o.e * np.sin(ecc) - mean) / (1.0 - o.e * np.cos(ecc))
            ecc -= step
            if abs(step) < 1e-13:
                break
        return float(2.0 * np.arctan2(np.sqrt(1 + o.e) * np.sin(ecc / 2), np.sqrt(1 - o.e) * np.cos(ecc / 2)))

    def orbit_state(self, t):
        o = self.orbit
        if o.model == "circular":
            u = float(o.arg_perigee_rad + o.mean_anomaly0_rad + o.mean_motion_rad_s * t)
            r, r_dot, nu_dot, nu_ddot = o.a, 0.0, o.mean_motion_rad_s, 0.0
        else:
            nu = self.true_anomaly(t)
            u = float(o.arg_perigee_rad + nu)
            r = o._p / (1.0 + o.e * np.cos(nu))
            nu_dot = o._h / r**2
            r_dot = o.mu / o._h * o.e * np.sin(nu)
            nu_ddot = -2.0 * nu_dot * r_dot / r
        r_hat = o._node * np.cos(u) + o._in_plane * np.sin(u)
        t_hat = -o._node * np.sin(u) + o._in_plane * np.cos(u)
        frame = np.column_stack([t_hat, -o._normal, -r_hat])
        return {
            "position": r * r_hat,
            "r": float(r),
            "u": u,
            "rate": float(nu_dot),
            "rate_dot": float(nu_ddot),
            "frame": frame,
        }

    def field_orbital(self, t, orb):
        f = self.env.field
        if f.model == "dipole-printed":
            i = self.orbit.inclination_rad
            si = np.sin(i)
            return (
                f.strength / orb["r"] ** 3 * np.array([np.cos(orb["u"]) * si, np.cos(i), -2.0 * np.sin(orb["u"]) * si])
            )
        if f.model == "igrf":
            k = min(int(t / f.igrf_step_s), len(f._table_b) - 2)
            w = (t - k * f.igrf_step_s) / f.igrf_step_s
            b_eci = (1.0 - w) * f._table_b[k] + w * f._table_b[k + 1]
        else:
            pos = orb["position"]
            r = float(np.linalg.norm(pos))
            r_hat = pos / r
            m_hat = np.array([0.0, 0.0, -1.0])
            b_eci = f.strength / r**3 * (3.0 * float(m_hat @ r_hat) * r_hat - m_hat)
        return orb["frame"].T @ b_eci

    def reference(self, t):
        ref = self.ref
        if ref._constant or t <= 0.0:
            t = 0.0
        elif t >= ref.t_final_s:
            t = ref.t_final_s
        p, v = 0.0, 0.0
        if t > 0.0:
            for _a, b, _f, vc, pc in ref._pieces:
                if t <= b:
                    p, v = _horner(pc, t), _horner(vc, t)
                    break
        ang, rate = ref.start_rad + ref.gain * p, ref.gain * v
        q_d = quaternion.from_euler_321_deg(*np.degrees(ang))
        if q_d[3] < 0:
            q_d = -q_d
        phi, theta, _ = ang
        dphi, dtheta, dpsi = rate
        sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta)
        w_d = np.array([dphi - dpsi * st, dtheta * cf + dpsi * sf * ct, -dtheta * sf + dpsi * cf * ct])
        return q_d, w_d

    def true_inertia(self, t):
        if self.delta_j is None:
            return self.inertia
        d = self.delta_j
        return self.inertia + np.diag(d.amplitude_kg_m2 * np.sin(d.frequency_rad_s * t + d.phase_rad))

    def disturbance(self, t):
        env = self.env
        dist = env.disturbance
        if env.paper_disturbance:
            w0 = env.model.orbital_rate_rad_s
            k = 2.0 if env.disturbance_second_harmonic else 1.0
            a, b, q = w0 * t, k * w0 * t, np.pi / 4
            d = np.array(
                [
                    1e-7 + 1e-5 * np.sin(a + q) + 1e-5 * np.sin(b - q),
                    1e-7 + 1e-5 * np.sin(a - q) + 1e-5 * np.sin(b + q),
                    1e-7 + 1e-5 * np.sin(a) + 1e-5 * np.sin(b + 2 * q),
                ]
            )
            return env.disturbance_scale * d
        if isinstance(dist, Disturbance):
            return env.disturbance_scale * dist.torque_nm_at(t)
        return np.zeros(3)

    def context(self, t):
        orb = self.orbit_state(t)
        inertia = self.true_inertia(t)
        if self.delta_j is None:
            eff_inv = self.eff_inv_const
        else:
            eff = inertia.copy()
            eff[1, 1] -= self.j_w
            eff_inv = np.linalg.inv(eff)
        q_d, w_d = self.reference(t)
        return orb, self.field_orbital(t, orb), q_d, w_d, inertia, eff_inv, self.disturbance(t)

    # ------------------------------------------------------------------ dynamics
    def augmented(self, t, aug, m, t_w):
        x, y, z, w = aug[:4] / np.sqrt(aug[:4] @ aug[:4])
        w0, w1, w2 = aug[4:7]
        orb, b_orb, q_d, w_d, inertia, eff_inv, dist = self.context(t)
        b = _orbital_to_body([x, y, z, w]) @ b_orb
        tau = _cross(m, b)
        ext = dist
        if self.env.gravity_gradient:
            o = _orbital_to_body([x, y, z, w])[:, 2]
            ext = ext + 3.0 * 3.986004418e14 / orb["r"] ** 3 * _cross(o, inertia @ o)
        dy = _derivative(aug, inertia, eff_inv, self.j_w, t_w, tau + ext, orb["rate"], orb["rate_dot"])
        q_e = quaternion.error(np.array([x, y, z, w]), q_d)
        w_e = np.array([w0, w1, w2]) - quaternion.to_matrix(q_e).T @ w_d
        u = tau + E_Y * t_w
        xe = np.concatenate([q_e[:3], w_e])
        return np.append(dy, xe @ self.Q @ xe + u @ self.R @ u)

    def step(self, delivered):
        """Advance one control step with the delivered command (4, physical units);
        returns ``(cost, applied (4), magnetic torque mean (3))``."""
        env = self.env
        h, n_sub = env.integrator_dt_s, env._substeps
        m = np.asarray(delivered[:3], dtype=float)
        aug = np.append(self.y, 0.0)
        t0 = self.steps * env.control_dt_s
        wheel_sum, tau_sum = 0.0, np.zeros(3)
        for j in range(n_sub):
            ts = t0 + j * h
            orb, b_orb = self.context(ts)[:2]
            w_bi = aug[4:7] + _orbital_to_body(aug[:4])[:, 1] * (-orb["rate"])
            h_w = self.j_w * (aug[7] + w_bi[1])
            t_w = float(delivered[3])
            if abs(h_w) >= self.h_max and -t_w * h_w > 0:
                t_w = 0.0
            wheel_sum += t_w
            tau_sum += _cross(m, _orbital_to_body(aug[:4]) @ b_orb)

            def f(t, yy, t_w=t_w):
                return self.augmented(t, yy, m, t_w)

            k1 = f(ts, aug)
            k2 = f(ts + 0.5 * h, aug + 0.5 * h * k1)
            k3 = f(ts + 0.5 * h, aug + 0.5 * h * k2)
            k4 = f(ts + h, aug + h * k3)
            aug = aug + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            aug[:4] /= np.linalg.norm(aug[:4])
        self.steps += 1
        self.y = aug[:-1]
        return float(aug[-1]), np.append(m, wheel_sum / n_sub), tau_sum / n_sub

    def error_state(self):
        t = self.steps * self.env.control_dt_s
        q_d, w_d = self.reference(t)
        q_e = quaternion.error(self.y[:4], q_d)
        return np.concatenate([q_e[:3], self.y[4:7] - quaternion.to_matrix(q_e).T @ w_d])
