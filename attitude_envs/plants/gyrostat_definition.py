"""The gyrostat (ReactionWheel, AirBearing), defined once: the equations of motion, the error
state, the stage cost's quadratic forms and input terms, the motor driver's limits and the
roll/pitch stop, written against an :class:`~attitude_envs.plants.ops.Ops` on *rows*.

Equations (:mod:`attitude_envs.plants.gyrostat`)::

    I_eff ω̇ = −ω × (Iω + J_s A Ω) − A u + T_ext + p × K,   Ω̇_i = u_i / J_s − a_i·ω̇,
    q̇ = ½ q ⊗ [ω, 0]

with ``K = R(q)ᵀ e_Z`` the unit gravity direction in body axes and ``p`` the offset torque of
the air-bearing table (Ahangarani Farahani et al., eqs. 6–9; zero for a free body).

Rows: every quantity is a row of a scratch ``W`` read and written as ``W[r * B + e]`` (row
``r`` of lane ``e`` of a block ``B`` lanes wide) and the shared constants are a flat ``C``
(layout of :func:`attitude_envs.plants.gyrostat_kernels.pack_constants`: the wheel axes
``A`` (3×N, row-major) at ``ax``, ``Q`` at ``cq``, ``R`` at ``cr``, the scalars ``S_JS …``
at ``sc``). The numba kernel runs the functions on its blocked buffer, one env per SIMD
lane (inlined, so the loops over ``e`` vectorize); the JAX twin and the CasADi model run
them on a Python list of scalars with ``B = 1, e = 0``. The order of every sum is the
kernel's, so all executors round alike (JAX up to XLA's fused multiply-adds).

Flags ``n``, ``offset``, ``include_h``, ``diagonal``, ``body_input``, ``flip`` are plain
Python values (compile-time constants of a numba kernel, static for the tracing executors).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

from attitude_envs.plants.ops import Ops

#: Scalar constants of a step, in the order of ``pack_constants``: J_s (kg·m²), torque limit
#: (N·m), speed limit (rad/s), RK4 sub-step h (s), offset torque p (3, N·m), tumble limit
#: (rad/s), control period (s), episode duration (s), sine and cosine of the roll/pitch stop
S_JS, S_MAX_TORQUE, S_MAX_SPEED, S_H, S_PX, S_PY, S_PZ, S_MAX_RATE, S_DT, S_DURATION, S_TILT_SIN, S_TILT_COS = range(12)
N_SCALARS = 12
#: Per-env matrix rows: 0–8 the inertia ``I`` (row-major), 9–17 ``I_eff⁻¹``.
MAT_ROWS = 18


@functools.cache
def define(ops: Ops) -> SimpleNamespace:
    """The gyrostat's functions for the executor ``ops`` (cached per executor)."""
    sqrt, fabs, where = ops.sqrt, ops.fabs, ops.where

    @ops.compile
    def derivative_lane(W, C, e, B, n, offset, y, u, uj, ext, mat, out, ax, sc):
        """Rows ``out[0:7+n]`` = ẏ of the state rows ``y`` (q, ω, Ω), motor torque rows ``u``
        (N·m) and ``uj`` (``u_i / J_s``, :func:`input_terms_lane`), external torque rows
        ``ext`` (3, N·m, body), matrix rows ``mat``; ``ax`` and ``sc`` the offsets of the
        wheel axes and of the scalars in ``C``. ``offset``: add ``p × K``."""
        j_s = C[sc + S_JS]
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
            p0, p1, p2 = C[sc + S_PX], C[sc + S_PY], C[sc + S_PZ]
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

    @ops.compile
    def error_state_lane(W, C, e, B, n, include_h, y, target, x, sc, flip):
        """Rows ``x`` = ``[q_e,vec, ω, (J_s Ω)]`` with ``q_e = q_T* ⊗ q/|q|`` of the state rows
        ``y`` and target rows ``target``, signed so that ``q_e,w ≥ 0`` with ``flip`` (without,
        a smooth function of the state); returns ``q_e,w``."""
        qx = W[y * B + e]
        qy = W[(y + 1) * B + e]
        qz = W[(y + 2) * B + e]
        qw = W[(y + 3) * B + e]
        norm = sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
        px = -W[target * B + e]
        py = -W[(target + 1) * B + e]
        pz = -W[(target + 2) * B + e]
        pw = W[(target + 3) * B + e]
        ex = pw * qx + px * qw + py * qz - pz * qy
        ey = pw * qy - px * qz + py * qw + pz * qx
        ez = pw * qz + px * qy - py * qx + pz * qw
        ew = pw * qw - px * qx - py * qy - pz * qz
        if flip:
            sign = where(ew < 0.0, -1.0, 1.0)
            ex, ey, ez, ew = sign * ex, sign * ey, sign * ez, sign * ew
        W[x * B + e] = ex
        W[(x + 1) * B + e] = ey
        W[(x + 2) * B + e] = ez
        W[(x + 3) * B + e] = W[(y + 4) * B + e]
        W[(x + 4) * B + e] = W[(y + 5) * B + e]
        W[(x + 5) * B + e] = W[(y + 6) * B + e]
        if include_h:
            j_s = C[sc + S_JS]
            for i in range(n):
                W[(x + 6 + i) * B + e] = j_s * W[(y + 7 + i) * B + e]
        return ew

    @ops.compile
    def quad_form_lane(W, C, e, B, mat, v, k, diagonal):
        """``vᵀ M v`` of the ``k`` rows ``v``, ``M`` row-major in ``C`` at ``mat``, summed row by
        row (the order of :func:`attitude_envs.plants.ops.define_quad_form`). With
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

    @ops.compile
    def state_cost_lane(W, C, e, B, n, include_h, diagonal_q, y, target, x, cq, sc, flip):
        """``xᵀQx`` of the state rows ``y`` (``x``: scratch rows for the error state)."""
        error_state_lane(W, C, e, B, n, include_h, y, target, x, sc, flip)
        return quad_form_lane(W, C, e, B, cq, x, 6 + n if include_h else 6, diagonal_q)

    @ops.compile
    def input_terms_lane(W, C, e, B, n, body_input, u, uj, uc, ax, cr, sc):
        """What the RK4 stages share while the motor torque rows ``u`` are held: rows ``uj`` =
        ``u_i / J_s``, and the returned input cost ``u_cᵀRu_c`` with ``u_c = −A u``
        (``body_input``) or ``u`` (``uc``: scratch rows)."""
        j_s = C[sc + S_JS]
        for i in range(n):
            W[(uj + i) * B + e] = W[(u + i) * B + e] / j_s
        if body_input:
            for k in range(3):
                acc = 0.0
                for i in range(n):
                    acc -= C[ax + k * n + i] * W[(u + i) * B + e]
                W[(uc + k) * B + e] = acc
            return quad_form_lane(W, C, e, B, cr, uc, 3, False)
        return quad_form_lane(W, C, e, B, cr, u, n, False)

    @ops.compile
    def tilt_lane(qx, qy, qz, qw, tilt_sin, tilt_cos):
        """Whether roll φ or pitch θ (3-2-1 Euler angles of ``q``) is beyond the stop ``L``:
        ``|θ| > L ⟺ |sin θ| > sin L`` and ``|φ| > L ⟺ cos φ < cos L`` (``L < π/2``), the
        angles of :func:`attitude_envs.euler.euler_321_rad` without the inverse trigonometry."""
        n2 = qx * qx + qy * qy + qz * qz + qw * qw
        s = 2.0 * (qw * qx + qy * qz)
        c = n2 - 2.0 * (qx * qx + qy * qy)
        sin_pitch = 2.0 * (qw * qy - qz * qx) / n2
        return (fabs(sin_pitch) > tilt_sin) | (c < tilt_cos * sqrt(s * s + c * c))

    @ops.compile
    def clip(v, lo, hi):
        """``min(max(v, lo), hi)`` written as two selects (numba's ``min``/``max`` do not vectorize)."""
        v = where(v < lo, lo, v)
        return where(v > hi, hi, v)

    @ops.compile
    def speed_limit_lane(W, C, e, B, i, cmd, wheel, sc):
        """Motor torque (N·m) of wheel ``i`` after the torque limit and the motor driver's
        speed limit: over the next ``h`` seconds the torque may take the wheel up to
        ``±max_speed`` but not beyond (ignoring the small body-coupling term ``a_i·ω̇``), so a
        wheel at its limit gets no further torque outwards."""
        max_torque, max_speed, j_s, h = C[sc + S_MAX_TORQUE], C[sc + S_MAX_SPEED], C[sc + S_JS], C[sc + S_H]
        v = clip(W[(cmd + i) * B + e], -max_torque, max_torque)
        wheel_speed = W[(wheel + i) * B + e]
        hi = j_s / h * (max_speed - wheel_speed)
        lo = j_s / h * (-max_speed - wheel_speed)
        limited = clip(clip(v, lo, hi), -max_torque, max_torque)
        return where(max_speed < math.inf, limited, v)

    return SimpleNamespace(
        derivative_lane=derivative_lane,
        error_state_lane=error_state_lane,
        quad_form_lane=quad_form_lane,
        state_cost_lane=state_cost_lane,
        input_terms_lane=input_terms_lane,
        tilt_lane=tilt_lane,
        clip=clip,
        speed_limit_lane=speed_limit_lane,
    )
