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

from attitude_envs.plants.kernel_math import quad_form

GRAVITY_MU_M3_S2 = 3.986004418e14

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
SH_Q, SH_R, SH_REF = 27, 63, 72
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
# mean m × b + e_y T_w (3); then (advance) 1.0 if the state and cost are finite, max |ω_bo|
ST_APPLIED, ST_TAU, ST_CONTROL, ST_FINITE, ST_MAX_RATE = 0, 4, 7, 10, 11
STEP_OUT_SIZE = 12
WHEEL_SPEED_SCALE_RAD_S = 1e3  # observation scale of the wheel speed
FIELD_SCALE_T = 5e-5  # observation scale of the body-frame field
AUG = 9  # [q (4), ω_bo (3), Ω, cost]
# work buffer: aug, stage input, 4 slopes, 3 contexts (sub-step start, middle, end), x, u,
# and the time of the end context (NaN: none; it is reused when the next sub-step or the
# snapshot falls on exactly that time; callers write NaN when the episode's draws change)
WK_C0 = 6 * AUG
WK_C1, WK_C2 = WK_C0 + CONTEXT_SIZE, WK_C0 + 2 * CONTEXT_SIZE
WK_X, WK_U, WK_TAG = WK_C0 + 3 * CONTEXT_SIZE, WK_C0 + 3 * CONTEXT_SIZE + 6, WK_C0 + 3 * CONTEXT_SIZE + 9
WORK_SIZE = WK_TAG + 1


# ----------------------------------------------------------------------------- orbit
@njit(cache=True, error_model="numpy")
def true_anomaly(orbit, t_s):
    """ν(t) from Kepler's equation M = E − e sin E (Newton, |ΔE| < 1e-13), rad."""
    mean = orbit[ORB_M0] + orbit[ORB_N] * t_s
    e = orbit[ORB_E]
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
def orbit_state_into(orbit, t_s, out):
    """Position, velocity, radius, argument of latitude, ν̇, ν̈ and the LVLH frame at ``t_s``
    (layout ``OS_*``); ``orbit[ORB_MODEL]`` 1: the circular approximation."""
    if orbit[ORB_MODEL] == 1.0:
        u = orbit[ORB_ARGP] + orbit[ORB_M0] + orbit[ORB_N] * t_s
        r, r_dot = orbit[ORB_A], 0.0
        nu_dot, nu_ddot = orbit[ORB_N], 0.0
    else:
        nu = true_anomaly(orbit, t_s)
        u = orbit[ORB_ARGP] + nu
        e, h = orbit[ORB_E], orbit[ORB_H]
        r = orbit[ORB_P] / (1.0 + e * math.cos(nu))
        nu_dot = h / r**2
        r_dot = orbit[ORB_MU] / h * e * math.sin(nu)
        nu_ddot = -2.0 * nu_dot * r_dot / r
    cu, su = math.cos(u), math.sin(u)
    for i in range(3):
        node, in_plane = orbit[ORB_NODE + i], orbit[ORB_IN_PLANE + i]
        r_hat = node * cu + in_plane * su
        t_hat = -node * su + in_plane * cu
        out[OS_POS + i] = r * r_hat
        out[OS_VEL + i] = r_dot * r_hat + r * nu_dot * t_hat
        # LVLH: x = t̂, y = −ĥ (anti-normal), z = −r̂ (nadir)
        out[OS_FRAME + 3 * i] = t_hat
        out[OS_FRAME + 3 * i + 1] = -orbit[ORB_NORMAL + i]
        out[OS_FRAME + 3 * i + 2] = -r_hat
    out[OS_R] = r
    out[OS_U] = u
    out[OS_RATE] = nu_dot
    out[OS_RATE_DOT] = nu_ddot


