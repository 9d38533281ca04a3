"""Compiled hot path of the gyrostat (numba): one implementation of the equations of motion,
the error state, the stage cost and the RK4 control step, used by the single env, the batched
vector env and (through thin wrappers in :mod:`attitude_envs.plants.gyrostat`) by the tests.

Written for the sizes they have: scalar loops over 3-vectors and N wheels, no temporaries
beyond a few small work buffers per call. Equations: see :mod:`attitude_envs.plants.gyrostat`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from attitude_envs.plants.kernel_math import quad_form


@njit(cache=True, error_model="numpy")
def derivative_into(y, u, ext, inertia, inertia_eff_inv, axes, j_s, out, offset=None):
    """``out[:7+N] = ẏ`` for ``y = [q (4), ω (3), Ω (N)]``, motor torques ``u`` (N, N·m),
    external torque ``ext`` (3, N·m, body axes).

    ``offset`` (3, N·m, optional): the centre-of-mass offset torque vector ``p = m g r_s``
    of a platform on a spherical air bearing (spec 003 eq. 6–9): the body receives
    ``p × K`` with ``K = R(q)ᵀ e_Z`` the unit gravity direction (inertial +Z, "down") in
    body axes, ``K = [−sθ, sφcθ, cφcθ]`` in 3-2-1 Euler angles (eq. 7).
    """
    n = axes.shape[1]
    w0, w1, w2 = y[4], y[5], y[6]
    h0 = inertia[0, 0] * w0 + inertia[0, 1] * w1 + inertia[0, 2] * w2
    h1 = inertia[1, 0] * w0 + inertia[1, 1] * w1 + inertia[1, 2] * w2
    h2 = inertia[2, 0] * w0 + inertia[2, 1] * w1 + inertia[2, 2] * w2
    r0, r1, r2 = ext[0], ext[1], ext[2]
    if offset is not None:
        qx, qy, qz, qw = y[0], y[1], y[2], y[3]
        k0 = 2.0 * (qx * qz - qy * qw)
        k1 = 2.0 * (qy * qz + qx * qw)
        k2 = 1.0 - 2.0 * (qx * qx + qy * qy)
        r0 += offset[1] * k2 - offset[2] * k1
        r1 += offset[2] * k0 - offset[0] * k2
        r2 += offset[0] * k1 - offset[1] * k0
    for i in range(n):
        hw = j_s * y[7 + i]
        h0 += axes[0, i] * hw
        h1 += axes[1, i] * hw
        h2 += axes[2, i] * hw
        r0 -= axes[0, i] * u[i]
        r1 -= axes[1, i] * u[i]
        r2 -= axes[2, i] * u[i]
    r0 -= w1 * h2 - w2 * h1
    r1 -= w2 * h0 - w0 * h2
    r2 -= w0 * h1 - w1 * h0
    d0 = inertia_eff_inv[0, 0] * r0 + inertia_eff_inv[0, 1] * r1 + inertia_eff_inv[0, 2] * r2
    d1 = inertia_eff_inv[1, 0] * r0 + inertia_eff_inv[1, 1] * r1 + inertia_eff_inv[1, 2] * r2
    d2 = inertia_eff_inv[2, 0] * r0 + inertia_eff_inv[2, 1] * r1 + inertia_eff_inv[2, 2] * r2
    x, yq, z, s = y[0], y[1], y[2], y[3]
    out[0] = 0.5 * (s * w0 + yq * w2 - z * w1)
    out[1] = 0.5 * (s * w1 + z * w0 - x * w2)
    out[2] = 0.5 * (s * w2 + x * w1 - yq * w0)
    out[3] = -0.5 * (x * w0 + yq * w1 + z * w2)
    out[4] = d0
    out[5] = d1
    out[6] = d2
    for i in range(n):
        out[7 + i] = u[i] / j_s - (axes[0, i] * d0 + axes[1, i] * d1 + axes[2, i] * d2)


@njit(cache=True, error_model="numpy")
def error_state_into(y, q_target, j_s, include_h, n_wheels, out):
    """``out = x = [q_e,vec, ω, (J_s Ω)]`` with ``q_e = q_T* ⊗ q/|q|`` (w ≥ 0); returns ``q_e,w``."""
    norm = np.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    qx, qy, qz, qw = y[0] / norm, y[1] / norm, y[2] / norm, y[3] / norm
    px, py, pz, pw = -q_target[0], -q_target[1], -q_target[2], q_target[3]
    ex = pw * qx + px * qw + py * qz - pz * qy
    ey = pw * qy - px * qz + py * qw + pz * qx
    ez = pw * qz + px * qy - py * qx + pz * qw
    ew = pw * qw - px * qx - py * qy - pz * qz
    if ew < 0.0:
        ex, ey, ez, ew = -ex, -ey, -ez, -ew
    out[0] = ex
    out[1] = ey
    out[2] = ez
    out[3] = y[4]
    out[4] = y[5]
    out[5] = y[6]
    if include_h:
        for i in range(n_wheels):
            out[6 + i] = j_s * y[7 + i]
    return ew


@njit(cache=True, error_model="numpy")
def stage_cost(y, u, q_target, axes, j_s, Q, R, body_input, include_h, xbuf, ubuf):
    """``xᵀQx + u_cᵀRu_c`` with ``u_c = −A u`` (``body_input``) or ``u``."""
    n = axes.shape[1]
    error_state_into(y, q_target, j_s, include_h, n, xbuf)
    total = quad_form(Q, xbuf, Q.shape[0])
    if body_input:
        for k in range(3):
            acc = 0.0
            for i in range(n):
                acc -= axes[k, i] * u[i]
            ubuf[k] = acc
        m = 3
    else:
        for i in range(n):
            ubuf[i] = u[i]
        m = n
    return total + quad_form(R, ubuf, m)


@njit(cache=True, error_model="numpy")
def speed_limit_into(cmd, wheel, max_torque, max_speed, j_s, h, out):
    """Motor torque (N·m) after the torque limit and the motor driver's speed limit: over
    the next ``h`` seconds the torque may take a wheel up to ``±max_speed`` but not beyond
    it (ignoring the small body-coupling term ``a_i·ω̇``), so a wheel at its limit gets no
    further torque outwards."""
    n = cmd.shape[0]
    for i in range(n):
        v = min(max(cmd[i], -max_torque), max_torque)
        if max_speed < np.inf:
            hi = j_s / h * (max_speed - wheel[i])
            lo = j_s / h * (-max_speed - wheel[i])
            v = min(max(v, lo), hi)
            v = min(max(v, -max_torque), max_torque)
        out[i] = v


@njit(cache=True, error_model="numpy")
def _augmented(
    aug, u, ext, inertia, inertia_eff_inv, axes, j_s, q_target, Q, R, body_input, include_h, xbuf, ubuf, out, offset
):
    derivative_into(aug, u, ext, inertia, inertia_eff_inv, axes, j_s, out, offset)
    out[aug.shape[0] - 1] = stage_cost(aug, u, q_target, axes, j_s, Q, R, body_input, include_h, xbuf, ubuf)


def work_size(n_wheels: int, n_state: int) -> int:
    """Length of the scratch buffer :func:`control_step` needs (allocated once by the caller)."""
    return 6 * (8 + n_wheels) + n_wheels + n_state + max(3, n_wheels)


@njit(cache=True, error_model="numpy")
def control_step(state, cmd, ext_stages, mats, axes, scalars, flags, q_target, Q, R, applied_out, work):
    """Advance ``state = [q, ω, Ω]`` (in place) over ``n_sub`` RK4 sub-steps of ``h`` seconds
    with the motor command ``cmd`` held; the stage cost is integrated as an extra state.

    Packed arguments (few arguments keep numba's dispatch cheap): ``mats = [I, I_eff⁻¹]``
    (2×3×3), ``scalars = [J_s, max_torque, max_speed, h, p_x, p_y, p_z]`` (``p``: the
    centre-of-mass offset torque vector of :func:`derivative_into`, zeros for a free body), ``flags = [n_sub, body_input,
    include_h]``. ``ext_stages[j, k]`` is the external torque at sub-step ``j``, RK4 stage
    time ``t_j + (0, h/2, h)[k]``. The quaternion is renormalized after each sub-step.
    ``applied_out`` receives the mean motor torque delivered; returns the step cost.
    ``work`` is a scratch buffer of :func:`work_size` floats (no allocation in the hot path).
    """
    inertia = mats[0]
    inertia_eff_inv = mats[1]
    j_s, max_torque, max_speed, h = scalars[0], scalars[1], scalars[2], scalars[3]
    offset = scalars[4:7]
    n_sub, body_input, include_h = flags[0], flags[1] != 0, flags[2] != 0
    n = axes.shape[1]
    size = 8 + n
    aug = work[0:size]
    tmp = work[size : 2 * size]
    ks = work[2 * size : 6 * size].reshape((4, size))
    u = work[6 * size : 6 * size + n]
    xbuf = work[6 * size + n : 6 * size + n + Q.shape[0]]
    ubuf = work[6 * size + n + Q.shape[0] :]
    for i in range(size - 1):
        aug[i] = state[i]
    aug[size - 1] = 0.0
    for i in range(n):
        applied_out[i] = 0.0
    for j in range(n_sub):
        speed_limit_into(cmd, aug[7 : 7 + n], max_torque, max_speed, j_s, h, u)
        for i in range(n):
            applied_out[i] += u[i] / n_sub
        for stage in range(4):  # classical RK4: stages at t, t + h/2, t + h/2, t + h
            if stage == 0:
                for i in range(size):
                    tmp[i] = aug[i]
            else:
                c = h if stage == 3 else 0.5 * h
                for i in range(size):
                    tmp[i] = aug[i] + c * ks[stage - 1, i]
            ext = ext_stages[j, (stage + 1) // 2]
            _augmented(
                tmp,
                u,
                ext,
                inertia,
                inertia_eff_inv,
                axes,
                j_s,
                q_target,
                Q,
                R,
                body_input,
                include_h,
                xbuf,
                ubuf,
                ks[stage],
                offset,
            )
        for i in range(size):
            aug[i] += (h / 6.0) * (ks[0, i] + 2.0 * ks[1, i] + 2.0 * ks[2, i] + ks[3, i])
        norm = np.sqrt(aug[0] * aug[0] + aug[1] * aug[1] + aug[2] * aug[2] + aug[3] * aug[3])
        for i in range(4):
            aug[i] /= norm
    for i in range(size - 1):
        state[i] = aug[i]
    return aug[size - 1]


@njit(cache=True, error_model="numpy")
def control_step_batch(
    states, cmds, ext_stages, mats, axes, scalars, flags, q_targets, Q, R, applied_out, costs_out, work
):
    """:func:`control_step` for ``E`` envs at once, serially (numba's threads lost to
    oversubscription on the 2-core machines this was measured on; see benchmarks/): rows of ``states``, ``cmds``,
    ``q_targets``, ``applied_out``; per-env ``mats`` (E, 2, 3, 3) and ``ext_stages``
    (E, n_sub, 3, 3); shared wheels, limits, weights; ``work`` (E, work_size)."""
    for e in range(states.shape[0]):
        costs_out[e] = control_step(
            states[e],
            cmds[e],
            ext_stages[e],
            mats[e],
            axes,
            scalars,
            flags,
            q_targets[e],
            Q,
            R,
            applied_out[e],
            work[e],
        )


@njit(cache=True, error_model="numpy")
def error_state_batch(states, q_targets, j_s, include_h, out, qe_w_out):
    """:func:`error_state_into` for every row of ``states``."""
    n = states.shape[1] - 7
    for e in range(states.shape[0]):
        qe_w_out[e] = error_state_into(states[e], q_targets[e], j_s, include_h, n, out[e])
