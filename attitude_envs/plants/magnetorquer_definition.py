"""The magnetorquer plant's dynamics, defined once (Sadigh, Kashaninia & Dehghan 2022, eqs. 1–8
with the consistent wheel bookkeeping of :mod:`attitude_envs.plants.magnetorquer`): the
orbital-to-body rotation, the gravity gradient, the error state, the stage cost, the wheel's
momentum limit and the augmented derivative ``d/dt [q, ω_bo, Ω, cost]``, written on scalars
against an :class:`~attitude_envs.plants.ops.Ops`, and the pieces of its time context (the
Kepler orbit's rates, the dipole and as-printed field models, the slew reference, the
inverse inertia, the paper's disturbance). :func:`define` returns them for one
executor: the numba kernels (:mod:`attitude_envs.plants.magnetorquer_kernels`), the JAX twin
(:mod:`attitude_envs.jax.magnetorquer`) and the CasADi model
(:mod:`attitude_envs.symbolic.magnetorquer`) are built from it.

The time-dependent quantities (orbit rate, field, reference, true inertia, disturbance) come
in a *time context*: a flat vector whose entries each executor lays out its own way, named by
a layout tuple of offsets (``L_*`` positions in it): ``(ν̇ rad/s, ν̈ rad/s², r m, b_orb (3, T),
q_d (4), ω_d (3, rad/s; right after q_d), I (3×3 row-major, kg·m²), I_eff⁻¹ (3×3, 1/(kg·m²)),
disturbance (3, N·m))``. :data:`COMPACT_LAYOUT` packs them in that order
(:data:`COMPACT_SIZE` entries).

Augmented state ``z`` (9): ``[q (4, scalar last, body relative to orbital), ω_bo (3, rad/s),
Ω (wheel speed relative to the body, rad/s), ∫cost]``. Error state ``x = [q_e,vec, ω_e]``
(6); control torque ``u = m × b + e_y T_w`` (3, N·m).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

from attitude_envs.plants.ops import Ops, define_quad_form

GRAVITY_MU_M3_S2 = 3.986004418e14
N_AUG = 9
#: positions in a layout tuple
L_RATE, L_RATE_DOT, L_RADIUS, L_FIELD, L_QD, L_WD, L_INERTIA, L_EFF_INV, L_DIST = range(9)
#: the context entries packed in the order of the ``L_*`` names
COMPACT_LAYOUT = (0, 1, 2, 3, 6, 10, 13, 22, 31)
COMPACT_SIZE = 34


@functools.cache
def define(ops: Ops) -> SimpleNamespace:
    """The magnetorquer plant's functions for the executor ``ops`` (cached per executor).
    Flags: ``gravity`` may be a runtime or traced boolean (selected with ``ops.where``);
    ``diagonal`` and ``flip`` are plain Python booleans for the tracing executors (JAX,
    CasADi) and may be runtime booleans under numba."""
    sin, cos, sqrt, fabs, where = ops.sin, ops.cos, ops.sqrt, ops.fabs, ops.where
    quad_form = define_quad_form(ops)

    @ops.compile
    def body_vector(x, y, z, w, v0, v1, v2):
        """``R v`` with ``R`` (orbital → body) of Sadigh et al. 2022 eq. (4), scalar-last q."""
        return (
            (1 - 2 * (y * y + z * z)) * v0 + 2 * (x * y + z * w) * v1 + 2 * (x * z - y * w) * v2,
            2 * (x * y - z * w) * v0 + (1 - 2 * (x * x + z * z)) * v1 + 2 * (y * z + x * w) * v2,
            2 * (x * z + y * w) * v0 + 2 * (y * z - x * w) * v1 + (1 - 2 * (x * x + y * y)) * v2,
        )

    @ops.compile
    def gravity_gradient(x, y, z, w, inertia, ib, radius):
        """``3μ/r³ ô × (I ô)`` (N·m), ô the nadir (orbital z) in body axes, ``I`` row-major at
        ``inertia[ib:]``, ``radius`` the orbit radius (m)."""
        o0, o1, o2 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        p0 = inertia[ib] * o0 + inertia[ib + 1] * o1 + inertia[ib + 2] * o2
        p1 = inertia[ib + 3] * o0 + inertia[ib + 4] * o1 + inertia[ib + 5] * o2
        p2 = inertia[ib + 6] * o0 + inertia[ib + 7] * o1 + inertia[ib + 8] * o2
        k = 3.0 * GRAVITY_MU_M3_S2 / radius**3
        return k * (o1 * p2 - o2 * p1), k * (o2 * p0 - o0 * p2), k * (o0 * p1 - o1 * p0)

    @ops.compile
    def external_torque(qx, qy, qz, qw, ctx, cb, lay, gravity):
        """The external torque (N·m, body axes) at the unit attitude ``q``: the context's
        disturbance plus, where ``gravity``, the gravity gradient."""
        d = cb + lay[L_DIST]
        g0, g1, g2 = gravity_gradient(qx, qy, qz, qw, ctx, cb + lay[L_INERTIA], ctx[cb + lay[L_RADIUS]])
        return (
            where(gravity, ctx[d] + g0, ctx[d]),
            where(gravity, ctx[d + 1] + g1, ctx[d + 1]),
            where(gravity, ctx[d + 2] + g2, ctx[d + 2]),
        )

    @ops.compile
    def error_state(x, y, z, w, w0, w1, w2, ref, base, flip):
        """``q_e = q_d* ⊗ q`` and ``ω_e = ω − C(q_e)ᵀ ω_d`` with ``[q_d, ω_d] =
        ref[base : base + 7]``: the 7 numbers ``(q_e,x, q_e,y, q_e,z, ω_e (3), q_e,w)``. With
        ``flip``, q_e's sign is chosen with w ≥ 0 (without, the caller's cost must not depend
        on that sign: no cross terms between q_e,vec and ω_e)."""
        dx, dy, dz, dw = ref[base], ref[base + 1], ref[base + 2], ref[base + 3]
        ex = dw * x - dx * w - dy * z + dz * y
        ey = dw * y - dy * w - dz * x + dx * z
        ez = dw * z - dz * w - dx * y + dy * x
        ew = dw * w + dx * x + dy * y + dz * z
        if flip:
            sign = where(ew < 0.0, -1.0, 1.0)
            ex, ey, ez, ew = sign * ex, sign * ey, sign * ez, sign * ew
        r0, r1, r2 = body_vector(ex, ey, ez, ew, ref[base + 4], ref[base + 5], ref[base + 6])
        return ex, ey, ez, w0 - r0, w1 - r1, w2 - r2, ew

    @ops.compile
    def stage_cost(Q, R, x, u, diagonal):
        """``xᵀQx + uᵀRu`` for the error state ``x`` (6) and control torque ``u`` (3, N·m);
        with ``diagonal`` (Q and R diagonal) the zero products are skipped (the same sums)."""
        if diagonal:
            total = 0.0
            for i in range(6):
                total += Q[i, i] * x[i] * x[i]
            for i in range(3):
                total += R[i, i] * u[i] * u[i]
            return total
        return quad_form(R, u, 3, quad_form(Q, x, 6))

    @ops.compile
    def wheel_torque(t_w, x, z, w_bo_y, wheel_speed, rate, j_w, h_max):
        """The wheel torque on the body (N·m) the momentum limit lets through: zero when the
        wheel momentum ``h_w = J_w (Ω + ω_bi,y)`` (``ω_bi = ω_bo − ν̇ R e_y``) is at
        ``|h_w| ≥ h_max`` (N·m·s, the storable momentum of the paper's Table 1) and ``t_w``
        would grow it; ``x, z`` the attitude's entries, ``rate`` ν̇ (rad/s)."""
        w_bi_y = w_bo_y + (1 - 2 * (x * x + z * z)) * (-rate)
        h_w = j_w * (wheel_speed + w_bi_y)
        blocked = where(fabs(h_w) >= h_max, -t_w * h_w > 0, False)
        return where(blocked, 0.0, t_w)

    @ops.compile
    def augmented(z, zb, m, t_w, ctx, cb, lay, j_w, gravity, Q, R, diagonal, flip):
        """``d/dt [q, ω_bo, Ω, cost]`` (9 values) at ``z[zb : zb + 9]`` with the time context
        ``ctx[cb:]`` laid out as ``lay``: dipole moments ``m`` (3, A·m²) against the field,
        wheel torque ``t_w`` on the body about +y (N·m), the disturbance and, where
        ``gravity``, the gravity gradient; J_w ``j_w`` (kg·m²); the stage cost (Q on x, R on
        u)."""
        x, y, zq, w = z[zb], z[zb + 1], z[zb + 2], z[zb + 3]
        w0, w1, w2, om = z[zb + 4], z[zb + 5], z[zb + 6], z[zb + 7]
        n = 1.0 / sqrt(x * x + y * y + zq * zq + w * w)
        qx, qy, qz, qw = x * n, y * n, zq * n, w * n
        f = cb + lay[L_FIELD]
        b0, b1, b2 = body_vector(qx, qy, qz, qw, ctx[f], ctx[f + 1], ctx[f + 2])
        tau0, tau1, tau2 = m[1] * b2 - m[2] * b1, m[2] * b0 - m[0] * b2, m[0] * b1 - m[1] * b0  # m × b (eq. 8)
        e0, e1, e2 = external_torque(qx, qy, qz, qw, ctx, cb, lay, gravity)
        # gyrostat equations (the raw quaternion, as integrated); R e_y is row 1 of to_matrix(q)
        r0, r1, r2 = 2 * (x * y + zq * w), 1 - 2 * (x * x + zq * zq), 2 * (y * zq - x * w)
        nd = ctx[cb + lay[L_RATE]]
        a0, a1, a2 = -nd * r0, -nd * r1, -nd * r2  # R ω_oi
        c0, c1, c2 = w0 + a0, w1 + a1, w2 + a2  # ω_bi
        i = cb + lay[L_INERTIA]
        h0 = ctx[i] * c0 + ctx[i + 1] * c1 + ctx[i + 2] * c2
        h1 = ctx[i + 3] * c0 + ctx[i + 4] * c1 + ctx[i + 5] * c2 + j_w * om
        h2 = ctx[i + 6] * c0 + ctx[i + 7] * c1 + ctx[i + 8] * c2
        s0 = -(c1 * h2 - c2 * h1) + (tau0 + e0)
        s1 = -(c2 * h0 - c0 * h2) + (tau1 + e1) + t_w
        s2 = -(c0 * h1 - c1 * h0) + (tau2 + e2)
        i = cb + lay[L_EFF_INV]
        d0 = ctx[i] * s0 + ctx[i + 1] * s1 + ctx[i + 2] * s2
        d1 = ctx[i + 3] * s0 + ctx[i + 4] * s1 + ctx[i + 5] * s2
        d2 = ctx[i + 6] * s0 + ctx[i + 7] * s1 + ctx[i + 8] * s2
        ndd = ctx[cb + lay[L_RATE_DOT]]
        ex, ey, ez, we0, we1, we2, _ = error_state(qx, qy, qz, qw, w0, w1, w2, ctx, cb + lay[L_QD], flip)
        cost = stage_cost(Q, R, (ex, ey, ez, we0, we1, we2), (tau0, tau1 + t_w, tau2), diagonal)
        return (
            0.5 * (w * w0 + y * w2 - zq * w1),
            0.5 * (w * w1 + zq * w0 - x * w2),
            0.5 * (w * w2 + x * w1 - y * w0),
            -0.5 * (x * w0 + y * w1 + zq * w2),
            d0 + (w1 * a2 - w2 * a1) + ndd * r0,
            d1 + (w2 * a0 - w0 * a2) + ndd * r1,
            d2 + (w0 * a1 - w1 * a0) + ndd * r2,
            -t_w / j_w - d1,
            cost,
        )

    @ops.compile
    def limit_rows(w0, w1, w2, max_rate_rad_s):
        """The tumbling limit as 6 rows ``g ≤ 0`` (inside): ``±ω_bo,i − max_rate`` (rad/s); the
        limit is crossed when a row is > 0."""
        return (
            w0 - max_rate_rad_s,
            -w0 - max_rate_rad_s,
            w1 - max_rate_rad_s,
            -w1 - max_rate_rad_s,
            w2 - max_rate_rad_s,
            -w2 - max_rate_rad_s,
        )

    # ------------------------------------------------------------------ the time context
    @ops.compile
    def kepler_rates(nu, e, h, p, mu):
        """``(r (m), ν̇ (rad/s), ṙ (m/s), ν̈ (rad/s²))`` of a Kepler orbit at true anomaly
        ``nu`` (rad): eccentricity ``e``, specific angular momentum ``h`` (m²/s), semi-latus
        rectum ``p`` (m), gravitational parameter ``mu`` (m³/s²)."""
        r = p / (1.0 + e * cos(nu))
        nu_dot = h / r**2
        r_dot = mu / h * e * sin(nu)
        return r, nu_dot, r_dot, -2.0 * nu_dot * r_dot / r

    @ops.compile
    def dipole_eci(px, py, pz, strength_t_m3):
        """Axial dipole ``μ_e/r³ [3(m̂·r̂)r̂ − m̂]``, ``m̂ = −z``, at an ECI position (m), tesla."""
        r = sqrt(px * px + py * py + pz * pz)
        rx, ry, rz = px / r, py / r, pz / r
        k = strength_t_m3 / r**3
        s = 3.0 * (-rz)
        return k * (s * rx), k * (s * ry), k * (s * rz + 1.0)

    @ops.compile
    def printed_field(radius, u, strength_t_m3, inclination_rad):
        """The field in the orbital frame as Sadigh et al. 2022 print it (eq. 9), tesla, at
        orbit radius ``radius`` (m) and argument of latitude ``u`` (rad)."""
        si = sin(inclination_rad)
        k = strength_t_m3 / radius**3
        return k * (cos(u) * si), k * cos(inclination_rad), k * (-2.0 * sin(u) * si)

    @ops.compile
    def euler_reference(p, v, phi0, theta0, psi0, g0, g1, g2):
        """``(q_d (4, scalar last, w ≥ 0), ω_d (3, rad/s))`` of the 3-2-1 slew at profile values
        ``p = ∫∫f`` and ``v = ∫f`` (Sadigh et al. 2022 eqs. 36–38): angles ``start + gain·p``
        (rad), the quaternion through degrees as
        :func:`attitude_envs.quaternion.from_euler_321_deg` computes it."""
        phi, theta, psi = phi0 + g0 * p, theta0 + g1 * p, psi0 + g2 * p
        dphi, dtheta, dpsi = g0 * v, g1 * v, g2 * v
        deg, rad = 180.0 / math.pi, math.pi / 180.0
        hf, ht, hp = (phi * deg) * rad * 0.5, (theta * deg) * rad * 0.5, (psi * deg) * rad * 0.5
        sf, cf, st, ct = sin(hf), cos(hf), sin(ht), cos(ht)
        sp, cp = sin(hp), cos(hp)
        qx = sf * ct * cp - cf * st * sp
        qy = cf * st * cp + sf * ct * sp
        qz = cf * ct * sp - sf * st * cp
        qw = cf * ct * cp + sf * st * sp
        sign = where(qw < 0.0, -1.0, 1.0)
        sf, cf, st, ct = sin(phi), cos(phi), sin(theta), cos(theta)
        return (
            sign * qx,
            sign * qy,
            sign * qz,
            sign * qw,
            dphi - dpsi * st,
            dtheta * cf + dpsi * sf * ct,
            -dtheta * sf + dpsi * cf * ct,
        )

    @ops.compile
    def inverse3(m, base):
        """``inv`` of the 3×3 row-major matrix ``m[base : base + 9]`` by its adjugate (9 values)."""
        a, b, c = m[base], m[base + 1], m[base + 2]
        d, e, f = m[base + 3], m[base + 4], m[base + 5]
        g, h, i = m[base + 6], m[base + 7], m[base + 8]
        c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
        inv_det = 1.0 / (a * c00 + b * c01 + c * c02)
        return (
            c00 * inv_det,
            (c * h - b * i) * inv_det,
            (b * f - c * e) * inv_det,
            c01 * inv_det,
            (a * i - c * g) * inv_det,
            (c * d - a * f) * inv_det,
            c02 * inv_det,
            (b * g - a * h) * inv_det,
            (a * e - b * d) * inv_det,
        )

    @ops.compile
    def paper_disturbance(scale, sin_a_p, sin_a_m, sin_b_m, sin_b_p, sin_a, sin_b_2q):
        """Sadigh et al. 2022 eq. (39), N·m: ``d_j = d0 + d1 sin(ω0 t + φ_j1) + d2 sin(k ω0 t +
        φ_j2)`` (d0 = 1e-7, d1 = d2 = 1e-5; φ_x = ±π/4, φ_y = ∓π/4, φ_z = (0, π/2)) times
        ``scale``, from the sines of ``a = ω0 t`` and ``b = k ω0 t``: ``sin(a ± π/4)``,
        ``sin(b ∓ π/4)``, ``sin a``, ``sin(b + π/2)`` (the caller may reuse ``a``'s for ``k = 1``)."""
        return (
            scale * (1e-7 + 1e-5 * sin_a_p + 1e-5 * sin_b_m),
            scale * (1e-7 + 1e-5 * sin_a_m + 1e-5 * sin_b_p),
            scale * (1e-7 + 1e-5 * sin_a + 1e-5 * sin_b_2q),
        )

    return SimpleNamespace(
        kepler_rates=kepler_rates,
        dipole_eci=dipole_eci,
        printed_field=printed_field,
        euler_reference=euler_reference,
        inverse3=inverse3,
        paper_disturbance=paper_disturbance,
        limit_rows=limit_rows,
        body_vector=body_vector,
        gravity_gradient=gravity_gradient,
        external_torque=external_torque,
        error_state=error_state,
        stage_cost=stage_cost,
        wheel_torque=wheel_torque,
        augmented=augmented,
    )