# ----------------------------------------------------------------------------- field
@njit(cache=True, error_model="numpy")
def dipole_eci_into(px, py, pz, strength_t_m3, out):
    """Axial dipole ``μ_e/r³ [3(m̂·r̂)r̂ − m̂]``, ``m̂ = −z``, at an ECI position (m), tesla."""
    r = math.sqrt(px * px + py * py + pz * pz)
    rx, ry, rz = px / r, py / r, pz / r
    k = strength_t_m3 / r**3
    s = 3.0 * (-rz)
    out[0] = k * (s * rx)
    out[1] = k * (s * ry)
    out[2] = k * (s * rz + 1.0)


@njit(cache=True, error_model="numpy")
def field_orbital_into(t_s, orb_state, model, strength_t_m3, inclination_rad, table, table_step_s, out):
    """Field in the orbital (LVLH) frame at ``t_s`` (tesla): ``model`` 0 dipole, 1 the
    as-printed eq. (9), 2 the IGRF table (ECI, linear interpolation between nodes)."""
    if model == 1:
        si = math.sin(inclination_rad)
        k = strength_t_m3 / orb_state[OS_R] ** 3
        u = orb_state[OS_U]
        out[0] = k * (math.cos(u) * si)
        out[1] = k * math.cos(inclination_rad)
        out[2] = k * (-2.0 * math.sin(u) * si)
        return
    if model == 2:
        k = min(int(t_s / table_step_s), table.shape[0] - 2)
        w = (t_s - k * table_step_s) / table_step_s
        b0 = (1.0 - w) * table[k, 0] + w * table[k + 1, 0]
        b1 = (1.0 - w) * table[k, 1] + w * table[k + 1, 1]
        b2 = (1.0 - w) * table[k, 2] + w * table[k + 1, 2]
    else:
        r = math.sqrt(orb_state[OS_POS] ** 2 + orb_state[OS_POS + 1] ** 2 + orb_state[OS_POS + 2] ** 2)
        rx, ry, rz = orb_state[OS_POS] / r, orb_state[OS_POS + 1] / r, orb_state[OS_POS + 2] / r
        k = strength_t_m3 / r**3
        s = 3.0 * (-rz)
        b0, b1, b2 = k * (s * rx), k * (s * ry), k * (s * rz + 1.0)
    f = OS_FRAME
    for j in range(3):  # eci_from_orbitalᵀ b
        out[j] = orb_state[f + j] * b0 + orb_state[f + 3 + j] * b1 + orb_state[f + 6 + j] * b2


# ----------------------------------------------------------------------------- reference
@njit(cache=True, error_model="numpy")
def _horner(ref, start, x):
    acc = 0.0
    for i in range(REF_COEFS):
        acc = acc * x + ref[start + i]
    return acc


@njit(cache=True, error_model="numpy")
def profile(ref, t_s):
    """``(∫∫f, ∫f, f)`` of the smooth sign function at ``t_s`` (s², s, 1)."""
    if t_s <= 0.0:
        return 0.0, 0.0, 0.0
    for k in range(3):
        base = REF_PIECES + k * REF_PIECE_SIZE
        if t_s <= ref[base + 1]:
            return (
                _horner(ref, base + 2 + 2 * REF_COEFS, t_s),
                _horner(ref, base + 2 + REF_COEFS, t_s),
                _horner(ref, base + 2, t_s),
            )
    v0, p0 = ref[REF_FINAL_V], ref[REF_FINAL_P]
    return p0 + v0 * (t_s - ref[REF_TF]), v0, 0.0


@njit(cache=True, error_model="numpy")
def reference_into(ref, t_s, out):
    """Desired quaternion (scalar last, w ≥ 0), body rate ω_d (rad/s) and q̇_d (1/s) at
    ``t_s``: ``out = [q_d (4), ω_d (3), q̇_d (4)]``; held at t ≤ 0 and t ≥ t_f."""
    if ref[REF_CONST] != 0.0 or t_s <= 0.0:
        for i in range(11):
            out[i] = ref[REF_HELD_START + i]
        return
    if t_s >= ref[REF_TF]:
        for i in range(11):
            out[i] = ref[REF_HELD_END + i]
        return
    _reference_at(ref, t_s, out)


