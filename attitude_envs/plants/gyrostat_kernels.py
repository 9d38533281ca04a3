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

#: Block width of the batched step (envs per SIMD block). 64 lanes keep one block's
#: scratch rows (~10 kB for 4 wheels) in the L1 cache.
BATCH_LANES = 64

#: Packed per-env matrices: rows 0–8 the inertia ``I`` (row-major), 9–17 ``I_eff⁻¹``.
MAT_ROWS = 18

# Scalar constants of the step, in the order of :func:`pack_constants`.
_JS, _MAX_TORQUE, _MAX_SPEED, _H, _PX, _PY, _PZ, _MAX_RATE, _DT, _DURATION, _TILT_SIN, _TILT_COS = range(12)
N_SCALARS = 12


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
# Each function computes one env (lane ``e``) of a block: row ``r`` of the scratch buffer
# ``W`` is ``W[r * B + e]``, the shared constants are ``C`` (:func:`pack_constants`).
# Inlined into the step's loops over ``e`` (numba IR inlining), so those loops vectorize.


@njit(inline="always", error_model="numpy")
def _derivative_lane(W, C, e, B, n, offset, y, u, uj, ext, mat, out, ax, sc):
    """Rows ``out[0:7+n]`` = ẏ of the state rows ``y`` (q, ω, Ω), motor torque rows ``u``
    (N·m) and ``uj`` (``u_i / J_s``, see :func:`_input_terms_lane`), external torque rows
    ``ext`` (3, N·m, body), matrix rows ``mat``; ``ax`` and ``sc`` are the offsets of the
    wheel axes and of the scalars (:func:`pack_constants`).

    ``I_eff ω̇ = −ω × (Iω + J_s A Ω) − A u + T_ext + p × K`` with ``K = R(q)ᵀ e_Z`` the unit
    gravity direction in body axes (air-bearing offset torque, Ahangarani Farahani et al.,
    eqs. 6–9; left out unless ``offset``: ``p = 0`` for a free body),
    ``Ω̇_i = u_i / J_s − a_i·ω̇``,
    ``q̇ = ½ q ⊗ [ω, 0]``.
    """
    j_s = C[sc + _JS]
    qx = W[y * B + e]
    qy = W[(y + 1) * B + e]
    qz = W[(y + 2) * B + e]
    qw = W[(y + 3) * B + e]
    w0 = W[(y + 4) * B + e]
    w1 = W[(y + 5) * B + e]
    w2 = W[(y + 6) * B + e]
    h0 = W[mat * B + e] * w0 + W[(mat + 1) * B + e] * w1 + W[(mat + 2) * B + e] * w2
    h1 = W[(mat + 3) * B + e] * w0 + W[(mat + 4) * B + e] * w1 + W[(mat + 5) * B + e] * w2
    h2 = W[(mat + 6) * B + e] * w0 + W[(mat + 7) * B + e] * w1 + W[(mat + 8) * B + e] * w2
    r0 = W[ext * B + e]
    r1 = W[(ext + 1) * B + e]
    r2 = W[(ext + 2) * B + e]
    if offset:
        k0 = 2.0 * (qx * qz - qy * qw)
        k1 = 2.0 * (qy * qz + qx * qw)
        k2 = 1.0 - 2.0 * (qx * qx + qy * qy)
        p0, p1, p2 = C[sc + _PX], C[sc + _PY], C[sc + _PZ]
        r0 += p1 * k2 - p2 * k1
        r1 += p2 * k0 - p0 * k2
        r2 += p0 * k1 - p1 * k0
    for i in range(n):
        a0, a1, a2 = C[ax + i], C[ax + n + i], C[ax + 2 * n + i]
        hw = j_s * W[(y + 7 + i) * B + e]
        h0 += a0 * hw
        h1 += a1 * hw
        h2 += a2 * hw
        ui = W[(u + i) * B + e]
        r0 -= a0 * ui
        r1 -= a1 * ui
        r2 -= a2 * ui
    r0 -= w1 * h2 - w2 * h1
    r1 -= w2 * h0 - w0 * h2
    r2 -= w0 * h1 - w1 * h0
    m = mat + 9
    d0 = W[m * B + e] * r0 + W[(m + 1) * B + e] * r1 + W[(m + 2) * B + e] * r2
    d1 = W[(m + 3) * B + e] * r0 + W[(m + 4) * B + e] * r1 + W[(m + 5) * B + e] * r2
    d2 = W[(m + 6) * B + e] * r0 + W[(m + 7) * B + e] * r1 + W[(m + 8) * B + e] * r2
    W[out * B + e] = 0.5 * (qw * w0 + qy * w2 - qz * w1)
    W[(out + 1) * B + e] = 0.5 * (qw * w1 + qz * w0 - qx * w2)
    W[(out + 2) * B + e] = 0.5 * (qw * w2 + qx * w1 - qy * w0)
    W[(out + 3) * B + e] = -0.5 * (qx * w0 + qy * w1 + qz * w2)
    W[(out + 4) * B + e] = d0
    W[(out + 5) * B + e] = d1
    W[(out + 6) * B + e] = d2
    for i in range(n):
        a0, a1, a2 = C[ax + i], C[ax + n + i], C[ax + 2 * n + i]
        W[(out + 7 + i) * B + e] = W[(uj + i) * B + e] - (a0 * d0 + a1 * d1 + a2 * d2)


