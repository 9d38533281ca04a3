"""The discrete problem of Magnetorquer-v0 (the nano-satellite of Sadigh, Kashaninia & Dehghan
2022: three magnetorquers and one y wheel, attitude relative to the orbital frame) in CasADi.

The step is :func:`attitude_envs.plants.magnetorquer_kernels.control_step` written out: the
normalized action clipped to [-1, 1] and scaled by the limits (dipoles A·m², wheel torque
N·m), the episode's known actuator faults at the step's start ``t = k·control_dt_s`` (e.g.
the paper's effectiveness loss of eq. 40), the wheel torque blocked where it would raise
``|h_w|`` past the storable momentum, classical RK4 sub-steps of ``integrator_dt_s`` of the
gyrostat equations (eqs. 1–8, :mod:`attitude_envs.plants.magnetorquer`) with the stage cost
``xᵀQx + uᵀRu`` as an extra state, the quaternion renormalized after each sub-step.

Everything that depends on time only — the orbit (ν̇, ν̈, radius), the field along it in the
orbital frame (dipole, as printed, or the episode's IGRF table), the reference ``q_d, ω_d``,
the true inertia ``I + ΔJ(t)`` (eq. 35) with its ``I_eff⁻¹`` and the disturbance (eq. 39,
constant or sinusoidal) — does not depend on the actions: it is evaluated once per sub-step
stage by the env's own compiled :func:`~attitude_envs.plants.magnetorquer_kernels.context_into`
(from the public ``kernel_constants``, ``episode_constants`` and ``field.table``) and handed
to the step as the per-step parameters ``DiscreteProblem.params``: ``step(x_k, a_k, p_k)``
with ``p_k = [k, contexts of step k]`` (:func:`context_table`).

Horizon: the problem covers the env's ``episode_duration_s`` as configured. The paper's
episode (two orbits, 12 038 s at 0.1 s: 120 380 steps) is too long for one NLP; for J* use the
slew, ``episode_duration_s=1200`` (the reference's ``t_final_s``: 12 000 steps), or its first
part (e.g. 200–600 s) for quick solves.

Not represented (ValueError): a random-walk disturbance (drawn step by step from the env's
generator), intermittent faults and a ``stuck`` fault without a value.
"""

from __future__ import annotations

import math

import casadi
import numpy as np

from attitude_envs.plants import magnetorquer_kernels as kernels
from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.cost import quad_form
from attitude_envs.symbolic.problem import DiscreteProblem

# the time context entries the step reads (indices into a kernels context, layout CX_*)
_FIELDS = np.array(
    [kernels.CX_ORB + kernels.OS_RATE, kernels.CX_ORB + kernels.OS_RATE_DOT, kernels.CX_ORB + kernels.OS_R]
    + list(range(kernels.CX_B, kernels.CX_B + 3))
    + list(range(kernels.CX_QD, kernels.CX_QD + 7))  # q_d (4), ω_d (3)
    + list(range(kernels.CX_I, kernels.CX_I + 9))
    + list(range(kernels.CX_EINV, kernels.CX_EINV + 9))
    + list(range(kernels.CX_DIST, kernels.CX_DIST + 3))
)
N_FIELDS = len(_FIELDS)
_RATE, _RATE_DOT, _R, _B, _QD, _WD, _I, _EINV, _DIST = 0, 1, 2, 3, 6, 10, 13, 22, 31


def _body_vector(x, y, z, w, v0, v1, v2):
    """``R v`` (orbital → body, Sadigh et al. 2022 eq. 4), as the kernel's ``_body_vector``."""
    return (
        (1 - 2 * (y * y + z * z)) * v0 + 2 * (x * y + z * w) * v1 + 2 * (x * z - y * w) * v2,
        2 * (x * y - z * w) * v0 + (1 - 2 * (x * x + z * z)) * v1 + 2 * (y * z + x * w) * v2,
        2 * (x * z + y * w) * v0 + 2 * (y * z - x * w) * v1 + (1 - 2 * (x * x + y * y)) * v2,
    )