@njit(cache=True, error_model="numpy")
def _reference_at(ref, t_s, out):
    """:func:`reference_into` evaluated from the profile (no held values)."""
    p, v, _ = profile(ref, t_s)
    g0, g1, g2 = ref[REF_GAIN], ref[REF_GAIN + 1], ref[REF_GAIN + 2]
    phi = ref[REF_START] + g0 * p
    theta = ref[REF_START + 1] + g1 * p
    psi = ref[REF_START + 2] + g2 * p
    dphi, dtheta, dpsi = g0 * v, g1 * v, g2 * v
    # quaternion of the 3-2-1 angles through degrees, as quaternion.from_euler_321_deg
    deg, rad = 180.0 / math.pi, math.pi / 180.0
    hf, ht, hp = (phi * deg) * rad * 0.5, (theta * deg) * rad * 0.5, (psi * deg) * rad * 0.5
    sf, cf, st, ct = math.sin(hf), math.cos(hf), math.sin(ht), math.cos(ht)
    sp, cp = math.sin(hp), math.cos(hp)
    qx = sf * ct * cp - cf * st * sp
    qy = cf * st * cp + sf * ct * sp
    qz = cf * ct * sp - sf * st * cp
    qw = cf * ct * cp + sf * st * sp
    if qw < 0:
        qx, qy, qz, qw = -qx, -qy, -qz, -qw
    sf, cf, st, ct = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
    wx = dphi - dpsi * st
    wy = dtheta * cf + dpsi * sf * ct
    wz = -dtheta * sf + dpsi * cf * ct
    out[0], out[1], out[2], out[3] = qx, qy, qz, qw
    out[4], out[5], out[6] = wx, wy, wz
    # q̇_d = ½ q_d ⊗ [ω_d, 0]
    out[7] = 0.5 * (qw * wx + qx * 0.0 + qy * wz - qz * wy)
    out[8] = 0.5 * (qw * wy - qx * wz + qy * 0.0 + qz * wx)
    out[9] = 0.5 * (qw * wz + qx * wy - qy * wx + qz * 0.0)
    out[10] = 0.5 * (qw * 0.0 - qx * wx - qy * wy - qz * wz)


# ----------------------------------------------------------------------------- plant
@njit(cache=True, error_model="numpy")
def paper_disturbance_into(t_s, orbital_rate_rad_s, scale, k, out):
    """Spec 002 eq. (39): ``d_j = d0 + d1 sin(ω0 t + φ_j1) + d2 sin(k ω0 t + φ_j2)``, N·m
    (d0 = 1e-7, d1 = d2 = 1e-5; φ_x = ±π/4, φ_y = ∓π/4, φ_z = (0, π/2)), times ``scale``."""
    a = orbital_rate_rad_s * t_s
    b = k * orbital_rate_rad_s * t_s
    q = math.pi / 4
    sa_p, sa_m = math.sin(a + q), math.sin(a - q)
    sb_m, sb_p = (sa_m, sa_p) if b == a else (math.sin(b - q), math.sin(b + q))  # k = 1: same arguments
    out[0] = scale * (1e-7 + 1e-5 * sa_p + 1e-5 * sb_m)
    out[1] = scale * (1e-7 + 1e-5 * sa_m + 1e-5 * sb_p)
    out[2] = scale * (1e-7 + 1e-5 * math.sin(a) + 1e-5 * math.sin(b + 2 * q))


@njit(cache=True, error_model="numpy")
def inverse3_into(m, base, out, out_base):
    """``out[out_base:+9] = inv(m[base:+9])`` for a 3×3 row-major matrix (adjugate / det)."""
    a, b, c = m[base], m[base + 1], m[base + 2]
    d, e, f = m[base + 3], m[base + 4], m[base + 5]
    g, h, i = m[base + 6], m[base + 7], m[base + 8]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    inv_det = 1.0 / (a * c00 + b * c01 + c * c02)
    out[out_base] = c00 * inv_det
    out[out_base + 1] = (c * h - b * i) * inv_det
    out[out_base + 2] = (b * f - c * e) * inv_det
    out[out_base + 3] = c01 * inv_det
    out[out_base + 4] = (a * i - c * g) * inv_det
    out[out_base + 5] = (c * d - a * f) * inv_det
    out[out_base + 6] = c02 * inv_det
    out[out_base + 7] = (b * g - a * h) * inv_det
    out[out_base + 8] = (a * e - b * d) * inv_det


