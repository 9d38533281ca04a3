"""Compiled hot path of the fuel-slosh plant (numba): the definition's equations
(:mod:`attitude_envs.plants.slosh_definition`, compiled through
:data:`attitude_envs.plants.ops.NUMBA`) laid into the envs' buffers, and the RK4 control step
of FuelSlosh-v0 with the stage cost and the new inputs integrated as extra states. Used by the
single env, the batched env and (through the thin wrappers in
:mod:`attitude_envs.plants.slosh`) by the linearization, the input inversion and the physics
tests; no arrays beyond one scratch buffer per call.

Packed plant constants (``SloshParams.packed``): the definition's ``P_*`` layout. The control step takes them with the sub-step and the cost weights in one array
(:func:`step_constants`): few arguments keep numba's dispatch cheap.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from attitude_envs.plants.ops import NUMBA
from attitude_envs.plants.slosh_definition import N_PACKED, N_STATE, define

_PLANT = define(NUMBA)
N_AUG = N_STATE + 3  # state (10) + ∫cost + ∫a_z + ∫Ω̇
WORK_SIZE = 6 * N_AUG  # aug, stage input, 4 RK4 slopes
# step constants: packed plant, then h (s), n_sub, control period (s), Q (7×7, row-major), R (2×2)
_C_H = N_PACKED
_C_NSUB = N_PACKED + 1
_C_DT = N_PACKED + 2
_C_Q = N_PACKED + 3
_C_R = _C_Q + 49
N_CONSTANTS = _C_R + 4


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


mass_entries = _PLANT.mass_entries
force_entries = _PLANT.force_entries
invert_inputs = _PLANT.invert_inputs


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
def forces_into(pk, y, delta, moment, out):
    """``out`` (5) = the right-hand side of the mass-matrix form under gimbal angle δ (rad)."""
    s1, c1 = math.sin(y[3]), math.cos(y[3])
    s2, c2 = math.sin(y[4]), math.cos(y[4])
    f = force_entries(pk, y, math.sin(delta), math.cos(delta), moment, s1, c1, s2, c2)
    for i in range(5):
        out[i] = f[i]


_derivative = _PLANT.derivative
_augmented = _PLANT.augmented
_limit_rows = _PLANT.limit_rows


@njit(cache=True, error_model="numpy")
def limit_crossed(y, max_slosh_angle_rad, max_pitch_rate_rad_s, max_pitch_angle_rad):
    """Whether the full state ``y`` (10) is past a termination limit (a limit row of the
    definition > 0; rad, rad/s)."""
    crossed = False
    for g in _limit_rows(y, max_slosh_angle_rad, max_pitch_rate_rad_s, max_pitch_angle_rad):
        crossed = crossed or g > 0.0
    return crossed


@njit(cache=True, error_model="numpy")
def limits_crossed(states, max_slosh_angle_rad, max_pitch_rate_rad_s, max_pitch_angle_rad, out):
    """``out[e]`` = :func:`limit_crossed` of full state row ``e`` (E × 10)."""
    for e in range(states.shape[0]):
        out[e] = limit_crossed(states[e], max_slosh_angle_rad, max_pitch_rate_rad_s, max_pitch_angle_rad)


@njit(cache=True, error_model="numpy")
def derivative_into(pk, y, sin_d, cos_d, moment, out):
    """``out[:10] = ẏ`` of the full state ``y`` (see :mod:`attitude_envs.plants.slosh`) under
    gimbal sin/cos and pitch moment (N·m)."""
    dy = _derivative(pk, y, sin_d, cos_d, moment)
    for i in range(N_STATE):
        out[i] = dy[i]


@njit(cache=True, error_model="numpy")
def _augmented_into(pk, aug, sin_d, cos_d, moment, Q, R, out):
    """ẏ (10), the stage cost xᵀQx + u_cᵀRu_c and the new inputs u_c = [a_z, Ω̇] into ``out``."""
    dy, stage, a_z, dom = _augmented(pk, aug, sin_d, cos_d, moment, Q, R)
    for i in range(N_STATE):
        out[i] = dy[i]
    out[10] = stage
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
            _augmented_into(pk, tmp, sin_d, cos_d, moment, Q, R, ks[stage])
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
