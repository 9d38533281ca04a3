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
"""

from __future__ import annotations

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
    """``(y (10), a (2), k (1)) -> (y_next (10), cost (1))``: one FuelSlosh-v0 control step of
    the unwrapped ``env`` (its kernel constants, limits and this episode's realized faults)."""
    pk, h, n_sub, Q, R, limits = _step_constants(env)
    y = casadi.SX.sym("y", slosh.N_STATE)
    a = casadi.SX.sym("a", 2)
    k = casadi.SX.sym("k")
    commanded = actuators.clip(a, -1.0, 1.0) * casadi.DM(limits)
    applied = actuators.delivered(commanded, k * env.control_dt_s, env.fault_layer.realized, limits)
    y_next, cost = _rk4_control_step(pk, h, n_sub, Q, R, y, applied[0], applied[1])
    return casadi.Function("fuel_slosh_step", [y, a, k], [y_next, cost], ["x", "a", "k"], ["x_next", "cost"])


def _step_constants(env) -> tuple:
    """``(packed plant constants, RK4 sub-step h (s), sub-steps per control step, Q, R,
    actuator limits)`` of the unwrapped FuelSlosh-v0 ``env``: what both symbolic steps read."""
    const = np.asarray(env.kernel_constants)
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
    pk, h, n_sub, Q, R, limits = _step_constants(env)
    y = casadi.SX.sym("y", slosh.N_STATE)
    a = casadi.SX.sym("a", 2)
    d = casadi.SX.sym("d", 2)
    applied = a * casadi.DM(limits) + d
    y_next, cost = _rk4_control_step(pk, h, n_sub, Q, R, y, applied[0], applied[1])
    return casadi.Function("fuel_slosh_nominal_step", [y, a, d], [y_next, cost], ["x", "a", "d"], ["x_next", "cost"])


def limits_function(env) -> casadi.Function:
    """``g(y) <= 0``: the env's termination limits on |ψ1|, |ψ2|, |Ω|, |θ| as the definition's 8
    linear rows."""
    y = casadi.SX.sym("y", slosh.N_STATE)
    rows = _PLANT.limit_rows(y, env.max_slosh_angle_rad, env.max_pitch_rate_rad_s, env.max_pitch_angle_rad)
    return casadi.Function("fuel_slosh_limits", [y], [casadi.vertcat(*rows)], ["x"], ["g"])


def build_fuel_slosh(env) -> DiscreteProblem:
    """The :class:`DiscreteProblem` of the unwrapped FuelSlosh-v0 ``env`` right after its reset:
    the whole episode (``episode_duration_s / control_dt_s`` steps) from its start state."""
    n_steps = math.ceil(env.episode_duration_s / env.control_dt_s - 1e-9)
    return DiscreteProblem(
        env_id=env.env_name,
        n_x=slosh.N_STATE,
        n_u=2,
        n_steps=n_steps,
        step=step_function(env),
        x0=np.asarray(env.state, float),
        a_lb=-np.ones(2),
        a_ub=np.ones(2),
        g=limits_function(env),
        notes=(
            "exact step (same operations as the compiled kernel); termination limits as path "
            "constraints; sensors and the observation play no part (the oracle acts on the true state)"
        ),
    )