@njit(cache=True, error_model="numpy")
def context_into(t_s, shared, env, table, ctx):
    """Everything that depends on time only (layout ``CX_*``): orbit, field, reference,
    true inertia ``I + ΔJ(t)`` (spec 002 eq. 35) and its ``(I − J_w e_y e_yᵀ)⁻¹``, disturbance."""
    orb = ctx[CX_ORB : CX_ORB + ORBIT_STATE_SIZE]
    orbit_state_into(env[EN_ORBIT : EN_ORBIT + ORBIT_SIZE], t_s, orb)
    field_orbital_into(
        t_s,
        orb,
        int(shared[SH_FIELD]),
        shared[SH_STRENGTH],
        shared[SH_INCL],
        table,
        shared[SH_TABLE_STEP],
        ctx[CX_B : CX_B + 3],
    )
    reference_into(shared[SH_REF:], t_s, ctx[CX_QD : CX_QD + 11])
    for i in range(9):
        ctx[CX_I + i] = env[EN_INERTIA + i]
    if shared[SH_DJ] != 0.0:
        for j in range(3):
            amp = shared[SH_DJ_AMP + j]
            ctx[CX_I + 4 * j] = env[EN_INERTIA + 4 * j] + amp * math.sin(
                shared[SH_DJ_FREQ + j] * t_s + shared[SH_DJ_PHASE + j]
            )
        for i in range(9):
            ctx[CX_EINV + i] = ctx[CX_I + i]
        ctx[CX_EINV + 4] -= shared[SH_JW]
        inverse3_into(ctx, CX_EINV, ctx, CX_EINV)  # reads all entries before writing
    else:
        for i in range(9):
            ctx[CX_EINV + i] = env[EN_EFF_INV + i]
    disturbance_into(t_s, shared, env, ctx)


@njit(cache=True, error_model="numpy")
def disturbance_into(t_s, shared, env, ctx):
    """The disturbance torque at ``t_s`` (N·m, body axes, without gravity gradient) into
    ``ctx``: spec 002 eq. (39), a torque held over the control step (constant, random walk:
    ``env[EN_DIST:]``) or a sinusoid with the phases ``env[EN_DIST:]``; times the scale."""
    kind = shared[SH_DIST]
    scale = shared[SH_DIST_SCALE]
    if kind == DIST_PAPER:
        paper_disturbance_into(t_s, shared[SH_DIST_RATE], scale, shared[SH_DIST_K], ctx[CX_DIST : CX_DIST + 3])
    elif kind == DIST_HELD:
        for j in range(3):
            ctx[CX_DIST + j] = scale * env[EN_DIST + j]
    elif kind == DIST_SINUSOIDAL:
        arg = 2 * math.pi * t_s / shared[SH_DIST_PERIOD]
        for j in range(3):
            ctx[CX_DIST + j] = scale * (shared[SH_DIST_AMP + j] * math.sin(arg + env[EN_DIST + j]))
    else:
        for j in range(3):
            ctx[CX_DIST + j] = 0.0


@njit(cache=True, error_model="numpy")
def _body_vector(x, y, z, w, v0, v1, v2):
    """``R v`` with ``R`` (orbital → body) of spec 002 eq. (4), scalar-last q."""
    return (
        (1 - 2 * (y * y + z * z)) * v0 + 2 * (x * y + z * w) * v1 + 2 * (x * z - y * w) * v2,
        2 * (x * y - z * w) * v0 + (1 - 2 * (x * x + z * z)) * v1 + 2 * (y * z + x * w) * v2,
        2 * (x * z + y * w) * v0 + 2 * (y * z - x * w) * v1 + (1 - 2 * (x * x + y * y)) * v2,
    )


