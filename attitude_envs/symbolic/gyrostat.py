"""The gyrostat's discrete step (ReactionWheel-v0, AirBearing-v0) in CasADi, from a parameter set.

One symbolic model serves both users of the equations: the optimal-control yardstick J*
(:func:`build_reaction_wheel`, :func:`build_air_bearing`: the episode's TRUE plant,
:meth:`GyrostatParameters.true_plant`) and the model-predictive baseline
(:mod:`baselines.mpc`: the NOMINAL model, :meth:`GyrostatParameters.nominal`). They differ
only in the :class:`GyrostatParameters` they pass to :func:`step_function` and in ``smooth``.

The step of :func:`attitude_envs.plants.gyrostat_kernels.step_kernel`, built from the plant's one
definition (:mod:`attitude_envs.plants.gyrostat_definition`, its row functions on a list of
symbols) in the kernel's order of operations:
state ``[q (4, scalar last), ω (3, rad/s), Ω (N, rad/s)]``; the action clipped to [−1, 1] and
scaled by the torque limit (``action_frame="body"``: the minimum-norm allocation
``u = −A⁺T``, each wheel clipped); the actuator faults at the step's start time ``t``; then
``n_substeps`` classical RK4 sub-steps of ``integrator_dt_s`` with the motor torque held
(after the motor driver's wheel-speed limiter at each sub-step's start), the stage cost
``xᵀQx + u_cᵀRu_c`` integrated by the same RK4 quadrature, the quaternion renormalized after
each sub-step. Equations (:mod:`attitude_envs.plants.gyrostat`)::

    I_eff ω̇ = −ω × (I ω + J_s A Ω) − A u + T_ext(t) + p × K(q)
    Ω̇ = u / J_s − Aᵀ ω̇,    q̇ = ½ q ⊗ [ω, 0]

with ``p`` the offset torque (``m g r_s``; Ahangarani Farahani et al., eqs. 6–9) and
``T_ext`` a constant or sinusoidal disturbance. ``smooth=True`` leaves out the step's
non-smooth operations (the action and per-wheel clips, the held torque's clip, the speed
limiter, the error quaternion's sign flip) for a controller that bounds its actions itself.
For J*, the tumble limit, the roll/pitch stop and the wheel-speed limit are the path
constraint ``g``.

Flight conditions (:mod:`attitude_envs.conditions`): the oracle's plant is the episode's drawn
one (inertia, misaligned wheel axes, offset torque; the body-frame allocation stays the
nominal one, as the env's) and it acts through the env's actuator chain
(:mod:`attitude_envs.actuator_dynamics`, :class:`~attitude_envs.symbolic.actuators.ChainSpec`);
the decision variables stay the normalized commands, and the chain's state follows
``[q, ω, Ω]`` in the step's state (zeros at the start). Stage by stage:

* **delay** (exact): a queue of the last ``d`` commanded torques; the plant receives the
  oldest (zeros for the first ``d`` periods);
* **resolution** (relaxed): the command is continuous; the env quantizes it, so the env's
  replay differs from the NLP by the quantization's effect (about 1e-6 relative here);
* **rate limit** (exact, non-smooth): the env's clip about the limiter's last output, a
  state (no wheel has one in the flight tables);
* **faults**: as in the lab, on the delayed command;
* **lag** (exact): its state ``y``; the period delivers ``c + (y₀ − c) φ`` and
  ``y⁺ = c + (y₀ − c) e^{−Δt/τ}`` with the env's own ``φ`` and decay;
* **gain × duty** (exact): the drawn scale factors times the duty cycle (without the
  actuator dynamics only the gain, after the faults);
* **friction** (at the period-start wheel speed): ``viscous · Ω`` exact; the Coulomb term's
  ``sign(Ω)`` is ``tanh(Ω/ε)`` (ε = :data:`~attitude_envs.symbolic.actuators.FRICTION_EPS_RAD_S`)
  in a first solve, then fixed per step from that solve's trajectory
  (:func:`with_friction_signs`) with the wheels held at least
  :data:`FRICTION_SIGN_MARGIN_RAD_S` from zero on the side of their sign, so that the env's
  replay keeps the signs the NLP assumed.

J* itself is always the env's replay of the optimal commands (:mod:`experiments.optimum`),
so a relaxation can cost optimality, never the number's honesty.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import casadi
import numpy as np

from attitude_envs.plants import gyrostat_kernels as kernels
from attitude_envs.plants.gyrostat_definition import MAT_ROWS, N_SCALARS, define
from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.ops import CASADI
from attitude_envs.symbolic.problem import DiscreteProblem

_G = define(CASADI)

__all__ = [
    "GyrostatParameters",
    "build_air_bearing",
    "build_reaction_wheel",
    "error_state",
    "step_function",
    "with_effectiveness",
]


@dataclass(frozen=True, eq=False)
class GyrostatParameters:
    """What the gyrostat's discrete step is built from (SI units; arrays as given).

    The plant: ``inertia_kg_m2`` ``I`` (3×3, wheels included) and ``inertia_eff_inv``
    (``(I − J_s A Aᵀ)⁻¹``), ``wheel_axes`` ``A`` (3×N), ``wheel_inertia_kg_m2`` ``J_s``,
    ``max_wheel_torque_nm``, ``max_wheel_speed_rad_s`` (inf: no speed limiter),
    ``offset_torque_nm`` ``p`` (3; zeros: none). The cost: ``Q``, ``R``, ``cost_input``
    (``"body"``: ``u_c = −A u``; ``"wheel"``: ``u_c = u``), ``include_wheel_momentum`` (``x``
    ends with ``J_s Ω``). The action: ``action_frame`` (``"wheel"``: one per wheel;
    ``"body"``: a body torque demand through ``allocation`` (N×3)). The integrator:
    ``n_substeps`` RK4 sub-steps of ``integrator_dt_s``. Time-varying inputs, functions of the
    time ``t`` the step receives: ``external_torque`` (``t -> T_ext`` (3) as a CasADi
    expression, or None) and ``faults`` (realized actuator faults,
    :attr:`attitude_envs.faults.ActuatorFaults.realized`; empty: healthy). A controller's
    belief about its actuators: ``effectiveness`` (N values in [0, 1], or None: all 1), the
    fraction of its commanded motor torque each wheel delivers at every time (0: an outage),
    applied to the command after the allocation and the per-wheel clip, as the env's
    ``outage``/``loss_of_effectiveness`` faults do (:func:`with_effectiveness`).
    The flight conditions' actuator chain (:mod:`attitude_envs.actuator_dynamics`):
    ``chain`` (:class:`~attitude_envs.symbolic.actuators.ChainSpec`, or None: the lab's ideal
    actuators), the delay, rate limit, lag, gains, duty and friction around the faults; its
    states (queued commands, limiter and lag outputs) follow ``[q, ω, Ω]`` in the step's state.
    """

    inertia_kg_m2: np.ndarray
    inertia_eff_inv: np.ndarray
    wheel_axes: np.ndarray
    wheel_inertia_kg_m2: float
    max_wheel_torque_nm: float
    max_wheel_speed_rad_s: float
    offset_torque_nm: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    cost_input: str
    include_wheel_momentum: bool
    action_frame: str
    allocation: np.ndarray
    n_substeps: int
    integrator_dt_s: float
    external_torque: Callable[[Any], Any] | None = None
    faults: tuple = ()
    effectiveness: np.ndarray | None = None
    chain: actuators.ChainSpec | None = None

    @property
    def n_chain_states(self) -> int:
        """Entries the flight actuator chain adds after ``[q, ω, Ω]`` (0: none)."""
        return 0 if self.chain is None else self.chain.n_state

    @property
    def n_wheels(self) -> int:
        return self.wheel_axes.shape[1]

    @property
    def n_actions(self) -> int:
        return 3 if self.action_frame == "body" else self.n_wheels

    @classmethod
    def nominal(cls, model, n_substeps: int, integrator_dt_s: float, action_frame: str = "wheel") -> GyrostatParameters:
        """What a controller may know: the nominal model ``model``
        (:class:`~attitude_envs.plants.gyrostat_model.ReactionWheelModel`, ``env.unwrapped.model``:
        nominal inertia, wheels, torque and speed limits, offset torque, cost) and the env's
        published integrator and action frame; no faults, no disturbance."""
        p = model.params
        return cls(
            inertia_kg_m2=np.asarray(p.inertia_kg_m2, dtype=float),
            inertia_eff_inv=np.asarray(p.inertia_eff_inv, dtype=float),
            wheel_axes=np.asarray(p.wheel_axes, dtype=float),
            wheel_inertia_kg_m2=float(p.wheel_inertia_kg_m2),
            max_wheel_torque_nm=float(p.max_wheel_torque_nm),
            max_wheel_speed_rad_s=float(p.max_wheel_speed_rad_s),
            offset_torque_nm=np.asarray(p.offset_torque_nm, dtype=float),
            Q=np.asarray(model.cost.Q, dtype=float),
            R=np.asarray(model.cost.R, dtype=float),
            cost_input=model.cost_input,
            include_wheel_momentum=bool(model.include_wheel_momentum),
            action_frame=action_frame,
            allocation=np.asarray(model.allocation, dtype=float),
            n_substeps=int(n_substeps),
            integrator_dt_s=float(integrator_dt_s),
        )

    @classmethod
    def true_plant(cls, env) -> GyrostatParameters:
        """The episode's true plant of ``env`` (an unwrapped ReactionWheel-v0 or AirBearing-v0,
        just reset; an oracle's knowledge): its drawn inertia, wheel axes (flight conditions
        misalign them), true offset torque, disturbance, realized faults and, with flight
        conditions, its actuator chain (delay, actuator dynamics, drawn scale-factor gains).
        The allocation of a body-frame action stays the nominal one (the env's). ValueError
        for a fault kind or disturbance without a symbolic model."""
        actuators.check_supported(env.fault_layer.realized)
        mats = np.array(env.kernel_matrices, dtype=float)  # this episode's true inertia
        nominal = cls.nominal(env.model, env.n_substeps, env.integrator_dt_s, env.action_frame)
        drawn = env.drawn_parameters() if hasattr(env, "drawn_parameters") else {}
        axes = drawn.get("wheel_axes")
        chain = actuators.ChainSpec.from_env(env, nominal.n_wheels)
        return replace(
            nominal,
            inertia_kg_m2=mats[:9].reshape(3, 3),
            inertia_eff_inv=mats[9:18].reshape(3, 3),
            wheel_axes=nominal.wheel_axes if axes is None else np.array(axes, dtype=float),
            offset_torque_nm=np.array(env.true_offset_torque_nm, dtype=float),  # may differ from the model's
            external_torque=_disturbance(env),
            faults=tuple(env.fault_layer.realized),
            chain=None if chain.is_identity else chain,
        )


def with_effectiveness(params: GyrostatParameters, effectiveness) -> GyrostatParameters:
    """``params`` with the wheels' assumed ``effectiveness`` (N values in [0, 1]; all ones gives
    the healthy model, whose step is bit-identical to ``params``' own). ValueError otherwise."""
    eff = np.asarray(effectiveness, dtype=float)
    if eff.shape != (params.n_wheels,) or not np.all((eff >= 0.0) & (eff <= 1.0)):
        raise ValueError(
            f"effectiveness must be {params.n_wheels} values in [0, 1] (one per wheel), got {effectiveness!r}"
        )
    return replace(params, effectiveness=eff.copy())


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


def _constants(params: GyrostatParameters) -> tuple[list, int, int, int, int]:
    """The definition's flat constants ``C`` of ``params`` (the kernel's
    :func:`~attitude_envs.plants.gyrostat_kernels.pack_constants` as a list of floats: wheel
    axes, Q, R, the scalars; the limits the step does not read at their defaults) and the
    offsets ``(ax, cq, cr, sc)``."""
    q_mat, r_mat = np.asarray(params.Q, float), np.asarray(params.R, float)
    packed = kernels.pack_constants(
        params.wheel_axes,
        q_mat,
        r_mat,
        params.wheel_inertia_kg_m2,
        params.max_wheel_torque_nm,
        params.max_wheel_speed_rad_s,
        params.integrator_dt_s,
        params.offset_torque_nm,
    )
    cq = 3 * params.n_wheels
    return [float(v) for v in packed], 0, cq, cq + q_mat.size, packed.shape[0] - N_SCALARS


def error_state(params: GyrostatParameters, y, q_target, smooth: bool = False):
    """The cost's error state ``x = [q_e,vec, ω, (J_s Ω)]`` of a symbolic state ``y``
    (SX or MX) with ``q_e = q_T* ⊗ q/|q|``, signed so that ``q_e,w ≥ 0`` as the env does
    (``smooth=True``: no sign flip, a smooth function of ``y``); the definition's
    ``error_state_lane``."""
    n = params.n_wheels
    n_state = 6 + n if params.include_wheel_momentum else 6
    C, _, _, _, sc = _constants(params)
    W = [y[i] for i in range(7 + n)] + [q_target[i] for i in range(4)] + [None] * n_state
    _G.error_state_lane(W, C, 0, 1, n, params.include_wheel_momentum, 0, 7 + n, 11 + n, sc, not smooth)
    return casadi.vertcat(*W[11 + n : 11 + n + n_state])


def step_function(params: GyrostatParameters, smooth: bool = False) -> casadi.Function:
    """The control step of ``params`` as a CasADi SX function
    ``(y (7+N+M), a (n_u), t (1), q_T (4)) -> (y_next (7+N+M), cost (1))``: ``y = [q, ω, Ω]``
    followed by the ``M`` = :attr:`GyrostatParameters.n_chain_states` states of a flight
    actuator chain (none in the lab),
    ``a`` the normalized action, ``t`` the step's start time (s; the faults and the
    disturbance are functions of it, nothing else is), ``q_T`` the target attitude,
    ``cost`` the env's step cost (see the module docstring). ``smooth=True``: no action or
    torque clips, no speed limiter, no error-quaternion sign flip (the caller bounds ``a``;
    realized ``faults``, if any, still clip at their limits as the env's fault layer does)."""
    n = params.n_wheels
    max_torque = float(params.max_wheel_torque_nm)
    offset = bool(np.any(np.asarray(params.offset_torque_nm) != 0.0))
    include_h = bool(params.include_wheel_momentum)
    n_state = 6 + n if include_h else 6
    body_input = params.cost_input == "body"
    h, n_sub = float(params.integrator_dt_s), int(params.n_substeps)
    ext = params.external_torque
    C, ax, cq, cr, sc = _constants(params)
    mat = [float(v) for v in np.ravel(params.inertia_kg_m2)] + [float(v) for v in np.ravel(params.inertia_eff_inv)]
    # rows of the definition's scratch list (one lane: B = 1, e = 0)
    Y, U, UJ = 0, 7 + n, 7 + 2 * n
    EXT = UJ + n
    MAT = EXT + 3
    TGT = MAT + MAT_ROWS
    X = TGT + 4
    OUT = X + n_state

    chain = params.chain
    n_extra = params.n_chain_states
    y = casadi.SX.sym("y", 7 + n + n_extra)
    extra = [y[7 + n + i] for i in range(n_extra)]
    # with fixed friction signs: sign(Ω) of each wheel at this step is a fifth input
    sgn = casadi.SX.sym("s", n) if chain is not None and chain.has_friction and chain.fixed_signs else None
    a = casadi.SX.sym("a", params.n_actions)
    t0 = casadi.SX.sym("t")
    target = casadi.SX.sym("q_T", 4)

    a_c = a if smooth else actuators.clip(a, -1.0, 1.0)
    if params.action_frame == "body":
        commanded = casadi.mtimes(casadi.DM(params.allocation * max_torque), a_c)
        if not smooth:
            commanded = actuators.clip(commanded, -max_torque, max_torque)
    else:
        commanded = a_c * max_torque
    eff = params.effectiveness
    if eff is not None and np.any(np.asarray(eff) != 1.0):  # all ones: the healthy graph, bit-identical
        # delivered = e ⊙ commanded: the env's outage (e = 0) and loss of effectiveness (e = 1 − value)
        commanded = commanded * casadi.DM(np.asarray(eff, dtype=float))
    new_extra = []
    if chain is not None:  # the flight chain's stages 1-3: delay, (resolution relaxed), rate limit
        commanded, new_extra = actuators.chain_command(chain, [commanded[i] for i in range(n)], extra)
        commanded = casadi.vertcat(*commanded)
    cmd = actuators.delivered(commanded, t0, params.faults, np.full(n, max_torque))
    cmd = [cmd[i] for i in range(n)]
    if chain is not None:  # stages 5-7: lag, gain and duty, friction at the period-start wheel speeds
        signs = [sgn[i] for i in range(n)] if sgn is not None else None
        cmd, lag_next = actuators.chain_output(chain, cmd, extra, [y[7 + i] for i in range(n)], signs)
        new_extra = new_extra + lag_next
    tgt = [target[i] for i in range(4)]

    z = [y[i] for i in range(7 + n)] + [casadi.SX(0.0)]
    for j in range(n_sub):
        if smooth:
            u = cmd
        else:  # the motor driver: torque limit, speed limiter (the kernel's speed_limit_lane)
            drive = cmd + z[7 : 7 + n]
            u = [_G.speed_limit_lane(drive, C, 0, 1, i, 0, n, sc) for i in range(n)]
        terms = u + [None] * (n + max(3, n))
        input_cost = _G.input_terms_lane(terms, C, 0, 1, n, body_input, 0, n, 2 * n, ax, cr, sc)
        uj = terms[n : 2 * n]
        t_j = t0 + j * h
        ks = []
        for stage, frac in enumerate((0.0, 0.5, 0.5, 1.0)):
            step = h if stage == 3 else 0.5 * h
            zs = z if stage == 0 else [z[i] + step * ks[-1][i] for i in range(8 + n)]
            t_ext = [0.0, 0.0, 0.0] if ext is None else ext(t_j + frac * h)
            W = zs[: 7 + n] + u + uj + [t_ext[c] for c in range(3)] + mat + tgt + [None] * (n_state + 7 + n)
            _G.derivative_lane(W, C, 0, 1, n, offset, Y, U, UJ, EXT, MAT, OUT, ax, sc)
            state_cost = _G.state_cost_lane(W, C, 0, 1, n, include_h, False, Y, TGT, X, cq, sc, not smooth)
            ks.append(W[OUT : OUT + 7 + n] + [state_cost + input_cost])
        z = [z[i] + (h / 6.0) * (ks[0][i] + 2.0 * ks[1][i] + 2.0 * ks[2][i] + ks[3][i]) for i in range(8 + n)]
        norm = casadi.sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2] + z[3] * z[3])
        z = [z[i] / norm for i in range(4)] + z[4:]
    z, cost = casadi.vertcat(*z[: 7 + n], *new_extra), z[7 + n]
    if sgn is not None:
        return casadi.Function(
            "gyrostat_step", [y, a, t0, target, sgn], [z, cost], ["y", "a", "t", "q_T", "s"], ["y_next", "cost"]
        )
    return casadi.Function("gyrostat_step", [y, a, t0, target], [z, cost], ["y", "a", "t", "q_T"], ["y_next", "cost"])