def _stage_cost(q_mat: np.ndarray, r_mat: np.ndarray, x: list, u: list):
    """``xᵀQx + uᵀRu`` in the kernel's ``stage_cost`` order (its diagonal fast path when diagonal)."""
    total = 0.0
    if np.array_equal(q_mat, np.diag(np.diag(q_mat))) and np.array_equal(r_mat, np.diag(np.diag(r_mat))):
        for i in range(6):
            if q_mat[i, i] != 0.0:
                total = total + float(q_mat[i, i]) * x[i] * x[i]
        for i in range(3):
            if r_mat[i, i] != 0.0:
                total = total + float(r_mat[i, i]) * u[i] * u[i]
        return total
    return quad_form(r_mat, u, quad_form(q_mat, x))


class _Plant:
    """The constants of one env configuration and episode the symbolic step needs."""

    def __init__(self, env) -> None:
        shared = np.asarray(env.kernel_constants, dtype=float)
        self.j_w = float(shared[kernels.SH_JW])
        self.h_max = float(shared[kernels.SH_HMAX])
        self.h = float(shared[kernels.SH_H])
        self.n_sub = int(shared[kernels.SH_NSUB])
        self.gravity_gradient = shared[kernels.SH_GG] != 0.0
        self.Q = np.asarray(env.model.cost.Q, dtype=float)
        self.R = np.asarray(env.model.cost.R, dtype=float)
        # the sign of q_e changes xᵀQx only through Q's cross terms between q_e,vec and ω_e
        self.flip_sign = bool(np.any(self.Q[:3, 3:] != 0.0))

    def augmented(self, z: list, m: list, t_w, c):
        """d/dt ``[q, ω_bo, Ω, cost]`` (kernels' ``augmented_derivative``) at ``z`` with the
        dipoles ``m`` (A·m²), wheel torque ``t_w`` (N·m) and the time context ``c`` (the
        ``_FIELDS`` entries)."""
        x, y, zq, w = z[0], z[1], z[2], z[3]
        w0, w1, w2, om = z[4], z[5], z[6], z[7]
        n = 1.0 / casadi.sqrt(x * x + y * y + zq * zq + w * w)
        qx, qy, qz, qw = x * n, y * n, zq * n, w * n
        b0, b1, b2 = _body_vector(qx, qy, qz, qw, c[_B], c[_B + 1], c[_B + 2])
        tau0, tau1, tau2 = m[1] * b2 - m[2] * b1, m[2] * b0 - m[0] * b2, m[0] * b1 - m[1] * b0
        e0, e1, e2 = c[_DIST], c[_DIST + 1], c[_DIST + 2]
        inertia = [c[_I + i] for i in range(9)]
        if self.gravity_gradient:
            g0, g1, g2 = self._gravity_gradient(qx, qy, qz, qw, inertia, c[_R])
            e0, e1, e2 = e0 + g0, e1 + g1, e2 + g2
        r0, r1, r2 = 2 * (x * y + zq * w), 1 - 2 * (x * x + zq * zq), 2 * (y * zq - x * w)
        nd = c[_RATE]
        a0, a1, a2 = -nd * r0, -nd * r1, -nd * r2
        c0, c1, c2 = w0 + a0, w1 + a1, w2 + a2
        h0 = inertia[0] * c0 + inertia[1] * c1 + inertia[2] * c2
        h1 = inertia[3] * c0 + inertia[4] * c1 + inertia[5] * c2 + self.j_w * om
        h2 = inertia[6] * c0 + inertia[7] * c1 + inertia[8] * c2
        s0 = -(c1 * h2 - c2 * h1) + (tau0 + e0)
        s1 = -(c2 * h0 - c0 * h2) + (tau1 + e1) + t_w
        s2 = -(c0 * h1 - c1 * h0) + (tau2 + e2)
        ei = [c[_EINV + i] for i in range(9)]
        d0 = ei[0] * s0 + ei[1] * s1 + ei[2] * s2
        d1 = ei[3] * s0 + ei[4] * s1 + ei[5] * s2
        d2 = ei[6] * s0 + ei[7] * s1 + ei[8] * s2
        ndd = c[_RATE_DOT]
        out = [
            0.5 * (w * w0 + y * w2 - zq * w1),
            0.5 * (w * w1 + zq * w0 - x * w2),
            0.5 * (w * w2 + x * w1 - y * w0),
            -0.5 * (x * w0 + y * w1 + zq * w2),
            d0 + (w1 * a2 - w2 * a1) + ndd * r0,
            d1 + (w2 * a0 - w0 * a2) + ndd * r1,
            d2 + (w0 * a1 - w1 * a0) + ndd * r2,
            -t_w / self.j_w - d1,
        ]
        err = self._error_state(qx, qy, qz, qw, w0, w1, w2, c)
        out.append(_stage_cost(self.Q, self.R, err, [tau0, tau1 + t_w, tau2]))
        return out

    def _error_state(self, x, y, z, w, w0, w1, w2, c) -> list:
        """``[q_e,vec, ω_e]``, ``q_e = q_d* ⊗ q`` (w ≥ 0), ``ω_e = ω − C(q_e)ᵀ ω_d`` (kernels' ``error_state``)."""
        dx, dy, dz, dw = c[_QD], c[_QD + 1], c[_QD + 2], c[_QD + 3]
        ex = dw * x - dx * w - dy * z + dz * y
        ey = dw * y - dy * w - dz * x + dx * z
        ez = dw * z - dz * w - dx * y + dy * x
        ew = dw * w + dx * x + dy * y + dz * z
        if self.flip_sign:  # otherwise the cost is exactly invariant to the sign
            sign = casadi.if_else(ew < 0, -1.0, 1.0)
            ex, ey, ez, ew = sign * ex, sign * ey, sign * ez, sign * ew
        r0, r1, r2 = _body_vector(ex, ey, ez, ew, c[_WD], c[_WD + 1], c[_WD + 2])
        return [ex, ey, ez, w0 - r0, w1 - r1, w2 - r2]

    @staticmethod
    def _gravity_gradient(x, y, z, w, inertia: list, radius):
        """``3μ/r³ ô × (I ô)`` (kernels' ``gravity_gradient``), N·m."""
        o0, o1, o2 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        p0 = inertia[0] * o0 + inertia[1] * o1 + inertia[2] * o2
        p1 = inertia[3] * o0 + inertia[4] * o1 + inertia[5] * o2
        p2 = inertia[6] * o0 + inertia[7] * o1 + inertia[8] * o2
        k = 3.0 * kernels.GRAVITY_MU_M3_S2 / radius**3
        return k * (o1 * p2 - o2 * p1), k * (o2 * p0 - o0 * p2), k * (o0 * p1 - o1 * p0)