@njit(cache=True, error_model="numpy")
def gravity_gradient(x, y, z, w, ctx):
    """``3μ/r³ ô × (I ô)``, ô the nadir (orbital z) in body axes, I the true inertia, N·m."""
    o0, o1, o2 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    i = CX_I
    p0 = ctx[i] * o0 + ctx[i + 1] * o1 + ctx[i + 2] * o2
    p1 = ctx[i + 3] * o0 + ctx[i + 4] * o1 + ctx[i + 5] * o2
    p2 = ctx[i + 6] * o0 + ctx[i + 7] * o1 + ctx[i + 8] * o2
    k = 3.0 * GRAVITY_MU_M3_S2 / ctx[CX_ORB + OS_R] ** 3
    return k * (o1 * p2 - o2 * p1), k * (o2 * p0 - o0 * p2), k * (o0 * p1 - o1 * p0)


@njit(cache=True, error_model="numpy")
def error_state(x, y, z, w, w0, w1, w2, q_d, w_d):
    """``q_e = q_d* ⊗ q`` (w ≥ 0) and ``ω_e = ω − C(q_e)ᵀ ω_d``: returns the 7 numbers
    ``(q_e,x, q_e,y, q_e,z, ω_e (3), q_e,w)``."""
    dx, dy, dz, dw = q_d[0], q_d[1], q_d[2], q_d[3]
    ex = dw * x - dx * w - dy * z + dz * y
    ey = dw * y - dy * w - dz * x + dx * z
    ez = dw * z - dz * w - dx * y + dy * x
    ew = dw * w + dx * x + dy * y + dz * z
    if ew < 0:
        ex, ey, ez, ew = -ex, -ey, -ez, -ew
    v0, v1, v2 = w_d[0], w_d[1], w_d[2]
    r0, r1, r2 = _body_vector(ex, ey, ez, ew, v0, v1, v2)
    return ex, ey, ez, w0 - r0, w1 - r1, w2 - r2, ew


