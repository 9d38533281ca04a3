"""The discrete problem of FuelSlosh-v0 (Navabi & Davoodi's planar two-pendulum slosh plant,
eqs. 11–14 in mass-matrix form) in CasADi: the same operations as the compiled step
:func:`attitude_envs.plants.slosh_kernels.control_step` — the translational block of
``M(ψ) ṡ = f + G`` eliminated in closed form, the 3×3 Schur complement solved by the unrolled
LDLᵀ, classical RK4 sub-steps with the stage cost ``xᵀQx + u_cᵀRu_c`` integrated as an extra
state — so states and step costs agree with the env to round-off.

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
from attitude_envs.plants import slosh_kernels as kernels
from attitude_envs.symbolic import actuators
from attitude_envs.symbolic.cost import quad_form
from attitude_envs.symbolic.problem import DiscreteProblem


def _mass_entries(pk, s1, c1, s2, c2):
    """:func:`attitude_envs.plants.slosh_kernels.mass_entries` (same operation order)."""
    mls1, mls2 = pk[kernels.P_ML1] * s1, pk[kernels.P_ML2] * s2
    mlc1, mlc2 = pk[kernels.P_ML1] * c1, pk[kernels.P_ML2] * c2
    m22 = pk[kernels.P_IRIGID] - 2.0 * (mlc1 * pk[kernels.P_A1] + mlc2 * pk[kernels.P_A2])
    return (
        pk[kernels.P_MT],
        mls1 + mls2,
        pk[kernels.P_SZ] + (mlc1 + mlc2),
        m22,
        mls1,
        mls2,
        mlc1,
        mlc2,
        pk[kernels.P_J1] - mlc1 * pk[kernels.P_A1],
        pk[kernels.P_J2] - mlc2 * pk[kernels.P_A2],
        pk[kernels.P_J1],
        pk[kernels.P_J2],
    )


def _force_entries(pk, y, sin_d, cos_d, moment, s1, c1, s2, c2):
    """:func:`attitude_envs.plants.slosh_kernels.force_entries` (same operation order)."""
    vx, vz, om, dp1, dp2 = y[5], y[6], y[7], y[8], y[9]
    ml1, ml2, a1, a2 = pk[kernels.P_ML1], pk[kernels.P_ML2], pk[kernels.P_A1], pk[kernels.P_A2]
    mt, sz = pk[kernels.P_MT], pk[kernels.P_SZ]
    w1 = (om + dp1) * (om + dp1)
    w2 = (om + dp2) * (om + dp2)
    fs, fc = pk[kernels.P_F] * sin_d, pk[kernels.P_F] * cos_d
    mls1, mls2 = ml1 * s1, ml2 * s2
    mlc1, mlc2 = ml1 * c1, ml2 * c2
    f0 = fc - mt * om * vz - sz * om * om - (mlc1 * w1 + mlc2 * w2)
    f1 = fs + mt * om * vx + (mls1 * w1 + mls2 * w2)
    f2 = (
        moment
        + pk[kernels.P_LEVER] * fs
        + om * vx * (sz + (mlc1 + mlc2))
        - om * vz * (mls1 + mls2)
        - (mls1 * a1 * (2.0 * om * dp1 + dp1 * dp1) + mls2 * a2 * (2.0 * om * dp2 + dp2 * dp2))
    )
    f3 = mls1 * a1 * om * om + ml1 * om * (vx * c1 - vz * s1) - pk[kernels.P_EPS1] * dp1
    f4 = mls2 * a2 * om * om + ml2 * om * (vx * c2 - vz * s2) - pk[kernels.P_EPS2] * dp2
    return f0, f1, f2, f3, f4


def derivative(pk: np.ndarray, y, sin_d, cos_d, moment) -> list:
    """ẏ (10 CasADi expressions) of the full state ``y`` under gimbal sin/cos and pitch moment
    (N·m): :func:`attitude_envs.plants.slosh_kernels.derivative_into` (same operation order)."""
    th, vx, vz, om = y[2], y[5], y[6], y[7]
    c, s = casadi.cos(th), casadi.sin(th)
    s1, c1 = casadi.sin(y[3]), casadi.cos(y[3])
    s2, c2 = casadi.sin(y[4]), casadi.cos(y[4])
    mt, m02, m12, m22, m03, m04, m13, m14, m23, m24, j1, j2 = _mass_entries(pk, s1, c1, s2, c2)
    f0, f1, f2, f3, f4 = _force_entries(pk, y, sin_d, cos_d, moment, s1, c1, s2, c2)
    inv_mt = 1.0 / mt
    s00 = m22 - (m02 * m02 + m12 * m12) * inv_mt
    s10 = m23 - (m03 * m02 + m13 * m12) * inv_mt
    s20 = m24 - (m04 * m02 + m14 * m12) * inv_mt
    s11 = j1 - (m03 * m03 + m13 * m13) * inv_mt
    s21 = -(m04 * m03 + m14 * m13) * inv_mt
    s22 = j2 - (m04 * m04 + m14 * m14) * inv_mt
    r0 = f2 - (m02 * f0 + m12 * f1) * inv_mt
    r1 = f3 - (m03 * f0 + m13 * f1) * inv_mt
    r2 = f4 - (m04 * f0 + m14 * f1) * inv_mt
    d0 = s00
    l10 = s10 / d0
    l20 = s20 / d0
    d1 = s11 - l10 * s10
    l21 = (s21 - l20 * s10) / d1
    d2 = s22 - l20 * s20 - l21 * l21 * d1
    z1 = r1 - l10 * r0
    z2 = r2 - l20 * r0 - l21 * z1
    ddp2 = z2 / d2
    ddp1 = z1 / d1 - l21 * ddp2
    dom = r0 / d0 - l10 * ddp1 - l20 * ddp2
    return [
        vx * c + vz * s,
        -vx * s + vz * c,
        om,
        y[8],
        y[9],
        (f0 - m02 * dom - m03 * ddp1 - m04 * ddp2) * inv_mt,
        (f1 - m12 * dom - m13 * ddp1 - m14 * ddp2) * inv_mt,
        dom,
        ddp1,
        ddp2,
    ]


def _augmented(pk, Q, R, aug, sin_d, cos_d, moment) -> list:
    """ẏ (10) and the stage cost xᵀQx + u_cᵀRu_c, u_c = [a_z, Ω̇] (the kernel's augmented state
    without the new-input integrals)."""
    dy = derivative(pk, aug, sin_d, cos_d, moment)
    a_z = dy[6] - aug[7] * aug[5]
    x = [aug[6], aug[2], aug[7], aug[3], aug[8], aug[4], aug[9]]
    return [*dy, quad_form(Q, x) + quad_form(R, [a_z, dy[7]])]


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
    pk = const[: kernels.N_PACKED]
    h = float(const[kernels.N_PACKED])
    n_sub = int(const[kernels.N_PACKED + 1])
    Q = np.asarray(env.model.cost.Q, float)
    R = np.asarray(env.model.cost.R, float)
    return pk, h, n_sub, Q, R, np.asarray(env.actuator_limits, float)


def _rk4_control_step(pk, h: float, n_sub: int, Q, R, y, delta, moment):
    """``(y_next, cost)``: ``n_sub`` classical RK4 sub-steps of ``h`` seconds of the state ``y``
    (10) and the stage-cost integral under the held gimbal angle ``delta`` (rad) and pitch
    moment ``moment`` (N·m) — the compiled kernel's control step (same operation order)."""
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
    """``g(y) <= 0``: the env's termination limits on |ψ1|, |ψ2|, |Ω|, |θ| as 8 linear rows."""
    y = casadi.SX.sym("y", slosh.N_STATE)
    rows = []
    for index, limit in (
        (slosh.IPSI1, env.max_slosh_angle_rad),
        (slosh.IPSI2, env.max_slosh_angle_rad),
        (slosh.IOM, env.max_pitch_rate_rad_s),
        (slosh.ITH, env.max_pitch_angle_rad),
    ):
        rows += [y[index] - limit, -y[index] - limit]
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
