"""The discrete problem of Magnetorquer-v0 (the nano-satellite of Sadigh, Kashaninia & Dehghan
2022: three magnetorquers and one y wheel, attitude relative to the orbital frame) in CasADi.

The step is :func:`attitude_envs.plants.magnetorquer_kernels.control_step` built from the plant's
one definition (:mod:`attitude_envs.plants.magnetorquer_definition`): the
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

Flight conditions (:mod:`attitude_envs.conditions`,
:mod:`attitude_envs.presets.flight_magnetorquer`): the oracle knows the episode's draws and
acts through the env's actuator chain (:func:`attitude_envs.symbolic.actuators.through_chain`,
:class:`~attitude_envs.symbolic.actuators.ChainSpec` of the four actuators, dipoles then
wheel); the chain's states follow ``[q, ω_bo, Ω]`` (zeros at the start) and the decision
variables stay the normalized commands. Feature by feature:

* **inertia** (exact): the drawn true inertia is in the env's ``episode_constants``, so in
  the time contexts (``I``, ``I_eff⁻¹``) the step reads;
* **delay** (exact): a queue of the last ``d`` commands, the plant receives the oldest
  (zeros for the first ``d`` periods);
* **resolution** (relaxed): the dipoles' 8-bit quantum and the wheel's minimum torque
  (1.5 % of its limit) are not modelled, the oracle's command is continuous; the env
  quantizes it, so the replay differs from the NLP's objective by the quantization's effect
  (measured 0.2–1.5 % of J* on 100-step episodes);
* **faults**: as in the lab, on the delayed command;
* **wheel lag** (exact): its state; the period holds ``c + (y₀ − c) φ`` and
  ``y⁺ = c + (y₀ − c) e^{−Δt/τ}`` with the env's own ``φ`` and decay (the dipoles have none);
* **gains × duty** (exact): the drawn scale factors times the duty cycle (0.8 for the
  dipoles: off while the magnetometer samples; 1 for the wheel);
* **wheel friction** (at the period-start speed, against ``−Ω``: the wheel's output is the
  torque on the body, so friction opposing its spin adds ``+coulomb·sign(Ω)``, the env's
  convention): viscous exact; the Coulomb ``sign`` first relaxed to ``tanh(−Ω/ε)``
  (ε = :data:`FRICTION_EPS_RAD_S`), then
  fixed per step from the last solve (:func:`with_friction_signs`, with the margin rows
  :func:`attitude_envs.symbolic.with_friction_signs` switches per step), so the fixed-sign
  step is the env's to rounding wherever the optimum keeps those signs;
* then the momentum limit and the plant exactly as in the lab; sensors play no part.

J* is always the env's replay of the optimal commands (:mod:`experiments.optimum`), so a
relaxation can cost optimality, never the number's honesty.

Not represented (ValueError): a random-walk disturbance (drawn step by step from the env's
generator), intermittent faults and a ``stuck`` fault without a value.
"""

from __future__ import annotations

import dataclasses
import math

import casadi
import numpy as np

from attitude_envs.plants import magnetorquer_kernels as kernels
from attitude_envs.plants.magnetorquer_definition import COMPACT_LAYOUT, COMPACT_SIZE, define
from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.ops import CASADI
from attitude_envs.symbolic.problem import DiscreteProblem

_PLANT = define(CASADI)
# the time context entries the step reads: the kernels' context (layout CX_*) picked into the
# definition's compact layout (ν̇, ν̈, r, b_orb (3), q_d (4), ω_d (3), I (9), I_eff⁻¹ (9), disturbance (3))
_SIZES = (1, 1, 1, 3, 4, 3, 9, 9, 3)
_FIELDS = np.concatenate([np.arange(start, start + n) for start, n in zip(kernels.CONTEXT_LAYOUT, _SIZES, strict=True)])
N_FIELDS = COMPACT_SIZE
_RATE, _RATE_DOT, _R, _B, _QD, _WD, _I, _EINV, _DIST = COMPACT_LAYOUT