@njit(cache=True, error_model="numpy")
def augmented_derivative(aug, m, t_w, shared, ctx, xbuf, ubuf, out):
    """``out = d/dt [q, ω_bo, Ω, cost]`` (spec 002 eqs. 1–8 with the consistent wheel
    bookkeeping, see :mod:`attitude_envs.plants.magnetorquer`): dipole moments ``m`` (A·m²)
    against the field, wheel torque ``t_w`` on the body about +y (N·m), the disturbance and
    optional gravity gradient; cost ``xᵀQx + uᵀRu`` with ``x = [q_e,vec, ω_e]`` and the
    body control torque ``u = m × b + e_y T_w``."""
    x, y, z, w, w0, w1, w2, om = aug[0], aug[1], aug[2], aug[3], aug[4], aug[5], aug[6], aug[7]
    n = (x * x + y * y + z * z + w * w) ** -0.5
    qx, qy, qz, qw = x * n, y * n, z * n, w * n
    b0, b1, b2 = _body_vector(qx, qy, qz, qw, ctx[CX_B], ctx[CX_B + 1], ctx[CX_B + 2])
    tau0, tau1, tau2 = m[1] * b2 - m[2] * b1, m[2] * b0 - m[0] * b2, m[0] * b1 - m[1] * b0  # m × b (eq. 8)
    e0, e1, e2 = ctx[CX_DIST], ctx[CX_DIST + 1], ctx[CX_DIST + 2]
    if shared[SH_GG] != 0.0:
        g0, g1, g2 = gravity_gradient(qx, qy, qz, qw, ctx)
        e0, e1, e2 = e0 + g0, e1 + g1, e2 + g2
    j_w = shared[SH_JW]
    # gyrostat equations (the raw quaternion, as integrated); R e_y is row 1 of to_matrix(q)
    r0, r1, r2 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    nd = ctx[CX_ORB + OS_RATE]
    a0, a1, a2 = -nd * r0, -nd * r1, -nd * r2  # R ω_oi
    c0, c1, c2 = w0 + a0, w1 + a1, w2 + a2  # ω_bi
    i = CX_I
    h0 = ctx[i] * c0 + ctx[i + 1] * c1 + ctx[i + 2] * c2
    h1 = ctx[i + 3] * c0 + ctx[i + 4] * c1 + ctx[i + 5] * c2 + j_w * om
    h2 = ctx[i + 6] * c0 + ctx[i + 7] * c1 + ctx[i + 8] * c2
    s0 = -(c1 * h2 - c2 * h1) + (tau0 + e0)
    s1 = -(c2 * h0 - c0 * h2) + (tau1 + e1) + t_w
    s2 = -(c0 * h1 - c1 * h0) + (tau2 + e2)
    i = CX_EINV
    d0 = ctx[i] * s0 + ctx[i + 1] * s1 + ctx[i + 2] * s2
    d1 = ctx[i + 3] * s0 + ctx[i + 4] * s1 + ctx[i + 5] * s2
    d2 = ctx[i + 6] * s0 + ctx[i + 7] * s1 + ctx[i + 8] * s2
    ndd = ctx[CX_ORB + OS_RATE_DOT]
    out[0] = 0.5 * (w * w0 + y * w2 - z * w1)
    out[1] = 0.5 * (w * w1 + z * w0 - x * w2)
    out[2] = 0.5 * (w * w2 + x * w1 - y * w0)
    out[3] = -0.5 * (x * w0 + y * w1 + z * w2)
    out[4] = d0 + (w1 * a2 - w2 * a1) + ndd * r0
    out[5] = d1 + (w2 * a0 - w0 * a2) + ndd * r1
    out[6] = d2 + (w0 * a1 - w1 * a0) + ndd * r2
    out[7] = -t_w / j_w - d1
    ex, ey, ez, we0, we1, we2, _ = error_state(
        qx, qy, qz, qw, w0, w1, w2, ctx[CX_QD : CX_QD + 4], ctx[CX_WD : CX_WD + 3]
    )
    xbuf[0], xbuf[1], xbuf[2], xbuf[3], xbuf[4], xbuf[5] = ex, ey, ez, we0, we1, we2
    ubuf[0], ubuf[1], ubuf[2] = tau0, tau1 + t_w, tau2
    out[8] = quad_form(shared[SH_Q : SH_Q + 36].reshape((6, 6)), xbuf, 6) + quad_form(
        shared[SH_R : SH_R + 9].reshape((3, 3)), ubuf, 3
    )


