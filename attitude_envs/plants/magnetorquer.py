"""Nano-satellite with three magnetorquers and one reaction wheel on body y (the plant of
Sadigh, Kashaninia & Dehghan 2022, §2).

State ``y = [q (4, scalar last: body relative to the orbital frame), ω_bo (3, rad/s, body
rate relative to the orbital frame in body axes), Ω (1, wheel speed relative to the body,
rad/s)]``. The dynamics are the exact gyrostat equations of
:mod:`attitude_envs.plants.gyrostat` for one wheel on ``e_y`` (the paper's eqs. 5–6 with
consistent momentum bookkeeping: ``I_eff``, not ``J_t``, on the left; the difference,
J_w/J_yy ≈ 5e-5, is negligible):

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
term). ``R`` (orbital → body) is ``to_matrix(q)ᵀ``, the paper's eq. (4).

The equations, the momentum limit of the wheel (Table 1's storable momentum, enforced by
blocking any torque that would raise ``|h_w|`` past it), the disturbance of eq. (39), the
gravity gradient, ΔJ(t) of eq. (35) and the RK4 step are compiled in
:mod:`attitude_envs.plants.magnetorquer_kernels` (the one implementation); this module holds
the parameter container and the small helpers the controllers use. The paper's values are
the preset ``sadigh-2022`` (:mod:`attitude_envs.presets.sadigh_2022`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from attitude_envs import validation

E_Y = np.array([0.0, 1.0, 0.0])
_DELTA_J_KEYS = ("amplitude_kg_m2", "frequency_rad_s", "phase_rad")


@dataclass(frozen=True)
class MagnetorquerParams:
    """Physical parameters (SI). ``inertia_kg_m2`` includes the wheel's spin inertia."""

    inertia_kg_m2: np.ndarray
    wheel_inertia_kg_m2: float
    max_dipole_am2: float
    max_wheel_torque_nm: float
    max_wheel_momentum_nms: float
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


def orbital_to_body(q: np.ndarray) -> np.ndarray:
    """``R`` of the paper's eq. (4): maps orbital-frame vectors to body axes (scalar-last q)."""
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


@dataclass(frozen=True)
class TimeVaryingInertia:
    """Sadigh et al. 2022 eq. (35)'s form: ``ΔJ(t) = diag(a_j sin(f_j t + φ_j))`` added to the
    true inertia, kg·m² (evaluated by the compiled step,
    :func:`attitude_envs.plants.magnetorquer_kernels.context_into`)."""

    amplitude_kg_m2: np.ndarray
    frequency_rad_s: np.ndarray
    phase_rad: np.ndarray

    @classmethod
    def from_config(cls, config: dict | None, defaults: Mapping | None = None) -> TimeVaryingInertia | None:
        """From a dict with ``amplitude_kg_m2``, ``frequency_rad_s``, ``phase_rad`` (3 each);
        keys it lacks come from ``defaults``. None: no time-varying inertia."""
        if config is None:
            return None
        if not isinstance(config, Mapping):
            raise ValueError(f"time_varying_inertia must be a dict or None, got {config!r}")
        unknown = set(config) - set(_DELTA_J_KEYS)
        if unknown:
            raise ValueError(f"time_varying_inertia has unknown keys {sorted(unknown)}")
        cfg = {**(defaults or {}), **config}
        missing = [k for k in _DELTA_J_KEYS if k not in cfg]
        if missing:
            raise ValueError(f"time_varying_inertia needs the keys {list(_DELTA_J_KEYS)}, missing {missing}")
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
