"""Compiled hot path of the gyrostat (numba): one implementation of the equations of motion,
the error state, the stage cost and the RK4 control step, used by the single env, the batched
vector env and (through thin wrappers in :mod:`attitude_envs.plants.gyrostat`) by the tests.

Layout: blocked struct of arrays. The step works on blocks of ``lanes`` envs: per-env
inputs are (n_blocks, rows, lanes) arrays (:func:`blocks`) and each block is copied into a
scratch buffer whose rows are ``lanes`` floats long, so every inner loop runs over the env
index with unit stride and constant row offsets, and LLVM turns it into SIMD instructions.
Each env is one SIMD lane and nothing mixes lanes, so a lane computes the same IEEE
operations in the same order whatever the vector width: the single env (``lanes=1``) and
the batched env (``lanes=``:data:`BATCH_LANES`) agree bit for bit. No fastmath: no
reassociation, no fused multiply-add contraction.

:func:`step_kernel` compiles one kernel per wheel count, block width and cost/offset layout
(compile-time constants: the wheel and cost loops unroll); any wheel count works, and numba
caches each on disk (the first use of a new layout compiles for ~5–25 s). Equations: see
:mod:`attitude_envs.plants.gyrostat`.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from attitude_envs.plants.gyrostat_definition import (
    MAT_ROWS,
    N_SCALARS,
    S_DT,
    S_DURATION,
    S_H,
    S_JS,
    S_MAX_RATE,
    S_MAX_SPEED,
    S_MAX_TORQUE,
    S_TILT_COS,
    S_TILT_SIN,
    define,
)
from attitude_envs.plants.ops import NUMBA

#: Block width of the batched step (envs per SIMD block). 64 lanes keep one block's
#: scratch rows (~10 kB for 4 wheels) in the L1 cache.
BATCH_LANES = 64


def pack_constants(
    axes: np.ndarray,
    q_mat: np.ndarray,
    r_mat: np.ndarray,
    wheel_inertia_kg_m2: float,
    max_torque_nm: float,
    max_speed_rad_s: float,
    integrator_dt_s: float,
    offset_torque_nm: np.ndarray,
    max_rate_rad_s: float = np.inf,
    control_dt_s: float = 0.0,
    episode_duration_s: float = np.inf,
    tilt_limit_rad: float = np.inf,
) -> np.ndarray:
    """The shared constants of a step in one float64 vector: ``axes`` (3×N, row-major),
    ``Q``, ``R`` (row-major), then ``J_s`` (kg·m²), torque limit (N·m), speed limit (rad/s),
    ``h`` (s), offset torque ``p`` (3, N·m), tumble limit (rad/s), control period (s),
    episode duration (s), and the sine and cosine of the roll/pitch stop ``tilt_limit_rad``
    (in (0, π/2); infinite: none) of :func:`tilt_exceeded`. Kept apart from the scratch
    buffer (see :class:`_Rows`)."""
    if np.isfinite(tilt_limit_rad):
        tilt_sin, tilt_cos = float(np.sin(tilt_limit_rad)), float(np.cos(tilt_limit_rad))
    else:
        tilt_sin, tilt_cos = 2.0, -2.0  # never: |sin θ| <= 1 and cos φ >= -1
    scalars = [
        wheel_inertia_kg_m2,
        max_torque_nm,
        max_speed_rad_s,
        integrator_dt_s,
        *np.asarray(offset_torque_nm, dtype=float),
        max_rate_rad_s,
        control_dt_s,
        episode_duration_s,
        tilt_sin,
        tilt_cos,
    ]
    return np.concatenate([np.ravel(axes), np.ravel(q_mat), np.ravel(r_mat), np.asarray(scalars, dtype=float)])


def pack_matrices(inertia: np.ndarray, inertia_eff_inv: np.ndarray) -> np.ndarray:
    """One env's column of the per-env matrix rows (:data:`MAT_ROWS`)."""
    return np.concatenate([np.ravel(inertia), np.ravel(inertia_eff_inv)])