def _check_supported(env) -> None:
    """ValueError for what the symbolic model does not represent."""
    if env.disturbance is not None and env.disturbance.kind not in ("constant", "sinusoidal"):
        raise ValueError(
            f"disturbance kind must be 'paper', 'constant' or 'sinusoidal' for a symbolic model, "
            f"got {env.disturbance.kind!r}"
        )
    actuators.check_supported(env.fault_layer.realized)


def context_table(env, n_steps: int) -> np.ndarray:
    """The time context of every sub-step stage of steps ``0 … n_steps − 1`` of the episode the
    unwrapped Magnetorquer-v0 ``env`` has just started: ``(n_steps, (2·n_sub + 1)·N_FIELDS)``,
    per step the contexts at ``t_j``, ``t_j + h/2`` for each sub-step ``j`` and at the step's end,
    at the same times the compiled step evaluates them."""
    _check_supported(env)
    shared = np.asarray(env.kernel_constants, dtype=float)
    episode = np.array(env.episode_constants, dtype=float)
    table = np.asarray(env.field.table, dtype=float)
    h, n_sub, dt = float(shared[kernels.SH_H]), int(shared[kernels.SH_NSUB]), float(env.control_dt_s)
    ctx = np.empty(kernels.CONTEXT_SIZE)
    out = np.empty((n_steps, 2 * n_sub + 1, N_FIELDS))
    for k in range(n_steps):
        t0, t1 = k * dt, (k + 1) * dt  # the env's times: steps · control_dt_s
        times = []
        for j in range(n_sub):
            ts = t0 + j * h
            times += [ts, ts + 0.5 * h]
        times.append(t1)
        for i, t in enumerate(times):
            kernels.context_into(t, shared, episode, table, ctx, 0)
            out[k, i] = ctx[_FIELDS]
    return out.reshape(n_steps, -1)


