"""The fuel-slosh plant, defined once (Navabi & Davoodi, eqs. 11–14 in mass-matrix form,
re-derived from their Lagrangian, eqs. 1–10; :mod:`attitude_envs.plants.slosh`): its packed
constants, mass matrix, generalized forces, state derivative, error state, stage cost with
the new inputs, limit checks and the inversion of the new inputs, written on scalars against an
:class:`~attitude_envs.plants.ops.Ops`. :func:`define` returns them for one executor: the
numba kernels (:mod:`attitude_envs.plants.slosh_kernels`), the JAX twin
(:mod:`attitude_envs.jax.fuel_slosh`) and the CasADi model (:mod:`attitude_envs.symbolic.slosh`)
are built from it, so a physics change is one edit here.

The 5×5 mass matrix of ``s = [v_x, v_z, Ω, ψ̇1, ψ̇2]``

    M = [[m_t I₂, C], [Cᵀ, D]],  C = [[Σ m_i l_i sψ_i, m_i l_i sψ_i], [S_z + Σ m_i l_i cψ_i, m_i l_i cψ_i]],
    D = [[I_θθ(ψ), J_i − m_i l_i a_i cψ_i], [·, diag(J_i)]]

has a scalar translational block, so the solve eliminates ``[v̇_x, v̇_z]`` in closed form and
solves the 3×3 symmetric positive definite Schur complement ``D − CᵀC / m_t`` (pitch and slosh
inertia seen by a free-floating body) by an unrolled LDLᵀ.

Packed plant constants (``P_*``): ``[m_t, S_z, I_rigid, m1 l1, m2 l2, J1, J2, a1, a2, ε1,
ε2, F, b + d]`` in kg, kg·m, kg·m², kg·m, kg·m, kg·m², kg·m², m, m, kg·m²/s, kg·m²/s, N, m.
Full state ``y`` (10, SI): ``[X, Z, θ, ψ1, ψ2, v_x, v_z, Ω, ψ̇1, ψ̇2]``; error state
``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]``; new inputs ``u_c = [a_z, Ω̇]`` (m/s², rad/s²).
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

from attitude_envs.plants.ops import Ops, define_quad_form

P_MT, P_SZ, P_IRIGID, P_ML1, P_ML2, P_J1, P_J2, P_A1, P_A2, P_EPS1, P_EPS2, P_F, P_LEVER = range(13)
N_PACKED = 13
N_STATE = 10
N_ERROR = 7
N_LIMIT_ROWS = 8


@functools.cache
def define(ops: Ops) -> SimpleNamespace:
    """The slosh plant's functions for the executor ``ops`` (cached per executor)."""
    sin, cos, sqrt, asin = ops.sin, ops.cos, ops.sqrt, ops.asin
    fabs, fmin, fmax = ops.fabs, ops.fmin, ops.fmax
    quad_form = define_quad_form(ops)

    def packed_constants(p):
        """The 13 packed constants (module docstring) of the physical parameters ``p``: any
        object with :class:`~attitude_envs.plants.slosh.SloshParams`' field names (Navabi &
        Davoodi, Table 3: kg, kg·m², m, N, kg·m²/s; the slosh entries per pendulum), e.g. the
        JAX twin's ``EnvParams``. Plain Python (run once per plant, not compiled)."""
        m1, m2 = p.slosh_mass_kg[0], p.slosh_mass_kg[1]
        i1, i2 = p.slosh_inertia_kg_m2[0], p.slosh_inertia_kg_m2[1]
        a1, a2 = p.hinge_m[0], p.hinge_m[1]
        l1, l2 = p.length_m[0], p.length_m[1]
        mass, fuel_mass, fuel_offset, b = p.mass_kg, p.fuel_mass_kg, p.fuel_offset_m, p.b_m
        s_z = mass * b - fuel_mass * fuel_offset - (m1 * a1 + m2 * a2)
        # pitch inertia about O of everything, without the ψ-dependent pendulum terms
        i_rigid = (
            p.inertia_kg_m2
            + p.fuel_inertia_kg_m2
            + (i1 + i2)
            + mass * (b * b)
            + fuel_mass * (fuel_offset * fuel_offset)
            + (m1 * (a1 * a1 + l1 * l1) + m2 * (a2 * a2 + l2 * l2))
        )
        total = mass + fuel_mass + (m1 + m2)
        eps = p.damping_kg_m2_s
        return (
            total,
            s_z,
            i_rigid,
            m1 * l1,
            m2 * l2,
            i1 + m1 * (l1 * l1),
            i2 + m2 * (l2 * l2),
            a1,
            a2,
            eps[0],
            eps[1],
            p.thrust_n,
            b + p.d_m,
        )

    @ops.compile
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

    @ops.compile
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

    @ops.compile
    def derivative(pk, y, sin_d, cos_d, moment):
        """``ẏ`` (10) of the full state ``y`` under gimbal sin/cos and pitch moment (N·m):
        kinematics, then ``M ṡ = f + G`` solved by eliminating the translational block and an
        LDLᵀ of the 3×3 Schur complement."""
        th, vx, vz, om = y[2], y[5], y[6], y[7]
        c, s = cos(th), sin(th)
        s1, c1 = sin(y[3]), cos(y[3])
        s2, c2 = sin(y[4]), cos(y[4])
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
        return (
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
        )

    @ops.compile
    def invert_inputs(pk, y, u1, u2, iterations):
        """The gimbal angle δ (rad) and pitch moment M_c (N·m) that realize the new inputs
        ``a_z = u1`` (m/s²) and ``Ω̇ = u2`` (rad/s²) at the full state ``y``: Navabi & Davoodi's
        nonlinear eqs. 11–13 solved for the inputs (with ``v̇_z = a_z + Ω v_x`` and Ω̇ known,
        the v_x and slosh rows give ``v̇_x, ψ̈`` for a gimbal cosine, the z row then the gimbal
        sine; ``iterations`` fixed-point passes from δ = 0). Returns ``(δ, M_c, saturated)``:
        ``saturated`` when |sin δ| had to be clipped to 1 (the thrust's transverse authority
        exceeded)."""
        s1, c1 = sin(y[3]), cos(y[3])
        s2, c2 = sin(y[4]), cos(y[4])
        mt, m02, m12, m22, m03, m04, m13, m14, m23, m24, j1, j2 = mass_entries(pk, s1, c1, s2, c2)
        f0, f1, f2, f3, f4 = force_entries(pk, y, 0.0, 0.0, 0.0, s1, c1, s2, c2)  # no thrust
        dvz = u1 + y[7] * y[5]
        # the v_x and slosh rows with v̇_z, Ω̇ moved right (M01 = 0); their block
        # [[m_t, M03, M04], [M03, J1, 0], [M04, 0, J2]] is eliminated toward v̇_x
        r1 = f3 - (m13 * dvz + m23 * u2)
        r2 = f4 - (m14 * dvz + m24 * u2)
        e1, e2 = m03 / j1, m04 / j2
        pivot = mt - (m03 * e1 + m04 * e2)
        sin_d, cos_d = 0.0, 1.0
        saturated = False
        dvx, dp1, dp2 = 0.0, 0.0, 0.0
        for _ in range(iterations):
            r0 = f0 - m02 * u2 + pk[P_F] * cos_d
            dvx = (r0 - (e1 * r1 + e2 * r2)) / pivot
            dp1 = (r1 - m03 * dvx) / j1
            dp2 = (r2 - m04 * dvx) / j2
            sin_raw = (mt * dvz + m12 * u2 + m13 * dp1 + m14 * dp2 - f1) / pk[P_F]
            saturated = fabs(sin_raw) > 1.0
            sin_d = fmax(-1.0, fmin(1.0, sin_raw))
            cos_d = sqrt(1.0 - sin_d * sin_d)
        moment = m02 * dvx + m12 * dvz + m22 * u2 + m23 * dp1 + m24 * dp2 - f2 - pk[P_LEVER] * pk[P_F] * sin_d
        return asin(sin_d), moment, saturated

    @ops.compile
    def error_state(y):
        """``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` of the full state ``y``."""
        return y[6], y[2], y[7], y[3], y[8], y[4], y[9]

    @ops.compile
    def augmented(pk, y, sin_d, cos_d, moment, Q, R):
        """``(ẏ (10), stage cost xᵀQx + u_cᵀRu_c, a_z, Ω̇)``: the derivative with the running
        cost and the new inputs ``u_c = [a_z, Ω̇]`` (``a_z = v̇_z − Ω v_x`` of the tank centre,
        m/s²; rad/s²), Q (7×7) on the error state, R (2×2) on u_c."""
        dy = derivative(pk, y, sin_d, cos_d, moment)
        a_z = dy[6] - y[7] * y[5]
        dom = dy[7]
        stage = quad_form(Q, error_state(y), N_ERROR) + quad_form(R, (a_z, dom), 2)
        return dy, stage, a_z, dom

    @ops.compile
    def limit_rows(y, max_slosh_angle_rad, max_pitch_rate_rad_s, max_pitch_angle_rad):
        """The termination limits as 8 rows ``g(y) ≤ 0`` (inside) — ``±ψ1, ±ψ2`` against the
        slosh limit, ``±Ω`` the pitch-rate limit, ``±θ`` the pitch limit (rad, rad/s); a limit
        is crossed when a row is > 0 (a NaN row crosses nothing)."""
        return (
            y[3] - max_slosh_angle_rad,
            -y[3] - max_slosh_angle_rad,
            y[4] - max_slosh_angle_rad,
            -y[4] - max_slosh_angle_rad,
            y[7] - max_pitch_rate_rad_s,
            -y[7] - max_pitch_rate_rad_s,
            y[2] - max_pitch_angle_rad,
            -y[2] - max_pitch_angle_rad,
        )

    return SimpleNamespace(
        packed_constants=packed_constants,
        mass_entries=mass_entries,
        force_entries=force_entries,
        derivative=derivative,
        error_state=error_state,
        augmented=augmented,
        limit_rows=limit_rows,
        invert_inputs=invert_inputs,
        quad_form=quad_form,
    )
