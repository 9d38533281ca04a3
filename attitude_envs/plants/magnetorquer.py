"""Nano-satellite with three magnetorquers and one reaction wheel on body y (spec 002 §2).

State ``y = [q (4, scalar last: body relative to the orbital frame), ω_bo (3, rad/s, body
rate relative to the orbital frame in body axes), Ω (1, wheel speed relative to the body,
rad/s)]``. The dynamics are the exact gyrostat equations of
:mod:`attitude_envs.plants.gyrostat` for one wheel on ``e_y`` (spec 002 eqs. 5–6 with the
consistent momentum bookkeeping the spec recommends, §2.2):

    I_eff ω̇_bi = −ω_bi × (I ω_bi + J_w e_y Ω) + e_y T_w + τ        I_eff = I − J_w e_y e_yᵀ
    J_w (Ω̇ + ω̇_bi,y) = −T_w
    ω_bi = ω_bo + R ω_oi,   ω_oi = [0, −ν̇, 0]                         (eq. 3)
    ω̇_bo = ω̇_bi + ω_bo × R ω_oi − R ω̇_oi                            (eq. 12 with ν̈)
    q̇ = ½ q ⊗ [ω_bo, 0]                                                (eq. 1)

``I`` is the whole spacecraft's inertia including the wheel's spin inertia (``J_t`` of
the paper). ``T_w`` is the paper's wheel torque: the torque *on the body* about +y (the
motor applies −T_w to the wheel, eq. 6). ``τ`` holds the magnetic torque ``m × b``
(eqs. 7–8: ``B m = m × b``), the external disturbance and, optionally, gravity gradient.
With a time-varying inertia ``I(t)`` the equation is used as printed (eq. 5, no ``İω``
term, spec §6 item 16). ``R`` (orbital → body) is ``to_matrix(q)ᵀ``, the paper's eq. (4).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from attitude_envs import validation

E_Y = np.array([0.0, 1.0, 0.0])

# Spec 002 §2.5, §2.7 [READ]
PAPER_BODY_INERTIA_KG_M2 = np.diag([0.951, 0.97, 0.946])
PAPER_WHEEL_INERTIA_KG_M2 = 50e-6
PAPER_MAX_DIPOLE_AM2 = 0.5
PAPER_MAX_WHEEL_TORQUE_NM = 2.3e-4
PAPER_MAX_WHEEL_MOMENTUM_NMS = 40.0  # as printed; spec §6 item 10: likely 0.04
# Spec 002 eq. (35): ΔJ_s(t) = 0.095 diag(sin 0.3t, 2 cos 0.2t, sin 0.1t)
PAPER_DELTA_J = {
    "amplitude_kg_m2": [0.095, 0.19, 0.095],
    "frequency_rad_s": [0.3, 0.2, 0.1],
    "phase_rad": [0.0, np.pi / 2, 0.0],
}


@dataclass(frozen=True)
class MagnetorquerParams:
    """Physical parameters (SI). ``inertia_kg_m2`` includes the wheel's spin inertia."""

    inertia_kg_m2: np.ndarray
    wheel_inertia_kg_m2: float = PAPER_WHEEL_INERTIA_KG_M2
    max_dipole_am2: float = PAPER_MAX_DIPOLE_AM2
    max_wheel_torque_nm: float = PAPER_MAX_WHEEL_TORQUE_NM
    max_wheel_momentum_nms: float = PAPER_MAX_WHEEL_MOMENTUM_NMS
    inertia_eff_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        inertia = validation.inertia("inertia_kg_m2", self.inertia_kg_m2)
        j_w = validation.positive("wheel_inertia_kg_m2", self.wheel_inertia_kg_m2)
        eff = inertia - j_w * np.outer(E_Y, E_Y)
        if np.linalg.eigvalsh(eff)[0] <= 0:
            raise ValueError("wheel_inertia_kg_m2 is too large for inertia_kg_m2: I - J_w e_y e_y^T must be PD")
        object.__setattr__(self, "inertia_kg_m2", inertia)
        object.__setattr__(self, "wheel_inertia_kg_m2", j_w)
        object.__setattr__(self, "max_dipole_am2", validation.positive("max_dipole_am2", self.max_dipole_am2))
        object.__setattr__(
            self, "max_wheel_torque_nm", validation.positive("max_wheel_torque_nm", self.max_wheel_torque_nm)
        )
        object.__setattr__(
            self,
            "max_wheel_momentum_nms",
            validation.positive("max_wheel_momentum_nms", self.max_wheel_momentum_nms, allow_inf=True),
        )
        object.__setattr__(self, "inertia_eff_inv", np.linalg.inv(eff))

    @property
    def limits(self) -> np.ndarray:
        """Per-actuator output limits [m_x, m_y, m_z (A·m²), T_w (N·m)]."""
        d = self.max_dipole_am2
        return np.array([d, d, d, self.max_wheel_torque_nm])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for 3-vectors without ``np.cross``'s overhead."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def orbital_to_body(q: np.ndarray) -> np.ndarray:
    """``R`` of spec 002 eq. (4): maps orbital-frame vectors to body axes (scalar-last q)."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)],
            [2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)],
            [2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def inertial_rate(q: np.ndarray, rate_bo: np.ndarray, orbital_rate_rad_s: float) -> np.ndarray:
    """``ω_bi = ω_bo + R ω_oi`` (eq. 3), rad/s, body axes."""
    return rate_bo + orbital_to_body(q)[:, 1] * (-orbital_rate_rad_s)


def derivative(
    y,
    inertia_kg_m2: np.ndarray,
    inertia_eff_inv: np.ndarray,
    wheel_inertia_kg_m2: float,
    wheel_torque_nm: float,
    torque_nm,
    orbital_rate_rad_s: float,
    orbital_rate_dot_rad_s2: float = 0.0,
) -> np.ndarray:
    """Time derivative of ``y = [q (4), ω_bo (3), Ω (1)]`` (see the module docstring).

    Written with Python floats (3-vectors are cheaper that way than as numpy arrays: this
    is the hot path of every env step).
    """
    x, yq, z, s, w0, w1, w2, om = (float(v) for v in y[:8])
    # R e_y: the orbital y axis in body axes (row 1 of to_matrix(q))
    r0, r1, r2 = 2 * (x * yq + z * s), 1 - 2 * (x * x + z * z), 2 * (yq * z - x * s)
    nd = orbital_rate_rad_s
    a0, a1, a2 = -nd * r0, -nd * r1, -nd * r2  # R ω_oi
    b0, b1, b2 = w0 + a0, w1 + a1, w2 + a2  # ω_bi
    (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = inertia_kg_m2.tolist()
    h0 = i00 * b0 + i01 * b1 + i02 * b2
    h1 = i10 * b0 + i11 * b1 + i12 * b2 + wheel_inertia_kg_m2 * om
    h2 = i20 * b0 + i21 * b1 + i22 * b2
    t0, t1, t2 = (float(v) for v in torque_nm)
    c0 = -(b1 * h2 - b2 * h1) + t0
    c1 = -(b2 * h0 - b0 * h2) + t1 + wheel_torque_nm
    c2 = -(b0 * h1 - b1 * h0) + t2
    (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = inertia_eff_inv.tolist()
    d0 = e00 * c0 + e01 * c1 + e02 * c2
    d1 = e10 * c0 + e11 * c1 + e12 * c2
    d2 = e20 * c0 + e21 * c1 + e22 * c2
    om_dot = -wheel_torque_nm / wheel_inertia_kg_m2 - d1
    ndd = orbital_rate_dot_rad_s2
    return np.array(
        [
            0.5 * (s * w0 + yq * w2 - z * w1),
            0.5 * (s * w1 + z * w0 - x * w2),
            0.5 * (s * w2 + x * w1 - yq * w0),
            -0.5 * (x * w0 + yq * w1 + z * w2),
            d0 + (w1 * a2 - w2 * a1) + ndd * r0,
            d1 + (w2 * a0 - w0 * a2) + ndd * r1,
            d2 + (w0 * a1 - w1 * a0) + ndd * r2,
            om_dot,
        ]
    )


def angular_momentum_inertial(
    q_bo: np.ndarray,
    w_bi: np.ndarray,
    wheel_speed: float,
    inertia_kg_m2: np.ndarray,
    wheel_inertia_kg_m2: float,
    eci_from_orbital: np.ndarray,
) -> np.ndarray:
    """Total angular momentum (body + wheel) in ECI axes, N·m·s."""
    h_b = inertia_kg_m2 @ w_bi + wheel_inertia_kg_m2 * wheel_speed * E_Y
    return eci_from_orbital @ (orbital_to_body(q_bo).T @ h_b)


def wheel_momentum_limited(wheel_torque_nm: float, wheel_momentum_nms: float, max_momentum_nms: float) -> float:
    """Spec 002 §6 item 10: at ``|h_w| ≥ h_max`` a torque that would grow ``|h_w|`` is zeroed.

    ``h_w = J_w(Ω + ω_bi,y)``; the body torque ``T_w`` changes it by ``−T_w``.
    """
    if abs(wheel_momentum_nms) >= max_momentum_nms and -wheel_torque_nm * wheel_momentum_nms > 0:
        return 0.0
    return wheel_torque_nm


def paper_disturbance_nm(t_s: float, orbital_rate_rad_s: float, scale: float = 1.0, second_harmonic: bool = False):
    """Spec 002 eq. (39): ``d_j = d0 + d1 sin(ω0 t + φ_j1) + d2 sin(k ω0 t + φ_j2)``, N·m.

    d0 = 1e-7, d1 = d2 = 1e-5 on every axis; φ_x = ±π/4, φ_y = ∓π/4, φ_z = (0, π/2) (the
    spec's reading of the garbled z phases); ``k = 1`` as printed, 2 with
    ``second_harmonic``; the whole torque is multiplied by ``scale``.
    """
    w0 = orbital_rate_rad_s
    k = 2.0 if second_harmonic else 1.0
    a = w0 * t_s
    b = k * w0 * t_s
    q = np.pi / 4
    d = np.array(
        [
            1e-7 + 1e-5 * np.sin(a + q) + 1e-5 * np.sin(b - q),
            1e-7 + 1e-5 * np.sin(a - q) + 1e-5 * np.sin(b + q),
            1e-7 + 1e-5 * np.sin(a) + 1e-5 * np.sin(b + 2 * q),
        ]
    )
    return scale * d


def gravity_gradient_nm(
    q_bo: np.ndarray, inertia_kg_m2: np.ndarray, radius_m: float, mu_m3_s2: float = 3.986004418e14
) -> np.ndarray:
    """Gravity-gradient torque ``3μ/r³ ô × (I ô)``, ô the nadir (orbital z) in body axes, N·m."""
    o = orbital_to_body(q_bo)[:, 2]
    return 3.0 * mu_m3_s2 / radius_m**3 * cross(o, inertia_kg_m2 @ o)


@dataclass(frozen=True)
class TimeVaryingInertia:
    """Spec 002 eq. (35): ``ΔJ(t) = diag(a_j sin(f_j t + φ_j))`` added to the true inertia, kg·m²."""

    amplitude_kg_m2: np.ndarray
    frequency_rad_s: np.ndarray
    phase_rad: np.ndarray

    @classmethod
    def from_config(cls, config: dict | None) -> TimeVaryingInertia | None:
        if config is None:
            return None
        if not isinstance(config, dict):
            raise ValueError(f"time_varying_inertia must be a dict or None, got {config!r}")
        unknown = set(config) - set(PAPER_DELTA_J)
        if unknown:
            raise ValueError(f"time_varying_inertia has unknown keys {sorted(unknown)}")
        cfg = dict(PAPER_DELTA_J, **config)
        amp = validation.finite_array("time_varying_inertia.amplitude_kg_m2", cfg["amplitude_kg_m2"], (3,))
        if np.any(amp < 0):
            raise ValueError(f"time_varying_inertia.amplitude_kg_m2 must be >= 0, got {amp.tolist()}")
        freq = validation.finite_array("time_varying_inertia.frequency_rad_s", cfg["frequency_rad_s"], (3,))
        phase = validation.finite_array("time_varying_inertia.phase_rad", cfg["phase_rad"], (3,))
        return cls(amp, freq, phase)

    def check_against(self, inertia_kg_m2: np.ndarray) -> None:
        """``I + ΔJ(t)`` stays positive definite for every t (Weyl: λ_min(I) > max a_j)."""
        low = float(np.linalg.eigvalsh(inertia_kg_m2)[0])
        if low <= float(np.max(self.amplitude_kg_m2)):
            raise ValueError(
                f"time_varying_inertia.amplitude_kg_m2 (max {np.max(self.amplitude_kg_m2)}) must stay below the "
                f"smallest principal moment {low:.4g} kg·m² so that the inertia stays positive definite"
            )

    def delta_at(self, t_s: float) -> np.ndarray:
        return np.diag(self.amplitude_kg_m2 * np.sin(self.frequency_rad_s * t_s + self.phase_rad))