@njit(cache=True, error_model="numpy")
def control_step(state, cmd, t0_s, shared, env, table, step_out, work):
    """Advance ``state = [q, ω_bo, Ω]`` (in place) from ``t0_s`` over ``n_sub`` RK4 sub-steps
    with the delivered command ``cmd = [m (3, A·m²), T_w (N·m)]`` held; returns the step cost
    ``∫ (xᵀQx + uᵀRu) dt``. Per sub-step the wheel torque is zeroed when it would grow
    ``|h_w| ≥ h_max`` (spec 002 §6 item 10); the quaternion is renormalized after each.
    ``step_out``: mean applied command (4) and mean magnetic torque ``m × b`` (3, N·m, body
    axes, at the sub-step starts). ``work``: :data:`WORK_SIZE` floats."""
    n_sub = int(shared[SH_NSUB])
    h = shared[SH_H]
    aug = work[0:AUG]
    tmp = work[AUG : 2 * AUG]
    ks = work[2 * AUG : 6 * AUG].reshape((4, AUG))
    c0 = work[WK_C0 : WK_C0 + CONTEXT_SIZE]
    c1 = work[WK_C1 : WK_C1 + CONTEXT_SIZE]
    c2 = work[WK_C2 : WK_C2 + CONTEXT_SIZE]
    xbuf = work[WK_X : WK_X + 6]
    ubuf = work[WK_U : WK_U + 3]
    for i in range(AUG - 1):
        aug[i] = state[i]
    aug[AUG - 1] = 0.0
    j_w, h_max = shared[SH_JW], shared[SH_HMAX]
    wheel_sum, tau0, tau1, tau2 = 0.0, 0.0, 0.0, 0.0
    for j in range(n_sub):
        ts = t0_s + j * h
        if work[WK_TAG] == ts:  # the previous end context: time-only parts are the same
            for i in range(CONTEXT_SIZE):
                c0[i] = c2[i]
            disturbance_into(ts, shared, env, c0)  # a held torque may have changed since
        else:
            context_into(ts, shared, env, table, c0)
        context_into(ts + 0.5 * h, shared, env, table, c1)
        context_into(ts + h, shared, env, table, c2)
        work[WK_TAG] = ts + h
        x, y, z, w = aug[0], aug[1], aug[2], aug[3]
        # wheel momentum h_w = J_w (Ω + ω_bi,y), ω_bi = ω_bo − ν̇ R e_y
        w_bi_y = aug[5] + (1 - 2 * (x * x + z * z)) * (-c0[CX_ORB + OS_RATE])
        h_w = j_w * (aug[7] + w_bi_y)
        t_w = cmd[3]
        if abs(h_w) >= h_max and -t_w * h_w > 0:
            t_w = 0.0
        wheel_sum += t_w
        b0, b1, b2 = _body_vector(x, y, z, w, c0[CX_B], c0[CX_B + 1], c0[CX_B + 2])
        tau0 += cmd[1] * b2 - cmd[2] * b1
        tau1 += cmd[2] * b0 - cmd[0] * b2
        tau2 += cmd[0] * b1 - cmd[1] * b0
        for stage in range(4):  # classical RK4: stages at t, t + h/2, t + h/2, t + h
            if stage == 0:
                for i in range(AUG):
                    tmp[i] = aug[i]
            else:
                c = h if stage == 3 else 0.5 * h
                for i in range(AUG):
                    tmp[i] = aug[i] + c * ks[stage - 1, i]
            ctx = c0 if stage == 0 else (c2 if stage == 3 else c1)
            augmented_derivative(tmp, cmd, t_w, shared, ctx, xbuf, ubuf, ks[stage])
        for i in range(AUG):
            aug[i] = aug[i] + (h / 6.0) * (ks[0, i] + 2.0 * ks[1, i] + 2.0 * ks[2, i] + ks[3, i])
        norm = math.sqrt(aug[0] * aug[0] + aug[1] * aug[1] + aug[2] * aug[2] + aug[3] * aug[3])
        for i in range(4):
            aug[i] /= norm
    for i in range(AUG - 1):
        state[i] = aug[i]
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
    return aug[AUG - 1]


@njit(cache=True, error_model="numpy")
def snapshot_into(state, t_s, shared, env, table, ctx, out):
    """Observation parts and ``info`` quantities of ``state`` at ``t_s`` (layout ``SN_*``):
    error state, scaled wheel speed and field; body and orbital field (T), inertial rate
    (rad/s), wheel momentum (N·m·s), reference, orbit radius / argument of latitude / rate,
    external torque (disturbance + gravity gradient, N·m), true inertia, error angle (deg).
    ``ctx``: a :data:`CONTEXT_SIZE` scratch buffer."""
    context_into(t_s, shared, env, table, ctx)
    snapshot_from_context(state, shared, ctx, out)


