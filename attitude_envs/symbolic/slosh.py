"""The discrete problem of FuelSlosh-v0 (Navabi & Davoodi's planar two-pendulum slosh plant,
eqs. 11–14 in mass-matrix form) in CasADi, built from the plant's one definition
(:mod:`attitude_envs.plants.slosh_definition`) as the compiled step
:func:`attitude_envs.plants.slosh_kernels.control_step` is: classical RK4 sub-steps with the
stage cost ``xᵀQx + u_cᵀRu_c`` integrated as an extra state, in the kernel's order of
operations, so states and step costs agree with the env to round-off.

State: the env's full state ``y`` (10, :mod:`attitude_envs.plants.slosh`). Action: the
normalized ``[δ, M_c]``, clipped to [-1, 1] and scaled by the actuator limits, then the
episode's actuator faults at ``t = k·control_dt_s`` (:mod:`attitude_envs.symbolic.actuators`).
Path constraints: the env's termination limits ``|ψ_i| ≤ max_slosh_angle``, ``|Ω| ≤
max_pitch_rate``, ``|θ| ≤ max_pitch_angle`` (linear, ``g(y) ≤ 0``).

Flight conditions (:mod:`attitude_envs.conditions`, :mod:`attitude_envs.presets.flight_slosh`):
the oracle knows the episode's draws and acts through the env's actuator chain
(:func:`attitude_envs.symbolic.actuators.through_chain`); the chain's states follow ``y``
(zeros at the start) and the decision variables stay the normalized commands:

* **slosh masses and pendulum lengths** (exact): drawn per episode, they are in the env's
  ``kernel_constants`` (the repacked plant, the fixed propellant taking the change of the
  slosh masses), which the step reads;
* **delay** (exact): a queue of the last ``d`` commanded ``[δ, M_c]``, the plant receives
  the oldest (zeros for the first ``d`` periods);
* **gimbal rate limit** (exact): the limiter's last output is a state (the pitch moment
  has no limit: its limiter state just follows the command). With a delay (flight's one
  period) the clip is replaced by a path constraint holding the oldest queued command within
  ``rate_limit · Δt`` of that output (:func:`~attitude_envs.symbolic.actuators.rate_limit_rows`),
  so the step stays smooth and the env's clip never acts at the optimum; no optimality is
  lost, since a command the env clips delivers exactly what its clipped value commanded
  does. Without a delay the step keeps the env's clip (exact, non-smooth). Measured: with
  the clip in the step IPOPT did not converge in 1000 iterations on a 100-step flight
  episode from the slosh LQR's warm start;
* **faults**: as in the lab, on the rate-limited command;
* **gimbal lag** (exact): its state ``δ_l``; the period holds ``c + (δ_l − c) φ`` and
  ``δ_l⁺ = c + (δ_l − c) e^{−Δt/τ}`` with the env's own ``φ`` and decay (the moment has no lag);
* **gains** (exact): this episode's drawn scale factors (times a unit duty cycle);
* **sensors** play no part (the oracle acts on the true state).

The chain is the env's in every operation, so the step equals the env's to rounding.
"""

from __future__ import annotations

import dataclasses
import math

import casadi
import numpy as np

from attitude_envs.plants import slosh
from attitude_envs.plants.slosh_definition import N_PACKED, define
from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.ops import CASADI
from attitude_envs.symbolic.problem import DiscreteProblem

_PLANT = define(CASADI)


def _augmented(pk, Q, R, aug, sin_d, cos_d, moment) -> list:
    """ẏ (10) and the stage cost xᵀQx + u_cᵀRu_c (the definition's augmented derivative without
    the new-input integrals)."""
    dy, stage, _, _ = _PLANT.augmented(pk, aug, sin_d, cos_d, moment, Q, R)
    return [*dy, stage]