@njit(inline="always", error_model="numpy")
def _error_state_lane(W, C, e, B, n, include_h, y, target, x, sc):
    """Rows ``x`` = ``[q_e,vec, ω, (J_s Ω)]`` with ``q_e = q_T* ⊗ q/|q|`` (``q_e,w ≥ 0``) of
    the state rows ``y`` and target rows ``target``; returns ``q_e,w``."""
    qx = W[y * B + e]
    qy = W[(y + 1) * B + e]
    qz = W[(y + 2) * B + e]
    qw = W[(y + 3) * B + e]
    norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
    px = -W[target * B + e]
    py = -W[(target + 1) * B + e]
    pz = -W[(target + 2) * B + e]
    pw = W[(target + 3) * B + e]
    ex = pw * qx + px * qw + py * qz - pz * qy
    ey = pw * qy - px * qz + py * qw + pz * qx
    ez = pw * qz + px * qy - py * qx + pz * qw
    ew = pw * qw - px * qx - py * qy - pz * qz
    if ew < 0.0:
        ex, ey, ez, ew = -ex, -ey, -ez, -ew
    W[x * B + e] = ex
    W[(x + 1) * B + e] = ey
    W[(x + 2) * B + e] = ez
    W[(x + 3) * B + e] = W[(y + 4) * B + e]
    W[(x + 4) * B + e] = W[(y + 5) * B + e]
    W[(x + 5) * B + e] = W[(y + 6) * B + e]
    if include_h:
        j_s = C[sc + _JS]
        for i in range(n):
            W[(x + 6 + i) * B + e] = j_s * W[(y + 7 + i) * B + e]
    return ew


@njit(inline="always", error_model="numpy")
def _quad_form_lane(W, C, e, B, mat, v, k, diagonal):
    """``vᵀ M v`` of the ``k`` rows ``v``, ``M`` row-major at offset ``mat`` (row-by-row
    summation, the order of :func:`attitude_envs.plants.ops.define_quad_form`). With
    ``diagonal`` (``M`` is) the zero terms are left out: for finite ``v`` the same value,
    bit for bit (each row's sum is ``0 + M_ii v_i`` either way)."""
    total = 0.0
    for i in range(k):
        if diagonal:
            acc = 0.0 + C[mat + i * k + i] * W[(v + i) * B + e]
        else:
            acc = 0.0
            for j in range(k):
                acc += C[mat + i * k + j] * W[(v + j) * B + e]
        total += W[(v + i) * B + e] * acc
    return total


@njit(inline="always", error_model="numpy")
def _state_cost_lane(W, C, e, B, n, include_h, diagonal_q, y, target, x, cq, sc):
    """``xᵀQx`` of the state rows ``y`` (``x``: scratch rows for the error state)."""
    _error_state_lane(W, C, e, B, n, include_h, y, target, x, sc)
    return _quad_form_lane(W, C, e, B, cq, x, 6 + n if include_h else 6, diagonal_q)