@njit(cache=True, error_model="numpy")
def snapshot_from_context(state, shared, ctx, out):
    """:func:`snapshot_into` with the time context ``ctx`` of the snapshot's time given."""
    x, y, z, w = state[0], state[1], state[2], state[3]
    ex, ey, ez, we0, we1, we2, ew = error_state(
        x, y, z, w, state[4], state[5], state[6], ctx[CX_QD : CX_QD + 4], ctx[CX_WD : CX_WD + 3]
    )
    out[SN_X], out[SN_X + 1], out[SN_X + 2] = ex, ey, ez
    out[SN_X + 3], out[SN_X + 4], out[SN_X + 5] = we0, we1, we2
    out[SN_WHEEL] = state[7] / WHEEL_SPEED_SCALE_RAD_S
    b0, b1, b2 = _body_vector(x, y, z, w, ctx[CX_B], ctx[CX_B + 1], ctx[CX_B + 2])
    out[SN_BBODY], out[SN_BBODY + 1], out[SN_BBODY + 2] = b0, b1, b2
    out[SN_BSCALED], out[SN_BSCALED + 1], out[SN_BSCALED + 2] = (
        b0 / FIELD_SCALE_T,
        b1 / FIELD_SCALE_T,
        b2 / FIELD_SCALE_T,
    )
    nd = ctx[CX_ORB + OS_RATE]
    r0, r1, r2 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[SN_WBI] = state[4] + r0 * (-nd)
    out[SN_WBI + 1] = state[5] + r1 * (-nd)
    out[SN_WBI + 2] = state[6] + r2 * (-nd)
    out[SN_HW] = shared[SH_JW] * (state[7] + out[SN_WBI + 1])
    for i in range(11):
        out[SN_QD + i] = ctx[CX_QD + i]
    for i in range(3):
        out[SN_BORB + i] = ctx[CX_B + i]
    out[SN_R] = ctx[CX_ORB + OS_R]
    out[SN_U] = ctx[CX_ORB + OS_U]
    out[SN_RATE] = nd
    e0, e1, e2 = ctx[CX_DIST], ctx[CX_DIST + 1], ctx[CX_DIST + 2]
    if shared[SH_GG] != 0.0:
        g0, g1, g2 = gravity_gradient(x, y, z, w, ctx)
        e0, e1, e2 = e0 + g0, e1 + g1, e2 + g2
    out[SN_EXT], out[SN_EXT + 1], out[SN_EXT + 2] = e0, e1, e2
    for i in range(9):
        out[SN_I + i] = ctx[CX_I + i]
    out[SN_ANGLE] = math.degrees(2.0 * math.acos(min(1.0, abs(ew))))


@njit(cache=True, error_model="numpy")
def advance(state, cmd, t0_s, t1_s, shared, env, table, step_out, snap, work):
    """:func:`control_step` from ``t0_s``, then :func:`snapshot_into` at ``t1_s`` (the end of
    the control step, computed by the caller from the step count); returns the step cost."""
    cost = control_step(state, cmd, t0_s, shared, env, table, step_out, work)
    c2 = work[WK_C2 : WK_C2 + CONTEXT_SIZE]
    if work[WK_TAG] != t1_s:
        context_into(t1_s, shared, env, table, c2)
        work[WK_TAG] = t1_s
    snapshot_from_context(state, shared, c2, snap)
    finite = math.isfinite(cost)
    for i in range(AUG - 1):
        finite = finite and math.isfinite(state[i])
    step_out[ST_FINITE] = 1.0 if finite else 0.0
    step_out[ST_MAX_RATE] = max(abs(state[4]), abs(state[5]), abs(state[6]))
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


@njit(cache=True, error_model="numpy")
def snapshot_batch(states, ts, shared, envs, tables, work, snaps):
    """:func:`snapshot_into` for every row."""
    for e in range(states.shape[0]):
        snapshot_into(states[e], ts[e], shared, envs[e], tables[e], work[e, WK_C0 : WK_C0 + CONTEXT_SIZE], snaps[e])


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
    _reference_at(out, 0.0, out[REF_HELD_START : REF_HELD_START + 11])
    _reference_at(out, float(t_final_s), out[REF_HELD_END : REF_HELD_END + 11])
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
    out[SH_Q : SH_Q + 36] = np.asarray(Q, dtype=float).reshape(36)
    out[SH_R : SH_R + 9] = np.asarray(R, dtype=float).reshape(9)
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
