"""ReactionWheel-v0 and AirBearing-v0 as a :class:`~attitude_envs.symbolic.problem.DiscreteProblem`.

The step of :func:`attitude_envs.plants.gyrostat_kernels.step_kernel`, written out in CasADi:
state ``[q (4, scalar last), ω (3, rad/s), Ω (N, rad/s)]``; the action clipped to [−1, 1] and
scaled by the torque limit (``action_frame="body"``: the minimum-norm allocation
``u = −A⁺T``, each wheel clipped); the episode's known actuator faults at the step's start
time; then ``n_substeps`` classical RK4 sub-steps of ``integrator_dt_s`` with the motor
torque held (after the motor driver's wheel-speed limiter at each sub-step's start), the
stage cost ``xᵀQx + u_cᵀRu_c`` integrated as an extra state, the quaternion renormalized
after each sub-step. Equations (:mod:`attitude_envs.plants.gyrostat`)::

    I_eff ω̇ = −ω × (I ω + J_s A Ω) − A u + T_ext + p × K(q)
    Ω̇ = u / J_s − Aᵀ ω̇,    q̇ = ½ q ⊗ [ω, 0]

with the episode's true inertia (``kernel_matrices``), ``p`` the true plant's offset torque
(``true_offset_torque_nm``; Ahangarani Farahani et al., eqs. 6–9) and ``T_ext`` a constant or sinusoidal disturbance.
The tumble limit, the roll/pitch stop and the wheel-speed limit are the path constraint ``g``.
"""

from __future__ import annotations

import math

import casadi
import numpy as np

from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.problem import DiscreteProblem


def build_reaction_wheel(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped ReactionWheel-v0, just reset) starts."""
    return _build(env)


def build_air_bearing(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped AirBearing-v0, just reset) starts."""
    return _build(env)


def _disturbance(env):
    """``T_ext(t)`` as a function of an SX time (N·m), or None; ValueError for a random walk."""
    d = env.disturbance
    if d is None:
        return None
    if d.kind == "constant":
        torque = casadi.DM(np.asarray(d.torque_nm, dtype=float))
        return lambda t: torque
    if d.kind == "sinusoidal":
        amp, phase = np.asarray(d.amplitude_nm, dtype=float), np.array(d.episode_phase_rad, dtype=float)
        period = float(d.period_s)
        return lambda t: casadi.vertcat(*[amp[c] * casadi.sin(2 * np.pi * t / period + phase[c]) for c in range(3)])
    raise ValueError(f"disturbance kind must be 'constant' or 'sinusoidal' for a symbolic model, got {d.kind!r}")


def _error_state(z, target: np.ndarray, j_s: float, include_h: bool, n: int):
    """``[q_e,vec, ω, (J_s Ω)]`` with ``q_e = q_T* ⊗ q/|q|``, sign so that ``q_e,w ≥ 0``."""
    q = z[0:4] / casadi.norm_2(z[0:4])
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    px, py, pz, pw = -target[0], -target[1], -target[2], target[3]
    ex = pw * qx + px * qw + py * qz - pz * qy
    ey = pw * qy - px * qz + py * qw + pz * qx
    ez = pw * qz + px * qy - py * qx + pz * qw
    ew = pw * qw - px * qx - py * qy - pz * qz
    sign = casadi.if_else(ew < 0.0, -1.0, 1.0)
    parts = [sign * casadi.vertcat(ex, ey, ez), z[4:7]]
    if include_h:
        parts.append(j_s * z[7 : 7 + n])
    return casadi.vertcat(*parts)