# ---------------------------------------------------------------------------- lane math
# The plant definition's row functions (attitude_envs.plants.gyrostat_definition): each
# computes one env (lane ``e``) of a block, row ``r`` of the scratch buffer ``W`` at
# ``W[r * B + e]``, the shared constants in ``C`` (:func:`pack_constants`); inlined into the
# step's loops over ``e`` (numba IR inlining), so those loops vectorize.
_G = define(NUMBA)
_derivative_lane = _G.derivative_lane
_error_state_lane = _G.error_state_lane
_state_cost_lane = _G.state_cost_lane
_input_terms_lane = _G.input_terms_lane
_tilt_lane = _G.tilt_lane
_clip = _G.clip
_speed_limit_lane = _G.speed_limit_lane


@njit(cache=True, error_model="numpy")
def tilt_exceeded(q, constants):
    """:func:`_tilt_lane` of one quaternion ``q`` with the stop of :func:`pack_constants`'s
    ``constants`` (the single env's ``info``; the step uses the same test)."""
    sc = constants.shape[0] - N_SCALARS
    return _tilt_lane(q[0], q[1], q[2], q[3], constants[sc + S_TILT_SIN], constants[sc + S_TILT_COS])


class _Rows:
    """Layout of the step's constants vector (:func:`pack_constants`) and of its scratch
    buffer, rows of ``lanes`` floats (row ``r`` at ``r * lanes``), for ``n`` wheels:
    compile-time constants of the kernel. The constants stay in their own array: a
    loop-invariant load from the scratch array being written would stop LLVM's vectorizer."""

    def __init__(self, n: int, lanes: int, include_h: bool, body_input: bool) -> None:
        self.n_state = 6 + n if include_h else 6
        self.m_cost = 3 if body_input else n
        self.ax = 0  # constants: axes (3n), Q, R, scalars (pack_constants)
        self.cq = 3 * n
        self.cr = self.cq + self.n_state * self.n_state
        self.sc = self.cr + self.m_cost * self.m_cost
        self.n_const = self.sc + N_SCALARS
        self.size = size = 8 + n  # state + integrated cost
        self.aug = 0
        self.k = self.aug + size  # current RK4 stage's derivative
        self.acc = self.k + size  # weighted sum of the stages
        self.tmp = self.acc + size  # current stage's input
        self.u = self.tmp + size  # motor torque (N·m)
        self.cmd = self.u + n  # commanded torque (N·m)
        self.app = self.cmd + n  # mean torque delivered (N·m)
        self.mat = self.app + n
        self.target = self.mat + MAT_ROWS
        self.x = self.target + 4
        self.uc = self.x + self.n_state
        self.uj = self.uc + max(3, n)  # u / J_s
        self.ru = self.uj + n  # input cost u_cᵀRu_c
        self.ext = self.ru + 1  # external torque at the current stage's time
        self.qe_w = self.ext + 3  # outputs: q_e,w, 0 if finite (else NaN), max |ω|, tilt
        self.finite = self.qe_w + 1
        self.rate = self.finite + 1
        self.tilt = self.rate + 1  # 1 if beyond the roll/pitch stop, else 0
        self.n_rows = self.tilt + 1


def work_size(n_wheels: int, lanes: int, include_h: bool, body_input: bool) -> int:
    """Length of the scratch buffer of :func:`step_kernel`'s kernel (allocated once by the
    caller; no allocation in the hot path)."""
    return _Rows(n_wheels, lanes, include_h, body_input).n_rows * lanes


def kernel_for(model, lanes: int, offset_torque_nm: np.ndarray | None = None):
    """:func:`step_kernel` for a :class:`~attitude_envs.plants.gyrostat_model.ReactionWheelModel`
    whose true plant has the offset torque ``offset_torque_nm`` (N·m; None: the model's)."""
    offset = model.params.offset_torque_nm if offset_torque_nm is None else offset_torque_nm
    q = model.cost.Q
    return step_kernel(
        model.params.n_wheels,
        lanes,
        model.include_wheel_momentum,
        model.cost_input == "body",
        bool(np.array_equal(q, np.diag(np.diag(q)))),
        bool(np.any(np.asarray(offset) != 0.0)),
    )