def step_function(env) -> casadi.Function:
    """``(y (10 + M), a (2), k (1)) -> (y_next (10 + M), cost (1))``: one FuelSlosh-v0 control
    step of the unwrapped ``env`` (its kernel constants, limits, this episode's realized faults
    and, under flight conditions, its actuator chain, whose ``M`` states follow ``y``; none in
    the lab)."""
    pk, h, n_sub, Q, R, limits = _step_constants(env)
    chain = _chain(env)
    n_extra = 0 if chain is None else chain.n_state
    y = casadi.SX.sym("y", slosh.N_STATE + n_extra)
    a = casadi.SX.sym("a", 2)
    k = casadi.SX.sym("k")
    commanded = actuators.clip(a, -1.0, 1.0) * casadi.DM(limits)
    if chain is None:
        applied = actuators.delivered(commanded, k * env.control_dt_s, env.fault_layer.realized, limits)
        y_next, cost = _rk4_control_step(pk, h, n_sub, Q, R, y, applied[0], applied[1])
    else:
        extra = [y[slosh.N_STATE + i] for i in range(n_extra)]
        applied, new_extra = actuators.through_chain(
            chain, commanded, k * env.control_dt_s, env.fault_layer.realized, limits, extra
        )
        y_next, cost = _rk4_control_step(pk, h, n_sub, Q, R, y[: slosh.N_STATE], applied[0], applied[1])
        y_next = casadi.vertcat(y_next, *new_extra)
    return casadi.Function("fuel_slosh_step", [y, a, k], [y_next, cost], ["x", "a", "k"], ["x_next", "cost"])


def _chain(env) -> actuators.ChainSpec | None:
    """The env's flight actuator chain (gimbal angle, pitch moment), None in the lab."""
    chain = actuators.ChainSpec.from_env(env, 2)
    if chain.is_identity:
        return None
    if chain.has_rate and chain.delay_steps >= 1:  # the rate limit as a path constraint: a smooth step
        chain = dataclasses.replace(chain, rate_constrained=True)
    return chain


def _step_constants(env, nominal: bool = False) -> tuple:
    """``(packed plant constants, RK4 sub-step h (s), sub-steps per control step, Q, R,
    actuator limits)`` of the unwrapped FuelSlosh-v0 ``env``: what both symbolic steps read
    (``nominal``: the nominal plant's, not this episode's drawn one)."""
    const = np.asarray(env.nominal_kernel_constants if nominal else env.kernel_constants)
    pk = const[:N_PACKED]
    h = float(const[N_PACKED])
    n_sub = int(const[N_PACKED + 1])
    Q = casadi.DM(np.asarray(env.model.cost.Q, float))
    R = casadi.DM(np.asarray(env.model.cost.R, float))
    return pk, h, n_sub, Q, R, np.asarray(env.actuator_limits, float)