def _build(env) -> DiscreteProblem:
    model = env.model
    p = model.params
    n = p.n_wheels
    axes = casadi.DM(p.wheel_axes)
    j_s = float(p.wheel_inertia_kg_m2)
    max_torque, max_speed = float(p.max_wheel_torque_nm), float(p.max_wheel_speed_rad_s)
    offset = np.array(env.true_offset_torque_nm, dtype=float)  # the true plant's (may differ from the model's)
    mats = np.array(env.kernel_matrices, dtype=float)  # this episode's true inertia
    inertia, inertia_eff_inv = casadi.DM(mats[:9].reshape(3, 3)), casadi.DM(mats[9:18].reshape(3, 3))
    q_mat, r_mat = casadi.DM(model.cost.Q), casadi.DM(model.cost.R)
    include_h, body_input = model.include_wheel_momentum, model.cost_input == "body"
    h, n_sub, dt = float(env.integrator_dt_s), int(env.n_substeps), float(env.control_dt_s)
    target = np.array(env.target_attitude, dtype=float)
    ext = _disturbance(env)
    actuators.check_supported(env.fault_layer.realized)

    def derivative(y, u, t_ext):
        q, w, wheel = y[0:4], y[4:7], y[7 : 7 + n]
        mom = casadi.mtimes(inertia, w) + j_s * casadi.mtimes(axes, wheel)
        r = -casadi.mtimes(axes, u) - casadi.cross(w, mom)
        if t_ext is not None:
            r = r + t_ext
        if np.any(offset != 0.0):
            qx, qy, qz, qw = q[0], q[1], q[2], q[3]
            k_dir = casadi.vertcat(
                2.0 * (qx * qz - qy * qw), 2.0 * (qy * qz + qx * qw), 1.0 - 2.0 * (qx * qx + qy * qy)
            )
            r = r + casadi.cross(casadi.DM(offset), k_dir)
        w_dot = casadi.mtimes(inertia_eff_inv, r)
        qx, qy, qz, qw = q[0], q[1], q[2], q[3]
        w0, w1, w2 = w[0], w[1], w[2]
        q_dot = 0.5 * casadi.vertcat(
            qw * w0 + qy * w2 - qz * w1,
            qw * w1 + qz * w0 - qx * w2,
            qw * w2 + qx * w1 - qy * w0,
            -(qx * w0 + qy * w1 + qz * w2),
        )
        wheel_dot = u / j_s - casadi.mtimes(axes.T, w_dot)
        return casadi.vertcat(q_dot, w_dot, wheel_dot)

    def stage_cost(y):
        x = _error_state(y, target, j_s, include_h, n)
        return casadi.bilin(q_mat, x, x)

    n_x = 7 + n
    y = casadi.SX.sym("y", n_x)
    n_u = env.action_space.shape[0]
    a = casadi.SX.sym("a", n_u)
    k = casadi.SX.sym("k")
    t0 = k * dt  # the env's time: steps · control_dt_s
    a_c = actuators.clip(a, -1.0, 1.0)
    if env.action_frame == "body":
        torque = casadi.mtimes(casadi.DM(model.allocation * max_torque), a_c)
        commanded = actuators.clip(torque, -max_torque, max_torque)
    else:
        commanded = a_c * max_torque
    cmd = actuators.delivered(commanded, t0, env.fault_layer.realized, env.fault_layer.limits)

    z, cost = y, casadi.SX(0.0)
    for j in range(n_sub):
        v = actuators.clip(cmd, -max_torque, max_torque)
        if np.isfinite(max_speed):  # the motor driver's speed limiter (gyrostat_kernels._speed_limit_lane)
            wheel = z[7 : 7 + n]
            v = actuators.clip(
                actuators.clip(v, j_s / h * (-max_speed - wheel), j_s / h * (max_speed - wheel)),
                -max_torque,
                max_torque,
            )
        u_c = -casadi.mtimes(axes, v) if body_input else v
        input_cost = casadi.bilin(r_mat, u_c, u_c)
        t_j = t0 + j * h
        ks, costs = [], []
        for stage, frac in enumerate((0.0, 0.5, 0.5, 1.0)):
            zs = z if stage == 0 else z + (h if stage == 3 else 0.5 * h) * ks[-1]
            t_ext = None if ext is None else ext(t_j + frac * h)
            ks.append(derivative(zs, v, t_ext))
            costs.append(stage_cost(zs) + input_cost)
        z = z + (h / 6.0) * (ks[0] + 2.0 * ks[1] + 2.0 * ks[2] + ks[3])
        cost = cost + (h / 6.0) * (costs[0] + 2.0 * costs[1] + 2.0 * costs[2] + costs[3])
        z = casadi.vertcat(z[0:4] / casadi.norm_2(z[0:4]), z[4:])
    step = casadi.Function("step", [y, a, k], [z, cost], ["x", "a", "k"], ["x_next", "cost"])

    # path constraints g(x) <= 0: tumble limit, wheel-speed limit, roll/pitch stop
    xs = casadi.SX.sym("x", n_x)
    g_parts = [(xs[4:7] / float(env.max_rate_rad_s)) ** 2 - 1.0]  # normalized: each entry O(1)
    notes = ["tumble limit max|ω| <= max_rate_rad_s as a state constraint"]
    if np.isfinite(max_speed):
        g_parts.append((xs[7:] / max_speed) ** 2 - 1.0)
        notes.append(
            "wheel-speed limit |Ω| <= max_wheel_speed_rad_s as a state constraint (the limiter is in the step)"
        )
    if env.tilt_limit_deg is not None:
        qx, qy, qz, qw = xs[0], xs[1], xs[2], xs[3]
        n2 = qx * qx + qy * qy + qz * qz + qw * qw
        s = 2.0 * (qw * qx + qy * qz)
        c = n2 - 2.0 * (qx * qx + qy * qy)
        sin_pitch = 2.0 * (qw * qy - qz * qx) / n2
        lim = math.radians(env.tilt_limit_deg)
        # |θ| <= L: sin²θ <= sin²L; |φ| <= L: c > 0 and s² <= tan²L c²
        g_parts += [sin_pitch**2 - math.sin(lim) ** 2, s**2 - math.tan(lim) ** 2 * c**2, -c]
        notes.append("roll/pitch stop as a state constraint")
    g = casadi.Function("g", [xs], [casadi.vertcat(*g_parts)], ["x"], ["g"])
    n_steps = int(math.ceil(env.episode_duration_s / dt - 1e-9))
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=n_x,
        n_u=n_u,
        n_steps=n_steps,
        step=step,
        x0=np.array(env.state_row, dtype=float),
        a_lb=-np.ones(n_u),
        a_ub=np.ones(n_u),
        g=g,
        notes="; ".join(notes),
    )