class _Plant:
    """The constants of one env configuration and episode the symbolic step needs."""

    def __init__(self, env) -> None:
        shared = np.asarray(env.kernel_constants, dtype=float)
        self.j_w = float(shared[kernels.SH_JW])
        self.h_max = float(shared[kernels.SH_HMAX])
        self.h = float(shared[kernels.SH_H])
        self.n_sub = int(shared[kernels.SH_NSUB])
        self.gravity_gradient = shared[kernels.SH_GG] != 0.0
        q_mat = np.asarray(env.model.cost.Q, dtype=float)
        r_mat = np.asarray(env.model.cost.R, dtype=float)
        # the kernel's diagonal path when both are diagonal (its sums, without the zero products)
        self.diagonal = bool(shared[kernels.SH_DIAG] != 0.0)
        self.Q, self.R = casadi.DM(q_mat), casadi.DM(r_mat)
        # the sign of q_e changes xᵀQx only through Q's cross terms between q_e,vec and ω_e
        self.flip_sign = bool(np.any(q_mat[:3, 3:] != 0.0))

    def augmented(self, z: list, m: list, t_w, c):
        """d/dt ``[q, ω_bo, Ω, cost]`` (the plant definition's augmented derivative) at ``z``
        with the dipoles ``m`` (A·m²), wheel torque ``t_w`` (N·m) and the time context ``c``
        (the definition's compact layout)."""
        return list(
            _PLANT.augmented(
                z,
                0,
                m,
                t_w,
                c,
                0,
                COMPACT_LAYOUT,
                self.j_w,
                self.gravity_gradient,
                self.Q,
                self.R,
                self.diagonal,
                self.flip_sign,
            )
        )


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


def step_function(env, chain: actuators.ChainSpec | None = None) -> casadi.Function:
    """The SX step ``(x (8 + M), a (4), p (1 + (2·n_sub + 1)·N_FIELDS [+ 4])) -> (x_next, cost)``
    of the unwrapped ``env``'s episode, ``p = [k, the step's time contexts]`` (a row of
    :func:`step_parameters`); with a flight actuator ``chain`` its ``M`` states follow
    ``[q, ω_bo, Ω]`` and, with ``chain.fixed_signs``, ``p`` ends with the four actuators'
    Coulomb signs."""
    _check_supported(env)
    plant = _Plant(env)
    limits = np.asarray(env.model.params.limits, dtype=float)
    return _build_step(plant, limits, float(env.control_dt_s), env.fault_layer.realized, chain)