def _rk4_control_step(pk, h: float, n_sub: int, Q, R, y, delta, moment):
    """``(y_next, cost)``: ``n_sub`` classical RK4 sub-steps of ``h`` seconds of the state ``y``
    (10) and the stage-cost integral under the held gimbal angle ``delta`` (rad) and pitch
    moment ``moment`` (N·m) — the compiled kernel's control step, from the same definition."""
    sin_d, cos_d = casadi.sin(delta), casadi.cos(delta)
    n = slosh.N_STATE + 1
    aug = [y[i] for i in range(slosh.N_STATE)] + [0.0]
    for _ in range(n_sub):
        k1 = _augmented(pk, Q, R, aug, sin_d, cos_d, moment)
        k2 = _augmented(pk, Q, R, [aug[i] + 0.5 * h * k1[i] for i in range(n)], sin_d, cos_d, moment)
        k3 = _augmented(pk, Q, R, [aug[i] + 0.5 * h * k2[i] for i in range(n)], sin_d, cos_d, moment)
        k4 = _augmented(pk, Q, R, [aug[i] + h * k3[i] for i in range(n)], sin_d, cos_d, moment)
        aug = [aug[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(n)]
    return casadi.vertcat(*aug[: slosh.N_STATE]), aug[-1]


def nominal_step_function(env) -> casadi.Function:
    """``(y (10), a (2), d (2)) -> (y_next (10), cost (1))``: one control step of the NOMINAL
    FuelSlosh-v0 plant of the unwrapped ``env`` (its kernel constants: plant, integrator,
    control period, cost weights; no faults) for a model-based controller.

    The applied inputs are ``[δ (rad), M_c (N·m)] = a · actuator_limits + d``: the normalized
    action ``a`` is NOT clipped (a controller bounds it) and ``d`` is an additive input
    disturbance in physical units (rad, N·m; zero for the nominal plant — the offset-free MPC's
    estimate of actuator faults). With ``|a_i| ≤ 1`` and ``d = 0`` the step equals
    :func:`step_function` of a fault-free env (and the env's step) to round-off."""
    pk, h, n_sub, Q, R, limits = _step_constants(env, nominal=True)
    y = casadi.SX.sym("y", slosh.N_STATE)
    a = casadi.SX.sym("a", 2)
    d = casadi.SX.sym("d", 2)
    applied = a * casadi.DM(limits) + d
    y_next, cost = _rk4_control_step(pk, h, n_sub, Q, R, y, applied[0], applied[1])
    return casadi.Function("fuel_slosh_nominal_step", [y, a, d], [y_next, cost], ["x", "a", "d"], ["x_next", "cost"])


def limits_function(env, n_x: int = slosh.N_STATE) -> casadi.Function:
    """``g(y) <= 0``: the env's termination limits on |ψ1|, |ψ2|, |Ω|, |θ| as the definition's 8
    linear rows, of a state of ``n_x`` entries whose first 10 are the plant's (the actuator
    chain's states after them are not limited)."""
    y = casadi.SX.sym("y", n_x)
    rows = list(_PLANT.limit_rows(y, env.max_slosh_angle_rad, env.max_pitch_rate_rad_s, env.max_pitch_angle_rad))
    chain = _chain(env) if n_x > slosh.N_STATE else None
    if chain is not None:  # the gimbal's rate limit on the queued command (flight, with a delay)
        rows += actuators.rate_limit_rows(chain, [y[slosh.N_STATE + i] for i in range(n_x - slosh.N_STATE)])
    return casadi.Function("fuel_slosh_limits", [y], [casadi.vertcat(*rows)], ["x"], ["g"])


def build_fuel_slosh(env) -> DiscreteProblem:
    """The :class:`DiscreteProblem` of the unwrapped FuelSlosh-v0 ``env`` right after its reset:
    the whole episode (``episode_duration_s / control_dt_s`` steps) from its start state (and
    the flight actuator chain at rest after it)."""
    n_steps = math.ceil(env.episode_duration_s / env.control_dt_s - 1e-9)
    chain = _chain(env)
    n_extra = 0 if chain is None else chain.n_state
    notes = (
        "exact step (same operations as the compiled kernel); termination limits as path "
        "constraints; sensors and the observation play no part (the oracle acts on the true state)"
    )
    x0 = np.asarray(env.state, float)
    if chain is not None:
        drawn = "; the drawn slosh masses and pendulum lengths exact (the env's kernel constants)"
        notes = "; ".join([notes + (drawn if "slosh_mass_kg" in env.drawn_parameters() else ""), *chain.notes()])
        x0 = np.concatenate([x0, np.zeros(n_extra)])
    elif env.drawn_parameters():
        notes += "; the drawn slosh masses and pendulum lengths exact (the env's kernel constants)"
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=slosh.N_STATE + n_extra,
        n_u=2,
        n_steps=n_steps,
        step=step_function(env),
        x0=x0,
        a_lb=-np.ones(2),
        a_ub=np.ones(2),
        g=limits_function(env, slosh.N_STATE + n_extra),
        notes=notes,
    )