def step_function(env) -> casadi.Function:
    """The SX step ``(x (8), a (4), p (1 + (2·n_sub + 1)·N_FIELDS)) -> (x_next (8), cost (1))`` of
    the unwrapped ``env``'s episode, ``p = [k, the step's time contexts]`` (a row of
    :func:`step_parameters`)."""
    _check_supported(env)
    plant = _Plant(env)
    limits = np.asarray(env.model.params.limits, dtype=float)
    return _build_step(plant, limits, float(env.control_dt_s), env.fault_layer.realized)


def _build_step(plant: _Plant, limits: np.ndarray, control_dt_s: float, realized) -> casadi.Function:
    """The SX step of :func:`step_function` for ``plant`` (its ``h``, ``n_sub``), the actuator
    ``limits``, the control period (s) and the realized actuator faults ``realized`` (the
    fault layer's, or ``[]`` for a healthy model)."""
    y = casadi.SX.sym("y", 8)
    a = casadi.SX.sym("a", 4)
    p = casadi.SX.sym("p", 1 + (2 * plant.n_sub + 1) * N_FIELDS)
    commanded = actuators.clip(a, -1.0, 1.0) * casadi.DM(limits)
    cmd = actuators.delivered(commanded, p[0] * control_dt_s, realized, limits)
    m = [cmd[0], cmd[1], cmd[2]]
    h = plant.h
    aug = [y[i] for i in range(8)] + [0.0]
    for j in range(plant.n_sub):
        c0, c1, c2 = (p[1 + (2 * j + s) * N_FIELDS : 1 + (2 * j + s + 1) * N_FIELDS] for s in range(3))
        t_w = cmd[3]
        if math.isfinite(plant.h_max):  # the wheel's storable momentum (blocks torque that raises |h_w|)
            x, zq = aug[0], aug[2]
            h_w = plant.j_w * (aug[7] + (aug[5] + (1 - 2 * (x * x + zq * zq)) * (-c0[_RATE])))
            blocked = casadi.logic_and(casadi.fabs(h_w) >= plant.h_max, -t_w * h_w > 0)
            t_w = casadi.if_else(blocked, 0.0, t_w)
        k1 = plant.augmented(aug, m, t_w, c0)
        k2 = plant.augmented([aug[i] + 0.5 * h * k1[i] for i in range(9)], m, t_w, c1)
        k3 = plant.augmented([aug[i] + 0.5 * h * k2[i] for i in range(9)], m, t_w, c1)
        k4 = plant.augmented([aug[i] + h * k3[i] for i in range(9)], m, t_w, c2)
        aug = [aug[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(9)]
        norm = casadi.sqrt(aug[0] * aug[0] + aug[1] * aug[1] + aug[2] * aug[2] + aug[3] * aug[3])
        aug = [aug[i] / norm for i in range(4)] + aug[4:]
    return casadi.Function(
        "magnetorquer_step", [y, a, p], [casadi.vertcat(*aug[:8]), aug[8]], ["x", "a", "p"], ["x_next", "cost"]
    )


def step_parameters(env, n_steps: int) -> np.ndarray:
    """``(n_steps, 1 + (2·n_sub + 1)·N_FIELDS)``: per step ``[k, its time contexts]``
    (:func:`context_table`), the third argument of :func:`step_function`."""
    return np.column_stack([np.arange(n_steps, dtype=float), context_table(env, n_steps)])


def build_magnetorquer(env) -> DiscreteProblem:
    """The :class:`DiscreteProblem` of the unwrapped Magnetorquer-v0 ``env`` right after its
    reset, over its ``episode_duration_s`` (see the module docstring for the horizon)."""
    dt = float(env.control_dt_s)
    n_steps = int(math.ceil(env.episode_duration_s / dt - 1e-9))
    step = step_function(env)
    params = step_parameters(env, n_steps)
    xs = casadi.SX.sym("x", 8)
    rate = float(env.max_rate_rad_s)
    g = casadi.Function("magnetorquer_limits", [xs], [casadi.vertcat(xs[4:7] - rate, -xs[4:7] - rate)], ["x"], ["g"])
    notes = [
        "orbit, field, reference, ΔJ(t) and disturbance precomputed per sub-step stage (params)",
        "tumble limit max|ω_bo| <= max_rate_rad_s as a state constraint",
    ]
    if math.isfinite(float(env.model.params.max_wheel_momentum_nms)):
        notes.append("wheel momentum limit as in the step (torque blocked at |h_w| >= h_max)")
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=8,
        n_u=4,
        n_steps=n_steps,
        step=step,
        x0=np.array(env.state_row, dtype=float),
        a_lb=-np.ones(4),
        a_ub=np.ones(4),
        g=g,
        notes="; ".join(notes),
        params=params,
    )