def _build_step(
    plant: _Plant, limits: np.ndarray, control_dt_s: float, realized, chain: actuators.ChainSpec | None = None
) -> casadi.Function:
    """The SX step of :func:`step_function` for ``plant`` (its ``h``, ``n_sub``), the actuator
    ``limits``, the control period (s), the realized actuator faults ``realized`` (the
    fault layer's, or ``[]`` for a healthy model) and the flight actuator ``chain`` (None:
    the lab's ideal actuators)."""
    n_extra = 0 if chain is None else chain.n_state
    n_sign = 4 if chain is not None and chain.fixed_signs else 0
    y = casadi.SX.sym("y", 8 + n_extra)
    a = casadi.SX.sym("a", 4)
    p = casadi.SX.sym("p", 1 + (2 * plant.n_sub + 1) * N_FIELDS + n_sign)
    commanded = actuators.clip(a, -1.0, 1.0) * casadi.DM(limits)
    new_extra = []
    if chain is None:
        cmd = actuators.delivered(commanded, p[0] * control_dt_s, realized, limits)
    else:  # the wheel's friction against −Ω: T_w is the torque on the body (the env's _friction_speeds)
        speeds = [casadi.SX(0.0), casadi.SX(0.0), casadi.SX(0.0), -y[7]]
        signs = [p[p.shape[0] - n_sign + i] for i in range(n_sign)] if n_sign else None
        extra = [y[8 + i] for i in range(n_extra)]
        cmd, new_extra = actuators.through_chain(
            chain, commanded, p[0] * control_dt_s, realized, limits, extra, speeds, signs
        )
    m = [cmd[0], cmd[1], cmd[2]]
    h = plant.h
    aug = [y[i] for i in range(8)] + [0.0]
    for j in range(plant.n_sub):
        c0, c1, c2 = (p[1 + (2 * j + s) * N_FIELDS : 1 + (2 * j + s + 1) * N_FIELDS] for s in range(3))
        t_w = cmd[3]
        if math.isfinite(plant.h_max):  # the wheel's storable momentum (blocks torque that raises |h_w|)
            t_w = _PLANT.wheel_torque(t_w, aug[0], aug[2], aug[5], aug[7], c0[_RATE], plant.j_w, plant.h_max)
        k1 = plant.augmented(aug, m, t_w, c0)
        k2 = plant.augmented([aug[i] + 0.5 * h * k1[i] for i in range(9)], m, t_w, c1)
        k3 = plant.augmented([aug[i] + 0.5 * h * k2[i] for i in range(9)], m, t_w, c1)
        k4 = plant.augmented([aug[i] + h * k3[i] for i in range(9)], m, t_w, c2)
        aug = [aug[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(9)]
        norm = casadi.sqrt(aug[0] * aug[0] + aug[1] * aug[1] + aug[2] * aug[2] + aug[3] * aug[3])
        aug = [aug[i] / norm for i in range(4)] + aug[4:]
    return casadi.Function(
        "magnetorquer_step",
        [y, a, p],
        [casadi.vertcat(*aug[:8], *new_extra), aug[8]],
        ["x", "a", "p"],
        ["x_next", "cost"],
    )


def step_parameters(env, n_steps: int) -> np.ndarray:
    """``(n_steps, 1 + (2·n_sub + 1)·N_FIELDS)``: per step ``[k, its time contexts]``
    (:func:`context_table`), the third argument of :func:`step_function`."""
    return np.column_stack([np.arange(n_steps, dtype=float), context_table(env, n_steps)])


def build_magnetorquer(env) -> DiscreteProblem:
    """The :class:`DiscreteProblem` of the unwrapped Magnetorquer-v0 ``env`` right after its
    reset, over its ``episode_duration_s`` (see the module docstring for the horizon)."""
    return _build(env)


#: the margin (rad/s) by which the wheel keeps a fixed Coulomb sign (:func:`with_friction_signs`),
#: as the gyrostats' (:data:`attitude_envs.symbolic.gyrostat.FRICTION_SIGN_MARGIN_RAD_S`)
FRICTION_SIGN_MARGIN_RAD_S = 0.1


def friction_speeds(env, states: np.ndarray) -> np.ndarray:
    """``(n, 4)``: the speeds the actuator chain's friction acts against at each of the
    ``states`` (rows ``[q, ω_bo, Ω, chain states…]``), the env's convention
    (:meth:`~attitude_envs.envs.magnetorquer.MagnetorquerEnv._friction_speeds`): zeros for the
    dipoles and −Ω for the wheel (its output is the torque on the body)."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    out = np.zeros((states.shape[0], 4))
    out[:, 3] = -states[:, 7]
    return out


def with_friction_signs(env, signs) -> DiscreteProblem | None:
    """The problem of the episode ``env`` (unwrapped, just reset) starts, with the Coulomb
    signs fixed per step to ``signs`` ((n_steps, 4), ``sign`` of :func:`friction_speeds` of a
    first solve's trajectory) in place of the ``tanh`` relaxation, and each speed held at
    least :data:`FRICTION_SIGN_MARGIN_RAD_S` from zero on the side of its sign (the last 4
    rows of ``g(x, p)``, zero where the sign is 0, e.g. the dipoles'): exact wherever the
    optimum keeps those signs. None when the episode has no Coulomb friction.
    :func:`attitude_envs.symbolic.with_friction_signs` drops or switches those rows per step."""
    return _build(env, signs)


#: the smoothing speed ε (rad/s) of the wheel's Coulomb sign in the first solve: the wheel turns
#: slowly (tenths of rad/s in a slew's first seconds), so the gyrostats' ε
#: (:data:`attitude_envs.symbolic.actuators.FRICTION_EPS_RAD_S`, 0.5) smooths too much: measured
#: on 100-step flight episodes, seed 1's J* was 8.77e-6 with it against 7.21e-6 with 0.05
FRICTION_EPS_RAD_S = 0.05


def _chain(env) -> actuators.ChainSpec | None:
    chain = actuators.ChainSpec.from_env(env, 4)
    return None if chain.is_identity else dataclasses.replace(chain, friction_eps=FRICTION_EPS_RAD_S)


def _build(env, friction_signs=None) -> DiscreteProblem | None:
    dt = float(env.control_dt_s)
    n_steps = int(math.ceil(env.episode_duration_s / dt - 1e-9))
    chain = _chain(env)
    if friction_signs is not None:
        if chain is None or not chain.has_friction or not np.any(chain.coulomb != 0):
            return None
        chain = dataclasses.replace(chain, fixed_signs=True)
    n_extra = 0 if chain is None else chain.n_state
    step = step_function(env, chain)
    params = step_parameters(env, n_steps)
    if friction_signs is not None:
        params = np.column_stack([params, np.asarray(friction_signs, dtype=float).reshape(n_steps, 4)])
    n_x = 8 + n_extra
    xs = casadi.SX.sym("x", n_x)
    rate = float(env.max_rate_rad_s)
    rows = _PLANT.limit_rows(xs[4], xs[5], xs[6], rate)
    # the rows ordered as before (+ω_bo, then −ω_bo), so the NLP's constraint vector is unchanged
    rows = [*rows[0::2], *rows[1::2]]
    notes = [
        "orbit, field, reference, ΔJ(t) and disturbance precomputed per sub-step stage (params)",
        "tumble limit max|ω_bo| <= max_rate_rad_s as a state constraint",
    ]
    if math.isfinite(float(env.model.params.max_wheel_momentum_nms)):
        notes.append("wheel momentum limit as in the step (torque blocked at |h_w| >= h_max)")
    if "inertia_kg_m2" in env.drawn_parameters():
        notes.append("the drawn inertia exact (the env's episode constants, in the time contexts)")
    if chain is not None:
        notes += chain.notes()
    if friction_signs is not None:  # s·v >= δ for each speed v = [0, 0, 0, −Ω] where s = ±1 (nothing where s = 0)
        ps = casadi.SX.sym("p", params.shape[1])
        margin = float(FRICTION_SIGN_MARGIN_RAD_S)
        speeds = [0.0, 0.0, 0.0, -xs[7]]
        for i in range(4):
            s_i = ps[params.shape[1] - 4 + i]
            rows.append(s_i * (margin * s_i - speeds[i]) / margin)
        notes.append(f"the fixed friction signs held with a margin |Omega| >= {margin:g} rad/s")
        g = casadi.Function("magnetorquer_limits", [xs, ps], [casadi.vertcat(*rows)], ["x", "p"], ["g"])
    else:
        g = casadi.Function("magnetorquer_limits", [xs], [casadi.vertcat(*rows)], ["x"], ["g"])
    x0 = np.array(env.state_row, dtype=float)
    if n_extra:  # the chain at rest: empty delay line, limiter and lag outputs zero
        x0 = np.concatenate([x0, np.zeros(n_extra)])
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=n_x,
        n_u=4,
        n_steps=n_steps,
        step=step,
        x0=x0,
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
    err = _PLANT.error_state(y[0] * n, y[1] * n, y[2] * n, y[3] * n, y[4], y[5], y[6], c, _QD, plant.flip_sign)
    return casadi.Function("magnetorquer_error", [y, c], [casadi.vertcat(*err[:6])], ["y", "c"], ["x"])
