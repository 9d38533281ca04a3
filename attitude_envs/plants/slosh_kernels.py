"""Compiled hot path of the fuel-slosh plant (numba): the one implementation of its mass
matrix, generalized forces and state derivative (Navabi & Davoodi, eqs. 11–14 in
mass-matrix form; closed forms of :mod:`attitude_envs.plants.slosh`), and the RK4 control
step of FuelSlosh-v0 with the stage cost and the new inputs integrated as extra states.
Used by the single env, the batched env and (through the thin wrappers in
:mod:`attitude_envs.plants.slosh`) by the linearization, the input inversion and the
physics tests.

Written for the sizes they have: the 5×5 mass matrix

    M = [[m_t I₂, C], [Cᵀ, D]],  C = [[Σ m_i l_i sψ_i, m_i l_i sψ_i], [S_z + Σ m_i l_i cψ_i, m_i l_i cψ_i]],
    D = [[I_θθ(ψ), J_i − m_i l_i a_i cψ_i], [·, diag(J_i)]]

has a scalar translational block, so the solve eliminates ``[v̇_x, v̇_z]`` in closed form
and solves the 3×3 symmetric positive definite Schur complement ``D − CᵀC / m_t`` (pitch
and slosh inertia seen by a free-floating body) by an unrolled LDLᵀ; no arrays beyond one
scratch buffer per call.

Packed plant constants (:func:`pack`, ``SloshParams.packed``), indices ``P_*``:
``[m_t, S_z, I_rigid, m1 l1, m2 l2, J1, J2, a1, a2, ε1, ε2, F, b + d]`` in kg, kg·m,
kg·m², kg·m, kg·m, kg·m², kg·m², m, m, kg·m²/s, kg·m²/s, N, m. The control step takes
them with the sub-step and the cost weights in one array (:func:`step_constants`): few
arguments keep numba's dispatch cheap.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from attitude_envs.plants.kernel_math import quad_form

P_MT, P_SZ, P_IRIGID, P_ML1, P_ML2, P_J1, P_J2, P_A1, P_A2, P_EPS1, P_EPS2, P_F, P_LEVER = range(13)
N_PACKED = 13
N_AUG = 13  # state (10) + ∫cost + ∫a_z + ∫Ω̇
WORK_SIZE = 6 * N_AUG + 9  # aug, stage input, 4 RK4 slopes, reduced state (7), new inputs (2)
# step constants: packed plant, then h (s), n_sub, control period (s), Q (7×7, row-major), R (2×2)
_C_H = N_PACKED
_C_NSUB = N_PACKED + 1
_C_DT = N_PACKED + 2
_C_Q = N_PACKED + 3
_C_R = _C_Q + 49
N_CONSTANTS = _C_R + 4


def pack(
    total_mass_kg: float,
    s_z: float,
    i_rigid: float,
    ml,
    J,
    hinge_m,
    damping,
    thrust_n: float,
    lever_arm_m: float,
) -> np.ndarray:
    """The packed constant vector (layout in the module docstring) of a slosh plant."""
    return np.array(
        [
            total_mass_kg,
            s_z,
            i_rigid,
            ml[0],
            ml[1],
            J[0],
            J[1],
            hinge_m[0],
            hinge_m[1],
            damping[0],
            damping[1],
            thrust_n,
            lever_arm_m,
        ],
        dtype=float,
    )


def step_constants(
    packed: np.ndarray, h_s: float, n_sub: int, control_dt_s: float, Q: np.ndarray, R: np.ndarray
) -> np.ndarray:
    """One read-only array of everything :func:`control_step` holds fixed: the packed plant,
    the RK4 sub-step ``h_s`` (s), the number of sub-steps, the control period (s), the cost
    weights Q (7×7) on ``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` and R (2×2) on ``[a_z, Ω̇]``."""
    out = np.concatenate(
        [packed, [h_s, n_sub, control_dt_s], np.asarray(Q, float).ravel(), np.asarray(R, float).ravel()]
    )
    if out.shape != (N_CONSTANTS,):
        raise ValueError(f"step constants need 13 plant values, Q 7x7 and R 2x2; got {out.shape[0]} values")
    out.setflags(write=False)
    return out


@njit(cache=True, error_model="numpy")
def mass_entries(pk, s1, c1, s2, c2):
    """The distinct entries of M(ψ) from sin/cos of ψ1, ψ2: ``(m_t, M02, M12, M22, M03,
    M04, M13, M14, M23, M24, J1, J2)`` (M33 = J1, M44 = J2, M01 = M34 = 0)."""
    mls1, mls2 = pk[P_ML1] * s1, pk[P_ML2] * s2
    mlc1, mlc2 = pk[P_ML1] * c1, pk[P_ML2] * c2
    m22 = pk[P_IRIGID] - 2.0 * (mlc1 * pk[P_A1] + mlc2 * pk[P_A2])
    return (
        pk[P_MT],
        mls1 + mls2,
        pk[P_SZ] + (mlc1 + mlc2),
        m22,
        mls1,
        mls2,
        mlc1,
        mlc2,
        pk[P_J1] - mlc1 * pk[P_A1],
        pk[P_J2] - mlc2 * pk[P_A2],
        pk[P_J1],
        pk[P_J2],
    )


@njit(cache=True, error_model="numpy")
def mass_matrix_into(pk, psi1, psi2, out):
    """``out`` (5×5) = M(ψ) of ``s = [v_x, v_z, Ω, ψ̇1, ψ̇2]``."""
    mt, m02, m12, m22, m03, m04, m13, m14, m23, m24, j1, j2 = mass_entries(
        pk, math.sin(psi1), math.cos(psi1), math.sin(psi2), math.cos(psi2)
    )
    for i in range(5):
        for j in range(5):
            out[i, j] = 0.0
    out[0, 0] = out[1, 1] = mt
    out[0, 2] = out[2, 0] = m02
    out[1, 2] = out[2, 1] = m12
    out[2, 2] = m22
    out[0, 3] = out[3, 0] = m03
    out[0, 4] = out[4, 0] = m04
    out[1, 3] = out[3, 1] = m13
    out[1, 4] = out[4, 1] = m14
    out[2, 3] = out[3, 2] = m23
    out[2, 4] = out[4, 2] = m24
    out[3, 3] = j1
    out[4, 4] = j2


@njit(cache=True, error_model="numpy")
def force_entries(pk, y, sin_d, cos_d, moment, s1, c1, s2, c2):
    """``f(s, ψ) + G(δ, M_c)`` (5 values, N and N·m) at state ``y`` with gimbal sin/cos
    and pitch moment (N·m), given sin/cos of ψ1, ψ2."""
    vx, vz, om = y[5], y[6], y[7]
    dp1, dp2 = y[8], y[9]
    ml1, ml2, a1, a2 = pk[P_ML1], pk[P_ML2], pk[P_A1], pk[P_A2]
    w1 = (om + dp1) * (om + dp1)
    w2 = (om + dp2) * (om + dp2)
    fs, fc = pk[P_F] * sin_d, pk[P_F] * cos_d
    mls1, mls2 = ml1 * s1, ml2 * s2
    mlc1, mlc2 = ml1 * c1, ml2 * c2
    f0 = fc - pk[P_MT] * om * vz - pk[P_SZ] * om * om - (mlc1 * w1 + mlc2 * w2)
    f1 = fs + pk[P_MT] * om * vx + (mls1 * w1 + mls2 * w2)
    f2 = (
        moment
        + pk[P_LEVER] * fs
        + om * vx * (pk[P_SZ] + (mlc1 + mlc2))
        - om * vz * (mls1 + mls2)
        - (mls1 * a1 * (2.0 * om * dp1 + dp1 * dp1) + mls2 * a2 * (2.0 * om * dp2 + dp2 * dp2))
    )
    f3 = mls1 * a1 * om * om + ml1 * om * (vx * c1 - vz * s1) - pk[P_EPS1] * dp1
    f4 = mls2 * a2 * om * om + ml2 * om * (vx * c2 - vz * s2) - pk[P_EPS2] * dp2
    return f0, f1, f2, f3, f4


@njit(cache=True, error_model="numpy")
def forces_into(pk, y, delta, moment, out):
    """``out`` (5) = the right-hand side of the mass-matrix form under gimbal angle δ (rad)."""
    s1, c1 = math.sin(y[3]), math.cos(y[3])
    s2, c2 = math.sin(y[4]), math.cos(y[4])
    f = force_entries(pk, y, math.sin(delta), math.cos(delta), moment, s1, c1, s2, c2)
    for i in range(5):
        out[i] = f[i]


@njit(cache=True, error_model="numpy")
def derivative_into(pk, y, sin_d, cos_d, moment, out):
    """``out[:10] = ẏ`` of the full state ``y`` (see :mod:`attitude_envs.plants.slosh`) under
    gimbal sin/cos and pitch moment (N·m): kinematics, then ``M ṡ = f + G`` solved by
    eliminating the translational block and an LDLᵀ of the 3×3 Schur complement."""
    th, vx, vz, om = y[2], y[5], y[6], y[7]
    c, s = math.cos(th), math.sin(th)
    out[0] = vx * c + vz * s
    out[1] = -vx * s + vz * c
    out[2] = om
    out[3] = y[8]
    out[4] = y[9]
    s1, c1 = math.sin(y[3]), math.cos(y[3])
    s2, c2 = math.sin(y[4]), math.cos(y[4])
    mt, m02, m12, m22, m03, m04, m13, m14, m23, m24, j1, j2 = mass_entries(pk, s1, c1, s2, c2)
    f0, f1, f2, f3, f4 = force_entries(pk, y, sin_d, cos_d, moment, s1, c1, s2, c2)
    # Schur complement S = D − CᵀC/m_t on [Ω̇, ψ̈1, ψ̈2], rhs r = f_rot − Cᵀ f_trans/m_t
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
    # LDLᵀ (S is symmetric positive definite: no pivoting)
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
    out[5] = (f0 - m02 * dom - m03 * ddp1 - m04 * ddp2) * inv_mt
    out[6] = (f1 - m12 * dom - m13 * ddp1 - m14 * ddp2) * inv_mt
    out[7] = dom
    out[8] = ddp1
    out[9] = ddp2


@njit(cache=True, error_model="numpy")
def _augmented_into(pk, aug, sin_d, cos_d, moment, Q, R, xbuf, ubuf, out):
    """ẏ (10), the stage cost xᵀQx + u_cᵀRu_c and the new inputs u_c = [a_z, Ω̇]."""
    derivative_into(pk, aug, sin_d, cos_d, moment, out)
    a_z = out[6] - aug[7] * aug[5]  # a_z = v̇_z − Ω v_x (tank centre)
    dom = out[7]
    # reduced state x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]
    xbuf[0] = aug[6]
    xbuf[1] = aug[2]
    xbuf[2] = aug[7]
    xbuf[3] = aug[3]
    xbuf[4] = aug[8]
    xbuf[5] = aug[4]
    xbuf[6] = aug[9]
    ubuf[0] = a_z
    ubuf[1] = dom
    out[10] = quad_form(Q, xbuf, 7) + quad_form(R, ubuf, 2)
    out[11] = a_z
    out[12] = dom


@njit(cache=True, error_model="numpy")
def control_step(state, inputs, constants, new_inputs_out, work):
    """Advance ``state`` (10, in place) over ``n_sub`` RK4 sub-steps of ``h`` seconds with
    ``inputs = [δ (rad), M_c (N·m)]`` held (plant, ``h``, ``n_sub``, Q, R from
    :func:`step_constants`). Returns the step cost ∫(xᵀQx + u_cᵀRu_c) dt;
    ``new_inputs_out`` receives the step means of ``[a_z, Ω̇]`` (m/s², rad/s²). ``work``
    holds :data:`WORK_SIZE` floats (no allocation in the hot path)."""
    pk = constants[:N_PACKED]
    h = constants[_C_H]
    n_sub = int(constants[_C_NSUB])
    Q = constants[_C_Q:_C_R].reshape((7, 7))
    R = constants[_C_R:N_CONSTANTS].reshape((2, 2))
    n = N_AUG
    aug = work[0:n]
    tmp = work[n : 2 * n]
    ks = work[2 * n : 6 * n].reshape((4, n))
    xbuf = work[6 * n : 6 * n + 7]
    ubuf = work[6 * n + 7 : 6 * n + 9]
    sin_d, cos_d, moment = math.sin(inputs[0]), math.cos(inputs[0]), inputs[1]
    for i in range(10):
        aug[i] = state[i]
    for i in range(10, n):
        aug[i] = 0.0
    for _ in range(n_sub):
        for stage in range(4):  # classical RK4: stages at t, t + h/2, t + h/2, t + h
            if stage == 0:
                for i in range(n):
                    tmp[i] = aug[i]
            else:
                cst = h if stage == 3 else 0.5 * h
                for i in range(n):
                    tmp[i] = aug[i] + cst * ks[stage - 1, i]
            _augmented_into(pk, tmp, sin_d, cos_d, moment, Q, R, xbuf, ubuf, ks[stage])
        for i in range(n):
            aug[i] += (h / 6.0) * (ks[0, i] + 2.0 * ks[1, i] + 2.0 * ks[2, i] + ks[3, i])
    for i in range(10):
        state[i] = aug[i]
    new_inputs_out[0] = aug[11] / constants[_C_DT]
    new_inputs_out[1] = aug[12] / constants[_C_DT]
    return aug[10]


@njit(cache=True, error_model="numpy")
def control_step_batch(states, inputs, constants, new_inputs_out, costs_out, work):
    """:func:`control_step` for every row of ``states`` and ``inputs`` (E × 2), serially
    (numba threads lose to oversubscription on small machines, see benchmarks/); shared
    constants and one ``work`` buffer."""
    for e in range(states.shape[0]):
        costs_out[e] = control_step(states[e], inputs[e], constants, new_inputs_out[e], work)