def build_reaction_wheel(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped ReactionWheel-v0, just reset) starts."""
    return _build(env)


def build_air_bearing(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped AirBearing-v0, just reset) starts."""
    return _build(env)


#: the margin (rad/s) by which a wheel keeps the Coulomb sign fixed for it (:func:`with_friction_signs`):
#: the env's quantized commands move its wheel speeds off the oracle's by a few 0.01 rad/s
FRICTION_SIGN_MARGIN_RAD_S = 0.1


def with_friction_signs(env, signs) -> DiscreteProblem | None:
    """The problem of the episode ``env`` (unwrapped, just reset) starts, with the wheels'
    Coulomb friction signs fixed per step to ``signs`` ((n_steps, N), e.g. ``sign(Ω_k)`` of a
    first solve's trajectory) in place of the ``tanh`` relaxation: exact wherever the
    optimum keeps those signs. None when the episode has no Coulomb friction."""
    return _build(env, signs)


def _build(env, friction_signs=None) -> DiscreteProblem:
    params = GyrostatParameters.true_plant(env)
    if friction_signs is not None:
        if params.chain is None or not params.chain.has_friction:
            return None
        params = replace(params, chain=replace(params.chain, fixed_signs=True))
    dt = float(env.control_dt_s)
    n_w = params.n_wheels
    n_x, n_u = 7 + n_w + params.n_chain_states, env.action_space.shape[0]
    plant = step_function(params)
    y, a, k = casadi.SX.sym("y", n_x), casadi.SX.sym("a", n_u), casadi.SX.sym("k")
    # the env's time: steps · control_dt_s; its target is fixed for the episode
    target = casadi.DM(np.array(env.target_attitude, dtype=float))
    step_params = None
    if friction_signs is None:
        y_next, cost = plant(y, a, k * dt, target)
        step = casadi.Function("step", [y, a, k], [y_next, cost], ["x", "a", "k"], ["x_next", "cost"])
    else:  # per-step inputs [k, sign(Ω_k) of each wheel]
        p = casadi.SX.sym("p", 1 + n_w)
        y_next, cost = plant(y, a, p[0] * dt, target, p[1:])
        step = casadi.Function("step", [y, a, p], [y_next, cost], ["x", "a", "p"], ["x_next", "cost"])

    # path constraints g(x) <= 0: tumble limit, wheel-speed limit, roll/pitch stop
    max_speed = params.max_wheel_speed_rad_s
    xs = casadi.SX.sym("x", n_x)
    g_parts = [(xs[4:7] / float(env.max_rate_rad_s)) ** 2 - 1.0]  # normalized: each entry O(1)
    notes = ["tumble limit max|ω| <= max_rate_rad_s as a state constraint"]
    if np.isfinite(max_speed):
        g_parts.append((xs[7 : 7 + n_w] / max_speed) ** 2 - 1.0)
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
    if friction_signs is None:
        g = casadi.Function("g", [xs], [casadi.vertcat(*g_parts)], ["x"], ["g"])
    else:  # the fixed signs kept with a margin: s·Ω >= δ where s = ±1 (nothing where s = 0)
        ps = casadi.SX.sym("p", 1 + n_w)
        margin = float(FRICTION_SIGN_MARGIN_RAD_S)
        g_parts += [ps[1 + i] * (margin * ps[1 + i] - xs[7 + i]) / margin for i in range(n_w)]
        notes.append(f"the fixed friction signs held with a margin |Omega| >= {margin:g} rad/s")
        g = casadi.Function("g", [xs, ps], [casadi.vertcat(*g_parts)], ["x", "p"], ["g"])
    if params.chain is not None:
        notes += params.chain.notes()
    n_steps = int(math.ceil(env.episode_duration_s / dt - 1e-9))
    if friction_signs is not None:
        signs = np.asarray(friction_signs, dtype=float).reshape(n_steps, n_w)
        step_params = np.column_stack([np.arange(n_steps, dtype=float), signs])
    x0 = np.array(env.state_row, dtype=float)
    if params.n_chain_states:  # the chain at rest: empty delay line, limiter and lag outputs zero
        x0 = np.concatenate([x0, np.zeros(params.n_chain_states)])
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=n_x,
        n_u=n_u,
        n_steps=n_steps,
        step=step,
        x0=x0,
        a_lb=-np.ones(n_u),
        a_ub=np.ones(n_u),
        g=g,
        notes="; ".join(notes),
        params=step_params,
    )