@njit(inline="always", error_model="numpy")
def _input_terms_lane(W, C, e, B, n, body_input, u, uj, uc, ax, cr, sc):
    """What the RK4 stages share while the motor torque rows ``u`` are held: rows ``uj`` =
    ``u_i / J_s``, and the returned input cost ``u_cᵀRu_c`` with ``u_c = −A u``
    (``body_input``) or ``u`` (``uc``: scratch rows)."""
    j_s = C[sc + _JS]
    for i in range(n):
        W[(uj + i) * B + e] = W[(u + i) * B + e] / j_s
    if body_input:
        for k in range(3):
            acc = 0.0
            for i in range(n):
                acc -= C[ax + k * n + i] * W[(u + i) * B + e]
            W[(uc + k) * B + e] = acc
        return _quad_form_lane(W, C, e, B, cr, uc, 3, False)
    return _quad_form_lane(W, C, e, B, cr, u, n, False)


@njit(inline="always", error_model="numpy")
def _tilt_lane(qx, qy, qz, qw, tilt_sin, tilt_cos):
    """Whether roll φ or pitch θ (3-2-1 Euler angles of ``q``) is beyond the stop ``L``:
    ``|θ| > L ⟺ |sin θ| > sin L`` and ``|φ| > L ⟺ cos φ < cos L`` (``L < π/2``), the
    angles of :func:`attitude_envs.euler.euler_321_rad` without the inverse trigonometry."""
    n2 = qx * qx + qy * qy + qz * qz + qw * qw
    s = 2.0 * (qw * qx + qy * qz)
    c = n2 - 2.0 * (qx * qx + qy * qy)
    sin_pitch = 2.0 * (qw * qy - qz * qx) / n2
    return (abs(sin_pitch) > tilt_sin) | (c < tilt_cos * np.sqrt(s * s + c * c))


@njit(cache=True, error_model="numpy")
def tilt_exceeded(q, constants):
    """:func:`_tilt_lane` of one quaternion ``q`` with the stop of :func:`pack_constants`'s
    ``constants`` (the single env's ``info``; the step uses the same test)."""
    sc = constants.shape[0] - N_SCALARS
    return _tilt_lane(q[0], q[1], q[2], q[3], constants[sc + _TILT_SIN], constants[sc + _TILT_COS])


@njit(inline="always", error_model="numpy")
def _clip(v, lo, hi):
    """``min(max(v, lo), hi)`` written as two selects (numba's ``min``/``max`` do not vectorize)."""
    v = lo if v < lo else v
    return hi if v > hi else v


@njit(inline="always", error_model="numpy")
def _speed_limit_lane(W, C, e, B, i, cmd, wheel, sc):
    """Motor torque (N·m) of wheel ``i`` after the torque limit and the motor driver's
    speed limit: over the next ``h`` seconds the torque may take the wheel up to
    ``±max_speed`` but not beyond (ignoring the small body-coupling term ``a_i·ω̇``), so a
    wheel at its limit gets no further torque outwards."""
    max_torque, max_speed, j_s, h = C[sc + _MAX_TORQUE], C[sc + _MAX_SPEED], C[sc + _JS], C[sc + _H]
    v = _clip(W[(cmd + i) * B + e], -max_torque, max_torque)
    wheel_speed = W[(wheel + i) * B + e]
    hi = j_s / h * (max_speed - wheel_speed)
    lo = j_s / h * (-max_speed - wheel_speed)
    limited = _clip(_clip(v, lo, hi), -max_torque, max_torque)
    return limited if max_speed < np.inf else v


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
        h = C[SC + _H]
        max_torque = C[SC + _MAX_TORQUE]
        max_rate, dt, duration = C[SC + _MAX_RATE], C[SC + _DT], C[SC + _DURATION]
        max_speed = C[SC + _MAX_SPEED]
        tilt_sin, tilt_cos = C[SC + _TILT_SIN], C[SC + _TILT_COS]
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
                        state_cost = _state_cost_lane(W, C, e, B, n, include_h, diagonal_q, TMP, TGT, X, CQ, SC)
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
                W[QEW * B + e] = _error_state_lane(W, C, e, B, n, include_h, AUG, TGT, X, SC)
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
        W[uj : uj + n] = U[:, e] / constants[sc + _JS]
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
    C = np.full(1, j_s)  # J_s at offset 0 (= _JS)
    W = np.empty(11 + n + n_state)
    for e in range(Y.shape[1]):
        W[: 7 + n] = Y[:, e]
        W[7 + n : 11 + n] = T[:, e]
        qe_w_out[e] = _error_state_lane(W, C, 0, 1, n, include_h, 0, 7 + n, 11 + n, 0)
        out[:, e] = W[11 + n : 11 + n + n_state]
