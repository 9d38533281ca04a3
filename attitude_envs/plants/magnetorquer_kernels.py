"""Compiled hot path of Magnetorquer-v0 (numba): the one implementation of the Kepler orbit,
the field models along it, the smooth bang-bang reference, the time-varying inertia, the
disturbances, the gyrostat equations with one y wheel and the RK4 control step with the
stage cost as an extra state. :class:`~attitude_envs.plants.orbit.KeplerOrbit`,
:class:`~attitude_envs.plants.magnetic_field.FieldModel` and
:class:`~attitude_envs.trajectories.SmoothBangBang` evaluate through these functions too.

Equations: :mod:`attitude_envs.plants.magnetorquer` (dynamics), :mod:`attitude_envs.plants.orbit`,
:mod:`attitude_envs.plants.magnetic_field`, :mod:`attitude_envs.trajectories`. Written for
the sizes they have (scalar code over 3-vectors, no temporaries beyond caller-owned work
buffers).

Arguments are packed into a few float64 vectors (few arguments keep numba's dispatch cheap);
the layouts are the ``*_`` index constants below and the ``pack_*`` helpers build them:

* ``orbit`` (:data:`ORBIT_SIZE`): elements of one orbit (:func:`pack_orbit`);
* ``ref`` (:data:`REF_SIZE`): the reference profile (:func:`pack_reference`);
* ``shared`` (:data:`SHARED_SIZE` + ``ref``): everything one env configuration fixes
  (:func:`pack_shared`);
* ``env`` (:data:`ENV_SIZE`): what each episode draws: true inertia, orbit, disturbance
  phase or held value (:func:`pack_env`);
* ``table`` (k × 3): the tabulated IGRF field in ECI at multiples of the table step (a
  dummy 2 × 3 array for the dipole models).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from attitude_envs.plants.magnetorquer_definition import define
from attitude_envs.plants.ops import NUMBA

# ---- orbit elements (pack_orbit)
ORB_MODEL, ORB_A, ORB_E, ORB_M0, ORB_N, ORB_P, ORB_H, ORB_MU = 0, 1, 2, 3, 4, 5, 6, 7
ORB_NODE, ORB_IN_PLANE, ORB_NORMAL, ORB_ARGP = 8, 11, 14, 17
ORBIT_SIZE = 18
# ---- orbit state (orbit_state_into): position, velocity (ECI, m, m/s), r, argument of
# latitude u, ν̇, ν̈, eci_from_orbital (3×3 row-major)
OS_POS, OS_VEL, OS_R, OS_U, OS_RATE, OS_RATE_DOT, OS_FRAME = 0, 3, 6, 7, 8, 9, 10
ORBIT_STATE_SIZE = 19
# ---- reference profile (pack_reference): constant flag, t_f, θ0 (3), K (3), final ∫f and
# ∫∫f, 3 pieces × [start, end, f (6), ∫f (6), ∫∫f (6)] (Horner order, zero padded), then the
# held values [q_d, ω_d, q̇_d] before 0 and after t_f (evaluated once)
REF_CONST, REF_TF, REF_START, REF_GAIN, REF_FINAL_V, REF_FINAL_P, REF_PIECES = 0, 1, 2, 5, 8, 9, 10
REF_PIECE_SIZE, REF_COEFS = 20, 6
REF_HELD_START = REF_PIECES + 3 * REF_PIECE_SIZE
REF_HELD_END = REF_HELD_START + 11
REF_SIZE = REF_HELD_END + 11
# ---- shared configuration (pack_shared); the reference follows at SH_REF
SH_JW, SH_HMAX, SH_H, SH_NSUB = 0, 1, 2, 3
SH_FIELD, SH_STRENGTH, SH_INCL, SH_TABLE_STEP = 4, 5, 6, 7
SH_DIST, SH_DIST_SCALE, SH_DIST_RATE, SH_DIST_K, SH_DIST_AMP, SH_DIST_PERIOD = 8, 9, 10, 11, 12, 15
SH_GG, SH_DJ, SH_DJ_AMP, SH_DJ_FREQ, SH_DJ_PHASE = 16, 17, 18, 21, 24
SH_Q, SH_R, SH_DIAG, SH_REF = 27, 63, 72, 73  # SH_DIAG: 1.0 when Q and R are diagonal
SHARED_SIZE = SH_REF + REF_SIZE
FIELD_CODES = {"dipole": 0, "dipole-printed": 1, "igrf": 2}
DIST_NONE, DIST_PAPER, DIST_HELD, DIST_SINUSOIDAL = 0, 1, 2, 3
# ---- per-episode values (pack_env): true inertia (no ΔJ), its I_eff⁻¹, orbit, disturbance
# vector (held torque, or the sinusoid's phases)
EN_INERTIA, EN_EFF_INV, EN_ORBIT, EN_DIST = 0, 9, 18, 18 + ORBIT_SIZE
ENV_SIZE = EN_DIST + 3
# ---- time context (context_into): orbit state, field (orbital frame), q_d, ω_d, q̇_d, true
# inertia, I_eff⁻¹, disturbance (without gravity gradient)
CX_ORB, CX_B = 0, ORBIT_STATE_SIZE
CX_QD, CX_WD, CX_QDOT = CX_B + 3, CX_B + 7, CX_B + 10
CX_I, CX_EINV, CX_DIST = CX_B + 14, CX_B + 23, CX_B + 32
CONTEXT_SIZE = CX_DIST + 3
# ---- snapshot (snapshot_into): observation parts, then info quantities at one time
SN_X, SN_WHEEL, SN_BSCALED = 0, 6, 7  # error state, Ω/1000, b_body/5e-5: the observation
SN_BBODY, SN_WBI, SN_HW, SN_QD, SN_WD, SN_QDOT = 10, 13, 16, 17, 21, 24
SN_BORB, SN_R, SN_U, SN_RATE, SN_EXT, SN_I, SN_ANGLE = 28, 31, 32, 33, 34, 37, 46
SNAPSHOT_SIZE = 47
# ---- step outputs (control_step): applied (4), magnetic torque mean (3), control torque
# mean m × b + e_y T_w (3); then (advance) 1.0 if the state and cost are finite
ST_APPLIED, ST_TAU, ST_CONTROL, ST_FINITE = 0, 4, 7, 10
STEP_OUT_SIZE = 11
WHEEL_SPEED_SCALE_RAD_S = 1e3  # observation scale of the wheel speed
FIELD_SCALE_T = 5e-5  # observation scale of the body-frame field
AUG = 9  # [q (4), ω_bo (3), Ω, cost]
# work buffer: aug, stage input, 4 slopes, 3 contexts (sub-step start, middle, end) and the
# time of the end context (NaN: none; it is reused when the next sub-step or the snapshot
# falls on exactly that time; callers write NaN when the episode's draws change)
WK_AUG, WK_TMP, WK_K = 0, AUG, 2 * AUG
WK_C0 = 6 * AUG
WK_C1, WK_C2 = WK_C0 + CONTEXT_SIZE, WK_C0 + 2 * CONTEXT_SIZE
WK_TAG = WK_C0 + 3 * CONTEXT_SIZE
WORK_SIZE = WK_TAG + 1


_PLANT = define(NUMBA)
_body_vector = _PLANT.body_vector
error_state = _PLANT.error_state
_external_torque = _PLANT.external_torque
_augmented = _PLANT.augmented
_wheel_torque = _PLANT.wheel_torque
_limit_rows = _PLANT.limit_rows
_kepler_rates = _PLANT.kepler_rates
_dipole_eci = _PLANT.dipole_eci
_printed_field = _PLANT.printed_field
_euler_reference = _PLANT.euler_reference
_inverse3 = _PLANT.inverse3
_paper_disturbance = _PLANT.paper_disturbance


# ----------------------------------------------------------------------------- orbit
# Functions take (array, base) pairs rather than slices: a slice costs a reference-count
# round trip in compiled code, which the per-stage functions would pay many times a step.
@njit(cache=True, error_model="numpy")
def true_anomaly(orbit, ob, t_s):
    """ν(t) from Kepler's equation M = E − e sin E (Newton, |ΔE| < 1e-13), rad; the
    elements at ``orbit[ob:]``."""
    mean = orbit[ob + ORB_M0] + orbit[ob + ORB_N] * t_s
    e = orbit[ob + ORB_E]
    if e == 0.0:
        return mean
    ecc = mean + e * math.sin(mean)
    for _ in range(30):
        step = (ecc - e * math.sin(ecc) - mean) / (1.0 - e * math.cos(ecc))
        ecc -= step
        if abs(step) < 1e-13:
            break
    return 2.0 * math.atan2(math.sqrt(1 + e) * math.sin(ecc / 2), math.sqrt(1 - e) * math.cos(ecc / 2))


@njit(cache=True, error_model="numpy")
def orbit_state_into(orbit, ob, t_s, out, sb):
    """Position, velocity, radius, argument of latitude, ν̇, ν̈ and the LVLH frame at ``t_s``
    into ``out[sb:]`` (layout ``OS_*``); elements at ``orbit[ob:]``, model 1: the circular
    approximation."""
    if orbit[ob + ORB_MODEL] == 1.0:
        u = orbit[ob + ORB_ARGP] + orbit[ob + ORB_M0] + orbit[ob + ORB_N] * t_s
        r, r_dot = orbit[ob + ORB_A], 0.0
        nu_dot, nu_ddot = orbit[ob + ORB_N], 0.0
    else:
        nu = true_anomaly(orbit, ob, t_s)
        u = orbit[ob + ORB_ARGP] + nu
        r, nu_dot, r_dot, nu_ddot = _kepler_rates(
            nu, orbit[ob + ORB_E], orbit[ob + ORB_H], orbit[ob + ORB_P], orbit[ob + ORB_MU]
        )
    cu, su = math.cos(u), math.sin(u)
    for i in range(3):
        node, in_plane = orbit[ob + ORB_NODE + i], orbit[ob + ORB_IN_PLANE + i]
        r_hat = node * cu + in_plane * su
        t_hat = -node * su + in_plane * cu
        out[sb + OS_POS + i] = r * r_hat
        out[sb + OS_VEL + i] = r_dot * r_hat + r * nu_dot * t_hat
        # LVLH: x = t̂, y = −ĥ (anti-normal), z = −r̂ (nadir)
        out[sb + OS_FRAME + 3 * i] = t_hat
        out[sb + OS_FRAME + 3 * i + 1] = -orbit[ob + ORB_NORMAL + i]
        out[sb + OS_FRAME + 3 * i + 2] = -r_hat
    out[sb + OS_R] = r
    out[sb + OS_U] = u
    out[sb + OS_RATE] = nu_dot
    out[sb + OS_RATE_DOT] = nu_ddot


# ----------------------------------------------------------------------------- field
@njit(cache=True, error_model="numpy")
def dipole_eci_into(px, py, pz, strength_t_m3, out):
    """Axial dipole ``μ_e/r³ [3(m̂·r̂)r̂ − m̂]``, ``m̂ = −z``, at an ECI position (m), tesla."""
    out[0], out[1], out[2] = _dipole_eci(px, py, pz, strength_t_m3)


@njit(cache=True, error_model="numpy")
def field_orbital_into(t_s, orb, sb, model, strength_t_m3, inclination_rad, table, table_step_s, out, fb):
    """Field in the orbital (LVLH) frame at ``t_s`` (tesla) into ``out[fb:fb + 3]``, the orbit
    state at ``orb[sb:]``: ``model`` 0 dipole, 1 the as-printed eq. (9), 2 the IGRF table
    (ECI, linear interpolation between nodes)."""
    if model == 1:
        out[fb], out[fb + 1], out[fb + 2] = _printed_field(
            orb[sb + OS_R], orb[sb + OS_U], strength_t_m3, inclination_rad
        )
        return
    if model == 2:
        k = min(int(t_s / table_step_s), table.shape[0] - 2)
        w = (t_s - k * table_step_s) / table_step_s
        b0 = (1.0 - w) * table[k, 0] + w * table[k + 1, 0]
        b1 = (1.0 - w) * table[k, 1] + w * table[k + 1, 1]
        b2 = (1.0 - w) * table[k, 2] + w * table[k + 1, 2]
    else:
        b0, b1, b2 = _dipole_eci(orb[sb + OS_POS], orb[sb + OS_POS + 1], orb[sb + OS_POS + 2], strength_t_m3)
    f = sb + OS_FRAME
    for j in range(3):  # eci_from_orbitalᵀ b
        out[fb + j] = orb[f + j] * b0 + orb[f + 3 + j] * b1 + orb[f + 6 + j] * b2


# ----------------------------------------------------------------------------- reference
@njit(cache=True, error_model="numpy")
def _horner(ref, start, x):
    acc = 0.0
    for i in range(REF_COEFS):
        acc = acc * x + ref[start + i]
    return acc


@njit(cache=True, error_model="numpy")
def profile(ref, rb, t_s):
    """``(∫∫f, ∫f, f)`` of the smooth sign function at ``t_s`` (s², s, 1); profile at ``ref[rb:]``."""
    if t_s <= 0.0:
        return 0.0, 0.0, 0.0
    for k in range(3):
        base = rb + REF_PIECES + k * REF_PIECE_SIZE
        if t_s <= ref[base + 1]:
            return (
                _horner(ref, base + 2 + 2 * REF_COEFS, t_s),
                _horner(ref, base + 2 + REF_COEFS, t_s),
                _horner(ref, base + 2, t_s),
            )
    v0, p0 = ref[rb + REF_FINAL_V], ref[rb + REF_FINAL_P]
    return p0 + v0 * (t_s - ref[rb + REF_TF]), v0, 0.0


@njit(cache=True, error_model="numpy")
def reference_into(ref, rb, t_s, out, qb):
    """Desired quaternion (scalar last, w ≥ 0), body rate ω_d (rad/s) and q̇_d (1/s) at
    ``t_s``: ``out[qb:qb + 11] = [q_d (4), ω_d (3), q̇_d (4)]``; held at t ≤ 0 and t ≥ t_f."""
    if ref[rb + REF_CONST] != 0.0 or t_s <= 0.0:
        for i in range(11):
            out[qb + i] = ref[rb + REF_HELD_START + i]
        return
    if t_s >= ref[rb + REF_TF]:
        for i in range(11):
            out[qb + i] = ref[rb + REF_HELD_END + i]
        return
    _reference_at(ref, rb, t_s, out, qb)


@njit(cache=True, error_model="numpy")
def _reference_at(ref, rb, t_s, out, qb):
    """:func:`reference_into` evaluated from the profile (no held values)."""
    p, v, _ = profile(ref, rb, t_s)
    qx, qy, qz, qw, wx, wy, wz = _euler_reference(
        p,
        v,
        ref[rb + REF_START],
        ref[rb + REF_START + 1],
        ref[rb + REF_START + 2],
        ref[rb + REF_GAIN],
        ref[rb + REF_GAIN + 1],
        ref[rb + REF_GAIN + 2],
    )
    out[qb], out[qb + 1], out[qb + 2], out[qb + 3] = qx, qy, qz, qw
    out[qb + 4], out[qb + 5], out[qb + 6] = wx, wy, wz
    # q̇_d = ½ q_d ⊗ [ω_d, 0]
    out[qb + 7] = 0.5 * (qw * wx + qx * 0.0 + qy * wz - qz * wy)
    out[qb + 8] = 0.5 * (qw * wy - qx * wz + qy * 0.0 + qz * wx)
    out[qb + 9] = 0.5 * (qw * wz + qx * wy - qy * wx + qz * 0.0)
    out[qb + 10] = 0.5 * (qw * 0.0 - qx * wx - qy * wy - qz * wz)


# ----------------------------------------------------------------------------- plant
@njit(cache=True, error_model="numpy")
def paper_disturbance_into(t_s, orbital_rate_rad_s, scale, k, out, db):
    """Sadigh et al. 2022 eq. (39): ``d_j = d0 + d1 sin(ω0 t + φ_j1) + d2 sin(k ω0 t + φ_j2)``, N·m
    (d0 = 1e-7, d1 = d2 = 1e-5; φ_x = ±π/4, φ_y = ∓π/4, φ_z = (0, π/2)), times ``scale``,
    into ``out[db:db + 3]``."""
    a = orbital_rate_rad_s * t_s
    b = k * orbital_rate_rad_s * t_s
    q = math.pi / 4
    sa_p, sa_m = math.sin(a + q), math.sin(a - q)
    sb_m, sb_p = (sa_m, sa_p) if b == a else (math.sin(b - q), math.sin(b + q))  # k = 1: same arguments
    out[db], out[db + 1], out[db + 2] = _paper_disturbance(
        scale, sa_p, sa_m, sb_m, sb_p, math.sin(a), math.sin(b + 2 * q)
    )


@njit(cache=True, error_model="numpy")
def inverse3_into(m, base, out, out_base):
    """``out[out_base:+9] = inv(m[base:+9])`` for a 3×3 row-major matrix (adjugate / det);
    reads every entry before writing, so it may work in place."""
    inv = _inverse3(m, base)
    for i in range(9):
        out[out_base + i] = inv[i]


@njit(cache=True, error_model="numpy")
def context_into(t_s, shared, env, table, ctx, cb):
    """Everything that depends on time only into ``ctx[cb:]`` (layout ``CX_*``): orbit, field,
    reference, true inertia ``I + ΔJ(t)`` (Sadigh et al. 2022 eq. 35) and its ``(I − J_w e_y e_yᵀ)⁻¹``,
    disturbance."""
    orbit_state_into(env, EN_ORBIT, t_s, ctx, cb + CX_ORB)
    field_orbital_into(
        t_s,
        ctx,
        cb + CX_ORB,
        int(shared[SH_FIELD]),
        shared[SH_STRENGTH],
        shared[SH_INCL],
        table,
        shared[SH_TABLE_STEP],
        ctx,
        cb + CX_B,
    )
    reference_into(shared, SH_REF, t_s, ctx, cb + CX_QD)
    for i in range(9):
        ctx[cb + CX_I + i] = env[EN_INERTIA + i]
    if shared[SH_DJ] != 0.0:
        for j in range(3):
            amp = shared[SH_DJ_AMP + j]
            ctx[cb + CX_I + 4 * j] = env[EN_INERTIA + 4 * j] + amp * math.sin(
                shared[SH_DJ_FREQ + j] * t_s + shared[SH_DJ_PHASE + j]
            )
        for i in range(9):
            ctx[cb + CX_EINV + i] = ctx[cb + CX_I + i]
        ctx[cb + CX_EINV + 4] -= shared[SH_JW]
        inverse3_into(ctx, cb + CX_EINV, ctx, cb + CX_EINV)
    else:
        for i in range(9):
            ctx[cb + CX_EINV + i] = env[EN_EFF_INV + i]
    disturbance_into(t_s, shared, env, ctx, cb)


@njit(cache=True, error_model="numpy")
def disturbance_into(t_s, shared, env, ctx, cb):
    """The disturbance torque at ``t_s`` (N·m, body axes, without gravity gradient) into
    ``ctx[cb:]``: Sadigh et al. 2022 eq. (39), a torque held over the control step (constant, random
    walk: ``env[EN_DIST:]``) or a sinusoid with the phases ``env[EN_DIST:]``; times the scale."""
    kind = shared[SH_DIST]
    scale = shared[SH_DIST_SCALE]
    d = cb + CX_DIST
    if kind == DIST_PAPER:
        paper_disturbance_into(t_s, shared[SH_DIST_RATE], scale, shared[SH_DIST_K], ctx, d)
    elif kind == DIST_HELD:
        for j in range(3):
            ctx[d + j] = scale * env[EN_DIST + j]
    elif kind == DIST_SINUSOIDAL:
        arg = 2 * math.pi * t_s / shared[SH_DIST_PERIOD]
        for j in range(3):
            ctx[d + j] = scale * (shared[SH_DIST_AMP + j] * math.sin(arg + env[EN_DIST + j]))
    else:
        for j in range(3):
            ctx[d + j] = 0.0


@njit(cache=True, error_model="numpy")
def tumbling(state, max_rate_rad_s):
    """Whether the state ``[q, ω_bo, Ω]`` (8) is past the tumbling limit (a limit row of the
    definition > 0; rad/s)."""
    crossed = False
    for g in _limit_rows(state[4], state[5], state[6], max_rate_rad_s):
        crossed = crossed or g > 0.0
    return crossed


@njit(cache=True, error_model="numpy")
def tumbling_rows(states, max_rate_rad_s, out):
    """``out[e]`` = :func:`tumbling` of state row ``e`` (E × 8)."""
    for e in range(states.shape[0]):
        out[e] = tumbling(states[e], max_rate_rad_s)


#: where the definition's context entries sit in this module's time context (``CX_*``)
CONTEXT_LAYOUT = (CX_ORB + OS_RATE, CX_ORB + OS_RATE_DOT, CX_ORB + OS_R, CX_B, CX_QD, CX_WD, CX_I, CX_EINV, CX_DIST)


@njit(cache=True, error_model="numpy")
def cost_weights(shared):
    """``(Q (6×6), R (3×3), diagonal)``: the stage cost's weights of ``shared`` (views) and
    whether both are diagonal."""
    return (
        shared[SH_Q : SH_Q + 36].reshape((6, 6)),
        shared[SH_R : SH_R + 9].reshape((3, 3)),
        shared[SH_DIAG] != 0.0,
    )


@njit(cache=True, error_model="numpy")
def augmented_derivative(buf, ib, m, t_w, shared, Q, R, diagonal, cb, ob):
    """``buf[ob:ob + 9] = d/dt [q, ω_bo, Ω, cost]`` at ``buf[ib:ib + 9]`` with the time context
    ``buf[cb:]``: the definition's augmented derivative (dipoles ``m`` A·m², wheel torque
    ``t_w`` N·m on the body about +y; the cost weights of :func:`cost_weights`)."""
    dz = _augmented(buf, ib, m, t_w, buf, cb, CONTEXT_LAYOUT, shared[SH_JW], shared[SH_GG] != 0.0, Q, R, diagonal, True)
    for i in range(AUG):
        buf[ob + i] = dz[i]


@njit(cache=True, error_model="numpy")
def control_step(state, cmd, t0_s, t1_s, shared, env, table, step_out, work):
    """Advance ``state = [q, ω_bo, Ω]`` (in place) from ``t0_s`` to ``t1_s`` over ``n_sub`` RK4
    sub-steps of ``h`` with the delivered command ``cmd = [m (3, A·m²), T_w (N·m)]`` held;
    returns the step cost ``∫ (xᵀQx + uᵀRu) dt``. Sub-step ``j`` starts at ``t0 + j h``; the
    last one's end stage is evaluated at ``t1_s`` (the caller's step end, equal to ``t0 + n h``
    up to rounding), so that its time context serves the snapshot and the next step. Per sub-step the wheel torque is zeroed when it would grow
    ``|h_w| ≥ h_max`` (the storable momentum of the paper's Table 1); the quaternion is renormalized after each.
    ``step_out``: mean applied command (4), mean magnetic torque ``m × b`` and mean control
    torque (3 each, N·m, body axes, at the sub-step starts). ``work``: :data:`WORK_SIZE` floats."""
    n_sub = int(shared[SH_NSUB])
    h = shared[SH_H]
    for i in range(AUG - 1):
        work[WK_AUG + i] = state[i]
    work[WK_AUG + AUG - 1] = 0.0
    j_w, h_max = shared[SH_JW], shared[SH_HMAX]
    Q, R, diagonal = cost_weights(shared)
    wheel_sum, tau0, tau1, tau2 = 0.0, 0.0, 0.0, 0.0
    for j in range(n_sub):
        ts = t0_s + j * h
        te = t1_s if j == n_sub - 1 else t0_s + (j + 1) * h
        if work[WK_TAG] == ts:  # the previous end context: time-only parts are the same
            for i in range(CONTEXT_SIZE):
                work[WK_C0 + i] = work[WK_C2 + i]
            disturbance_into(ts, shared, env, work, WK_C0)  # a held torque may have changed since
        else:
            context_into(ts, shared, env, table, work, WK_C0)
        context_into(ts + 0.5 * h, shared, env, table, work, WK_C1)
        context_into(te, shared, env, table, work, WK_C2)
        work[WK_TAG] = te
        x, y, z, w = work[WK_AUG], work[WK_AUG + 1], work[WK_AUG + 2], work[WK_AUG + 3]
        t_w = _wheel_torque(
            cmd[3], x, z, work[WK_AUG + 5], work[WK_AUG + 7], work[WK_C0 + CX_ORB + OS_RATE], j_w, h_max
        )
        wheel_sum += t_w
        b = WK_C0 + CX_B
        b0, b1, b2 = _body_vector(x, y, z, w, work[b], work[b + 1], work[b + 2])
        tau0 += cmd[1] * b2 - cmd[2] * b1
        tau1 += cmd[2] * b0 - cmd[0] * b2
        tau2 += cmd[0] * b1 - cmd[1] * b0
        for stage in range(4):  # classical RK4: stages at t, t + h/2, t + h/2, t + h
            if stage == 0:
                for i in range(AUG):
                    work[WK_TMP + i] = work[WK_AUG + i]
            else:
                c = h if stage == 3 else 0.5 * h
                k = WK_K + (stage - 1) * AUG
                for i in range(AUG):
                    work[WK_TMP + i] = work[WK_AUG + i] + c * work[k + i]
            cb = WK_C0 if stage == 0 else (WK_C2 if stage == 3 else WK_C1)  # t, t + h/2, t + h/2, end
            augmented_derivative(work, WK_TMP, cmd, t_w, shared, Q, R, diagonal, cb, WK_K + stage * AUG)
        for i in range(AUG):
            k1, k2 = work[WK_K + i], work[WK_K + AUG + i]
            k3, k4 = work[WK_K + 2 * AUG + i], work[WK_K + 3 * AUG + i]
            work[WK_AUG + i] = work[WK_AUG + i] + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        a = WK_AUG
        norm = math.sqrt(
            work[a] * work[a] + work[a + 1] * work[a + 1] + work[a + 2] * work[a + 2] + work[a + 3] * work[a + 3]
        )
        for i in range(4):
            work[a + i] /= norm
    for i in range(AUG - 1):
        state[i] = work[WK_AUG + i]
    step_out[ST_APPLIED] = cmd[0]
    step_out[ST_APPLIED + 1] = cmd[1]
    step_out[ST_APPLIED + 2] = cmd[2]
    step_out[ST_APPLIED + 3] = wheel_sum / n_sub
    step_out[ST_TAU] = tau0 / n_sub
    step_out[ST_TAU + 1] = tau1 / n_sub
    step_out[ST_TAU + 2] = tau2 / n_sub
    step_out[ST_CONTROL] = step_out[ST_TAU]
    step_out[ST_CONTROL + 1] = step_out[ST_TAU + 1] + step_out[ST_APPLIED + 3]
    step_out[ST_CONTROL + 2] = step_out[ST_TAU + 2]
    return work[WK_AUG + AUG - 1]


@njit(cache=True, error_model="numpy")
def snapshot_into(state, t_s, shared, env, table, ctx, out):
    """Observation parts and ``info`` quantities of ``state`` at ``t_s`` (layout ``SN_*``):
    error state, scaled wheel speed and field; body and orbital field (T), inertial rate
    (rad/s), wheel momentum (N·m·s), reference, orbit radius / argument of latitude / rate,
    external torque (disturbance + gravity gradient, N·m), true inertia, error angle (deg).
    ``ctx``: a :data:`CONTEXT_SIZE` scratch buffer."""
    context_into(t_s, shared, env, table, ctx, 0)
    snapshot_from_context(state, shared, ctx, 0, out)


@njit(cache=True, error_model="numpy")
def snapshot_from_context(state, shared, ctx, cb, out):
    """:func:`snapshot_into` with the time context of the snapshot's time at ``ctx[cb:]``."""
    x, y, z, w = state[0], state[1], state[2], state[3]
    ex, ey, ez, we0, we1, we2, ew = error_state(x, y, z, w, state[4], state[5], state[6], ctx, cb + CX_QD, True)
    out[SN_X], out[SN_X + 1], out[SN_X + 2] = ex, ey, ez
    out[SN_X + 3], out[SN_X + 4], out[SN_X + 5] = we0, we1, we2
    out[SN_WHEEL] = state[7] / WHEEL_SPEED_SCALE_RAD_S
    b0, b1, b2 = _body_vector(x, y, z, w, ctx[cb + CX_B], ctx[cb + CX_B + 1], ctx[cb + CX_B + 2])
    out[SN_BBODY], out[SN_BBODY + 1], out[SN_BBODY + 2] = b0, b1, b2
    out[SN_BSCALED] = b0 / FIELD_SCALE_T
    out[SN_BSCALED + 1] = b1 / FIELD_SCALE_T
    out[SN_BSCALED + 2] = b2 / FIELD_SCALE_T
    nd = ctx[cb + CX_ORB + OS_RATE]
    r0, r1, r2 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[SN_WBI] = state[4] + r0 * (-nd)
    out[SN_WBI + 1] = state[5] + r1 * (-nd)
    out[SN_WBI + 2] = state[6] + r2 * (-nd)
    out[SN_HW] = shared[SH_JW] * (state[7] + out[SN_WBI + 1])
    for i in range(11):
        out[SN_QD + i] = ctx[cb + CX_QD + i]
    for i in range(3):
        out[SN_BORB + i] = ctx[cb + CX_B + i]
    out[SN_R] = ctx[cb + CX_ORB + OS_R]
    out[SN_U] = ctx[cb + CX_ORB + OS_U]
    out[SN_RATE] = nd
    e0, e1, e2 = _external_torque(x, y, z, w, ctx, cb, CONTEXT_LAYOUT, shared[SH_GG] != 0.0)
    out[SN_EXT], out[SN_EXT + 1], out[SN_EXT + 2] = e0, e1, e2
    for i in range(9):
        out[SN_I + i] = ctx[cb + CX_I + i]
    out[SN_ANGLE] = math.degrees(2.0 * math.acos(min(1.0, abs(ew))))


@njit(cache=True, error_model="numpy")
def advance(state, cmd, t0_s, t1_s, shared, env, table, step_out, snap, work):
    """:func:`control_step` from ``t0_s``, then :func:`snapshot_into` at ``t1_s`` (the end of
    the control step, computed by the caller from the step count), then ``step_out``'s
    finiteness flag; returns the step cost."""
    cost = control_step(state, cmd, t0_s, t1_s, shared, env, table, step_out, work)
    if work[WK_TAG] != t1_s:
        context_into(t1_s, shared, env, table, work, WK_C2)
        work[WK_TAG] = t1_s
    snapshot_from_context(state, shared, work, WK_C2, snap)
    finite = math.isfinite(cost)
    for i in range(AUG - 1):
        finite = finite and math.isfinite(state[i])
    step_out[ST_FINITE] = 1.0 if finite else 0.0
    return cost


@njit(cache=True, error_model="numpy")
def advance_batch(states, cmds, t0s, t1s, shared, envs, tables, step_out, snaps, costs, work):
    """:func:`advance` for every row, serially (numba's threads lose to oversubscription on
    small machines); per-env ``envs`` (E, ENV_SIZE) and ``tables`` (E, k, 3), one shared
    configuration, ``work`` (E, WORK_SIZE)."""
    for e in range(states.shape[0]):
        costs[e] = advance(
            states[e], cmds[e], t0s[e], t1s[e], shared, envs[e], tables[e], step_out[e], snaps[e], work[e]
        )


# ----------------------------------------------------------------------------- packing
def pack_orbit(
    model_circular: bool,
    a: float,
    e: float,
    mean_anomaly0_rad: float,
    mean_motion_rad_s: float,
    p: float,
    h: float,
    mu: float,
    node,
    in_plane,
    normal,
    arg_perigee_rad: float,
) -> np.ndarray:
    """The ``orbit`` vector (layout ``ORB_*``)."""
    out = np.zeros(ORBIT_SIZE)
    out[ORB_MODEL] = 1.0 if model_circular else 0.0
    out[ORB_A], out[ORB_E], out[ORB_M0], out[ORB_N] = a, e, mean_anomaly0_rad, mean_motion_rad_s
    out[ORB_P], out[ORB_H], out[ORB_MU] = p, h, mu
    out[ORB_NODE : ORB_NODE + 3] = node
    out[ORB_IN_PLANE : ORB_IN_PLANE + 3] = in_plane
    out[ORB_NORMAL : ORB_NORMAL + 3] = normal
    out[ORB_ARGP] = arg_perigee_rad
    return out


def pack_reference(constant: bool, t_final_s: float, start_rad, gain, final, pieces) -> np.ndarray:
    """The ``ref`` vector (layout ``REF_*``); ``pieces``: 3 × (start, end, f, ∫f, ∫∫f) with
    coefficient lists in Horner order (highest power first)."""
    out = np.zeros(REF_SIZE)
    out[REF_CONST] = 1.0 if constant else 0.0
    out[REF_TF] = t_final_s
    out[REF_START : REF_START + 3] = start_rad
    out[REF_GAIN : REF_GAIN + 3] = gain
    out[REF_FINAL_V], out[REF_FINAL_P] = final
    if len(pieces) != 3:
        raise ValueError(f"the reference needs 3 pieces, got {len(pieces)}")
    for k, (a, b, f, v, p) in enumerate(pieces):
        base = REF_PIECES + k * REF_PIECE_SIZE
        out[base], out[base + 1] = a, b
        for j, coefs in enumerate((f, v, p)):
            if len(coefs) > REF_COEFS:
                raise ValueError(f"reference polynomials have at most {REF_COEFS} coefficients, got {len(coefs)}")
            start = base + 2 + j * REF_COEFS + REF_COEFS - len(coefs)  # leading zeros: Horner unchanged
            out[start : start + len(coefs)] = coefs
    _reference_at(out, 0, 0.0, out, REF_HELD_START)
    _reference_at(out, 0, float(t_final_s), out, REF_HELD_END)
    return out


def pack_shared(
    *,
    wheel_inertia_kg_m2: float,
    max_wheel_momentum_nms: float,
    integrator_dt_s: float,
    substeps: int,
    field_model: str,
    dipole_strength_t_m3: float,
    inclination_rad: float,
    table_step_s: float,
    disturbance_kind: int,
    disturbance_scale: float,
    orbital_rate_rad_s: float,
    second_harmonic: bool,
    disturbance_amplitude_nm,
    disturbance_period_s: float,
    gravity_gradient: bool,
    delta_j,
    Q: np.ndarray,
    R: np.ndarray,
    reference: np.ndarray,
) -> np.ndarray:
    """The ``shared`` vector (layout ``SH_*``) of one env configuration. ``delta_j``: None or
    ``(amplitude (3), frequency (3), phase (3))`` of ΔJ(t)."""
    out = np.zeros(SHARED_SIZE)
    out[SH_JW], out[SH_HMAX], out[SH_H], out[SH_NSUB] = (
        wheel_inertia_kg_m2,
        max_wheel_momentum_nms,
        integrator_dt_s,
        substeps,
    )
    out[SH_FIELD] = FIELD_CODES[field_model]
    out[SH_STRENGTH], out[SH_INCL], out[SH_TABLE_STEP] = dipole_strength_t_m3, inclination_rad, table_step_s
    out[SH_DIST], out[SH_DIST_SCALE] = disturbance_kind, disturbance_scale
    out[SH_DIST_RATE], out[SH_DIST_K] = orbital_rate_rad_s, 2.0 if second_harmonic else 1.0
    out[SH_DIST_AMP : SH_DIST_AMP + 3] = disturbance_amplitude_nm
    out[SH_DIST_PERIOD] = disturbance_period_s
    out[SH_GG] = 1.0 if gravity_gradient else 0.0
    if delta_j is not None:
        out[SH_DJ] = 1.0
        out[SH_DJ_AMP : SH_DJ_AMP + 3], out[SH_DJ_FREQ : SH_DJ_FREQ + 3], out[SH_DJ_PHASE : SH_DJ_PHASE + 3] = delta_j
    q_mat, r_mat = np.asarray(Q, dtype=float), np.asarray(R, dtype=float)
    out[SH_Q : SH_Q + 36] = q_mat.reshape(36)
    out[SH_R : SH_R + 9] = r_mat.reshape(9)
    out[SH_DIAG] = float(
        np.array_equal(q_mat, np.diag(np.diag(q_mat))) and np.array_equal(r_mat, np.diag(np.diag(r_mat)))
    )
    out[SH_REF:] = reference
    return out


def pack_env(inertia_kg_m2: np.ndarray, inertia_eff_inv: np.ndarray, orbit: np.ndarray, disturbance) -> np.ndarray:
    """The per-episode ``env`` vector (layout ``EN_*``)."""
    out = np.empty(ENV_SIZE)
    out[EN_INERTIA : EN_INERTIA + 9] = np.asarray(inertia_kg_m2, dtype=float).reshape(9)
    out[EN_EFF_INV : EN_EFF_INV + 9] = np.asarray(inertia_eff_inv, dtype=float).reshape(9)
    out[EN_ORBIT : EN_ORBIT + ORBIT_SIZE] = orbit
    out[EN_DIST : EN_DIST + 3] = disturbance
    return out