# ----------------------------------------------------------------------------- nominal model
def disturbance_columns(n_sub: int) -> np.ndarray:
    """Indices of the disturbance entries (3 per context, ``2·n_sub + 1`` contexts) in a
    per-step parameter row ``p = [k, contexts]`` of a step with ``n_sub`` RK4 sub-steps."""
    if int(n_sub) < 1:
        raise ValueError(f"n_sub must be an integer >= 1, got {n_sub!r}")
    starts = 1 + N_FIELDS * np.arange(2 * int(n_sub) + 1) + _DIST
    return (starts[:, None] + np.arange(3)[None, :]).ravel()


def nominal_substeps(env, control_dt_s: float | None = None, integrator_dt_s: float | None = None) -> tuple[float, int]:
    """``(h, n_sub)`` of a model step of ``control_dt_s`` (s; default the env's) with RK4
    sub-steps of ``integrator_dt_s`` (s; default the env's): ValueError unless the period is
    a whole multiple of the sub-step."""
    dt = float(env.control_dt_s if control_dt_s is None else control_dt_s)
    h = float(env.integrator_dt_s if integrator_dt_s is None else integrator_dt_s)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"control_dt_s must be a finite number > 0 s, got {control_dt_s!r}")
    if not (math.isfinite(h) and 0.0 < h <= dt):
        raise ValueError(f"integrator_dt_s must be in (0, control_dt_s = {dt}] s, got {integrator_dt_s!r}")
    n_sub = round(dt / h)
    if abs(n_sub * h - dt) > 1e-9 * dt:
        raise ValueError(f"control_dt_s ({dt} s) must be a whole multiple of integrator_dt_s, got {h} s")
    return dt / n_sub, int(n_sub)


def nominal_constants(env) -> tuple[np.ndarray, np.ndarray]:
    """``(shared, episode)`` in the kernels' layouts for what a controller of the unwrapped
    Magnetorquer-v0 ``env`` may know after its reset: the env's configuration
    (``kernel_constants``: wheel, limits, field model, reference, Q, R) with no time-varying
    inertia (Sadigh et al. 2022 eq. 35 is the unknown truth) and no disturbance, and the episode's
    orbit (the known ephemeris) with the NOMINAL inertia ``env.model.params`` (no drawn
    dispersion) and no disturbance. Fresh arrays."""
    shared = np.array(env.kernel_constants, dtype=float)
    shared[kernels.SH_DJ] = 0.0
    shared[kernels.SH_DIST] = kernels.DIST_NONE
    params = env.model.params
    orbit = np.array(env.episode_constants[kernels.EN_ORBIT : kernels.EN_ORBIT + kernels.ORBIT_SIZE], dtype=float)
    episode = kernels.pack_env(params.inertia_kg_m2, params.inertia_eff_inv, orbit, np.zeros(3))
    return shared, episode