@functools.cache
def step_kernel(n_wheels: int, lanes: int, include_h: bool, body_input: bool, diagonal_q: bool, offset: bool):
    """The compiled batched step for ``n_wheels`` wheels, blocks of ``lanes`` envs, the
    cost layout (``include_h``: wheel momentum in ``x``; ``body_input``: cost on the body
    torque ``−A u``; ``diagonal_q``: ``Q`` is diagonal, its zeros are skipped) and the
    offset torque (``offset``: ``p ≠ 0``, else left out), memoized (numba also caches it
    on disk)::

        kernel(Y, cmd, scale, ext, M, T, constants, n_sub, steps, time_s,
               applied, cost, reward, obs, qe_w, terminated, truncated, observe_wheels, W)

    Per-env inputs are blocked struct-of-arrays (see :func:`blocks`): ``Y`` (nb, 7+N,
    lanes) the states ``[q, ω, Ω]``, ``M`` (nb, 18, lanes) :func:`pack_matrices`, ``T``
    (nb, 4, lanes) the targets, ``ext`` (nb, 9·n_sub, lanes) external torques (row
    ``9j + 3k + c``: sub-step ``j``, RK4 stage time ``t_j + (0, h/2, h)[k]``, axis ``c``;
    N·m) or (nb, 0, lanes) for none. Env ``g`` is lane ``g % lanes`` of block
    ``g // lanes``; lanes past the ``E`` envs are padding (computed, never reported).

    Advances ``Y`` in place over ``n_sub`` RK4 sub-steps of ``h`` with the motor command
    held, the stage cost integrated as an extra state and the quaternion renormalized
    after each sub-step. ``cmd`` (E, N): normalized actions (``scale``: clipped to [−1, 1]
    and times the torque limit, as the env does) or motor torques (N·m). ``constants``:
    :func:`pack_constants`; ``steps`` (E, int): step counters, incremented; ``time_s``
    (E): output, ``steps · control_dt_s``.

    Outputs per env: ``applied`` (E, N) mean motor torque delivered (N·m), ``cost`` (E) the
    step cost and ``reward`` (E) its negative, ``obs`` (E, n_obs) float32 ``[x, (Ω/Ω_max)]`` of the new state (zeros when
    it is not finite), ``qe_w`` (E) the error quaternion's scalar part (at most 1), ``terminated``
    (non-finite state or cost, ``max|ω|`` above the tumble limit, or roll or pitch beyond
    the stop, :func:`tilt_exceeded`) and ``truncated`` (the
    episode time reached, not terminated). Returns the number of envs that terminated or
    truncated, or −1, changing nothing, when ``cmd`` holds a NaN or an infinity.
    ``W``: :func:`work_size` floats.
    """
    n = int(n_wheels)
    B = int(lanes)
    include_h = bool(include_h)
    body_input = bool(body_input)
    diagonal_q = bool(diagonal_q)
    offset = bool(offset)
    lay = _Rows(n, B, include_h, body_input)
    n_state = lay.n_state
    AX, CQ, CR, SC, SIZE = lay.ax, lay.cq, lay.cr, lay.sc, lay.size
    AUG, K, ACC, TMP, U, CMD, APP = lay.aug, lay.k, lay.acc, lay.tmp, lay.u, lay.cmd, lay.app
    MAT, TGT, X, UC, UJ, RU, EXT = lay.mat, lay.target, lay.x, lay.uc, lay.uj, lay.ru, lay.ext
    QEW, FIN, RATE, TILT = lay.qe_w, lay.finite, lay.rate, lay.tilt

    @njit(cache=True, error_model="numpy")
    def kernel(
        Y,
        cmd,
        scale,
        ext,
        M,
        T,
        C,
        n_sub,
        steps,
        time_s,
        applied,
        cost,
        reward,
        obs,
        qe_w,
        terminated,
        truncated,
        observe_wheels,
        W,
    ):
        E = cmd.shape[0]
        zero = 0.0  # 0·x is 0 for every finite x, NaN otherwise
        for g in range(E):
            for i in range(n):
                zero += 0.0 * cmd[g, i]
        if zero != 0.0:
            return -1
        h = C[SC + S_H]
        max_torque = C[SC + S_MAX_TORQUE]
        max_rate, dt, duration = C[SC + S_MAX_RATE], C[SC + S_DT], C[SC + S_DURATION]
        max_speed = C[SC + S_MAX_SPEED]
        tilt_sin, tilt_cos = C[SC + S_TILT_SIN], C[SC + S_TILT_COS]
        has_ext = ext.shape[1] > 0
        n_done = 0
        for b in range(Y.shape[0]):
            e0 = b * B
            count = min(B, E - e0)
            # load the block: contiguous rows, no gathers
            for r in range(SIZE - 1):
                for e in range(B):
                    W[(AUG + r) * B + e] = Y[b, r, e]
            for r in range(MAT_ROWS):
                for e in range(B):
                    W[(MAT + r) * B + e] = M[b, r, e]
            for r in range(4):
                for e in range(B):
                    W[(TGT + r) * B + e] = T[b, r, e]
            for e in range(B):
                W[(AUG + SIZE - 1) * B + e] = 0.0
                for c in range(3):
                    W[(EXT + c) * B + e] = 0.0
            for i in range(n):
                for e in range(B):
                    W[(APP + i) * B + e] = 0.0
                    W[(CMD + i) * B + e] = 0.0  # padding lanes: no torque
                for e in range(count):
                    a = cmd[e0 + e, i]
                    W[(CMD + i) * B + e] = _clip(a, -1.0, 1.0) * max_torque if scale else a
            for j in range(n_sub):
                for e in range(B):
                    for i in range(n):
                        v = _speed_limit_lane(W, C, e, B, i, CMD, AUG + 7, SC)
                        W[(U + i) * B + e] = v
                        W[(APP + i) * B + e] += v / n_sub
                    W[RU * B + e] = _input_terms_lane(W, C, e, B, n, body_input, U, UJ, UC, AX, CR, SC)
                for stage in range(4):  # classical RK4: stages at t, t + h/2, t + h/2, t + h
                    if has_ext:
                        row = 9 * j + 3 * ((stage + 1) // 2)
                        for c in range(3):
                            for e in range(B):
                                W[(EXT + c) * B + e] = ext[b, row + c, e]
                    if stage == 0:
                        for r in range(SIZE):
                            for e in range(B):
                                W[(TMP + r) * B + e] = W[(AUG + r) * B + e]
                    else:
                        step = h if stage == 3 else 0.5 * h
                        for r in range(SIZE):
                            for e in range(B):
                                W[(TMP + r) * B + e] = W[(AUG + r) * B + e] + step * W[(K + r) * B + e]
                    for e in range(B):  # SIMD loops: one env per lane
                        _derivative_lane(W, C, e, B, n, offset, TMP, U, UJ, EXT, MAT, K, AX, SC)
                    for e in range(B):  # the stage cost xᵀQx + u_cᵀRu_c
                        state_cost = _state_cost_lane(W, C, e, B, n, include_h, diagonal_q, TMP, TGT, X, CQ, SC, True)
                        W[(K + SIZE - 1) * B + e] = state_cost + W[RU * B + e]
                    # acc = k1 + 2 k2 + 2 k3 + k4, summed in that order
                    if stage == 0:
                        for r in range(SIZE):
                            for e in range(B):
                                W[(ACC + r) * B + e] = W[(K + r) * B + e]
                    else:
                        weight = 1.0 if stage == 3 else 2.0
                        for r in range(SIZE):
                            for e in range(B):
                                W[(ACC + r) * B + e] += weight * W[(K + r) * B + e]
                for r in range(SIZE):
                    for e in range(B):
                        W[(AUG + r) * B + e] += (h / 6.0) * W[(ACC + r) * B + e]
                for e in range(B):
                    qx, qy = W[AUG * B + e], W[(AUG + 1) * B + e]
                    qz, qw = W[(AUG + 2) * B + e], W[(AUG + 3) * B + e]
                    norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
                    for r in range(4):
                        W[(AUG + r) * B + e] /= norm
            for r in range(SIZE - 1):
                for e in range(B):
                    Y[b, r, e] = W[(AUG + r) * B + e]
            # outputs: error state, finiteness (Σ y·0 is 0 or NaN) and tumble rate per lane
            for e in range(B):
                W[QEW * B + e] = _error_state_lane(W, C, e, B, n, include_h, AUG, TGT, X, SC, True)
                zero = 0.0
                for r in range(SIZE):
                    zero += 0.0 * W[(AUG + r) * B + e]
                W[FIN * B + e] = zero
                w0, w1, w2 = abs(W[(AUG + 4) * B + e]), abs(W[(AUG + 5) * B + e]), abs(W[(AUG + 6) * B + e])
                w0 = w1 if w1 > w0 else w0
                W[RATE * B + e] = w2 if w2 > w0 else w0
                qx, qy = W[AUG * B + e], W[(AUG + 1) * B + e]
                qz, qw = W[(AUG + 2) * B + e], W[(AUG + 3) * B + e]
                W[TILT * B + e] = 1.0 if _tilt_lane(qx, qy, qz, qw, tilt_sin, tilt_cos) else 0.0
            for e in range(count):  # scalars per env (SIMD: no branches)
                g = e0 + e
                c = W[(AUG + SIZE - 1) * B + e]
                cost[g] = c
                reward[g] = -c
                w = W[QEW * B + e]
                qe_w[g] = w if w < 1.0 else 1.0
                k = steps[g] + 1
                steps[g] = k
                time_s[g] = k * dt
                term = (W[FIN * B + e] != 0.0) | (W[RATE * B + e] > max_rate) | (W[TILT * B + e] != 0.0)
                trunc = (not term) & (k * dt >= duration - 1e-9 * dt)
                terminated[g] = term
                truncated[g] = trunc
                n_done += term + trunc
            for e in range(count):  # rows of the (E, N) and (E, n_obs) outputs
                g = e0 + e
                finite = W[FIN * B + e] == 0.0
                for i in range(n):
                    applied[g, i] = W[(APP + i) * B + e]
                for r in range(n_state):
                    obs[g, r] = np.float32(W[(X + r) * B + e]) if finite else np.float32(0.0)
                if observe_wheels:
                    for i in range(n):
                        v = W[(AUG + 7 + i) * B + e] / max_speed
                        obs[g, n_state + i] = np.float32(v) if finite else np.float32(0.0)
        return n_done

    return kernel


def blocks(n_envs: int, rows: int, lanes: int) -> np.ndarray:
    """Zeros in the blocked struct-of-arrays layout of :func:`step_kernel`'s per-env
    inputs: (⌈n_envs / lanes⌉, rows, lanes); env ``g`` is ``[g // lanes, :, g % lanes]``."""
    return np.zeros((-(-int(n_envs) // lanes), rows, lanes))


@njit(cache=True, error_model="numpy")
def derivative_columns(Y, U, EXT, M, constants, out):
    """ẏ of every column of ``Y`` (7+N, E) with motor torques ``U`` (N, E), external
    torques ``EXT`` (3, E), matrices ``M`` (18, E) and :func:`pack_constants` ``constants``
    (the generic, unspecialized path the tests and :func:`gyrostat.derivative` use)."""
    n = Y.shape[0] - 7
    y, u, uj = 0, 7 + n, 7 + 2 * n  # one lane (B = 1): row r is W[r]
    ext = uj + n
    mat, o = ext + 3, ext + 3 + MAT_ROWS
    W = np.empty(o + 7 + n)
    sc = constants.shape[0] - N_SCALARS
    for e in range(Y.shape[1]):
        W[y : y + 7 + n] = Y[:, e]
        W[u : u + n] = U[:, e]
        W[uj : uj + n] = U[:, e] / constants[sc + S_JS]
        W[ext : ext + 3] = EXT[:, e]
        W[mat : mat + MAT_ROWS] = M[:, e]
        _derivative_lane(W, constants, 0, 1, n, True, y, u, uj, ext, mat, o, 0, sc)
        out[:, e] = W[o : o + 7 + n]


@njit(cache=True, error_model="numpy")
def error_state_columns(Y, T, j_s, include_h, out, qe_w_out):
    """The error state of every column of ``Y`` (7+N, E) against targets ``T`` (4, E):
    ``out`` (n_state, E) ``[q_e,vec, ω, (J_s Ω)]``, ``qe_w_out`` (E) ``q_e,w``."""
    n = Y.shape[0] - 7
    n_state = out.shape[0]
    C = np.full(1, j_s)  # J_s at offset 0 (= S_JS)
    W = np.empty(11 + n + n_state)
    for e in range(Y.shape[1]):
        W[: 7 + n] = Y[:, e]
        W[7 + n : 11 + n] = T[:, e]
        qe_w_out[e] = _error_state_lane(W, C, 0, 1, n, include_h, 0, 7 + n, 11 + n, 0, True)
        out[:, e] = W[11 + n : 11 + n + n_state]