def nominal_step_parameters(
    env,
    start_times_s,
    control_dt_s: float | None = None,
    integrator_dt_s: float | None = None,
    constants: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Per-step parameters ``[k, contexts]`` of :func:`nominal_step_function` for steps of
    ``control_dt_s`` (s) starting at ``start_times_s`` (s, any times, e.g. past the episode's
    end): the contexts at each sub-step's start, middle and at the step's end, built by the
    env's compiled ``context_into`` from :func:`nominal_constants` (or ``constants``), so the
    disturbance entries (:func:`disturbance_columns`) are zero; ``k = t / control_dt_s``."""
    _check_supported(env)
    h, n_sub = nominal_substeps(env, control_dt_s, integrator_dt_s)
    dt = h * n_sub
    shared, episode = nominal_constants(env) if constants is None else constants
    table = np.asarray(env.field.table, dtype=float)
    starts = np.atleast_1d(np.asarray(start_times_s, dtype=float))
    ctx = np.empty(kernels.CONTEXT_SIZE)
    out = np.empty((starts.size, 2 * n_sub + 1, N_FIELDS))
    for k, t0 in enumerate(starts):
        times = []
        for j in range(n_sub):
            ts = t0 + j * h
            times += [ts, ts + 0.5 * h]
        times.append(t0 + dt)
        for i, t in enumerate(times):
            kernels.context_into(t, shared, episode, table, ctx, 0)
            out[k, i] = ctx[_FIELDS]
    return np.column_stack([starts / dt, out.reshape(starts.size, -1)])


def nominal_step_function(
    env, control_dt_s: float | None = None, integrator_dt_s: float | None = None
) -> casadi.Function:
    """The healthy-model step of the unwrapped ``env``, ``(x (8), a (4), p) -> (x_next, cost)``
    as :func:`step_function` (same equations, RK4 sub-steps, action clip, wheel momentum limit,
    stage cost ∫ xᵀQx + uᵀRu dt) but with no actuator faults, a step of ``control_dt_s`` (s)
    and sub-steps of ``integrator_dt_s`` (s; both default to the env's). With the rows of
    :func:`nominal_step_parameters` it is the nominal plant (nominal inertia, no ΔJ(t), the
    disturbance written into :func:`disturbance_columns`; zero there)."""
    _check_supported(env)
    h, n_sub = nominal_substeps(env, control_dt_s, integrator_dt_s)
    plant = _Plant(env)
    plant.h, plant.n_sub = h, n_sub
    limits = np.asarray(env.model.params.limits, dtype=float)
    return _build_step(plant, limits, h * n_sub, [])


def error_function(env) -> casadi.Function:
    """``(y (8), c (N_FIELDS)) -> x (6)``: the error state ``[q_e,vec, ω_e]`` of the state
    ``y = [q, ω_bo (rad/s), Ω]`` against the reference of the time context ``c`` (one context
    of a parameter row, e.g. the last one of a step: its end), as the kernels' ``error_state``."""
    plant = _Plant(env)
    y = casadi.SX.sym("y", 8)
    c = casadi.SX.sym("c", N_FIELDS)
    n = 1.0 / casadi.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    err = plant._error_state(y[0] * n, y[1] * n, y[2] * n, y[3] * n, y[4], y[5], y[6], c)  # noqa: SLF001 (this module's class)
    return casadi.Function("magnetorquer_error", [y, c], [casadi.vertcat(*err)], ["y", "c"], ["x"])
