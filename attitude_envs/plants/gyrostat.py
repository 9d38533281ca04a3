"""Rigid spacecraft with N reaction wheels: the exact gyrostat equations.

Conventions (the papers' ``ω̇ = I⁻¹[−ω×(Iω + h_w) + T_c]`` is their small-wheel case):

* ``inertia_kg_m2`` ``I`` is the whole spacecraft's inertia about its centre of mass,
  *including* the wheels' spin-axis inertia ``J_s``;
* ``wheel_axes`` ``A`` (3×N) holds the unit spin axes in body axes;
* ``Ω`` is each wheel's speed *relative to the body* (tachometer reading), rad/s;
* ``u`` is each wheel's motor torque, N·m: positive spins wheel i up about ``a_i`` and the
  body receives the reaction ``−a_i u_i``.

With ``I_eff = I − J_s A Aᵀ`` the equations are

    I_eff ω̇ = −ω × (I ω + J_s A Ω) − A u + T_ext
    J_s (Ω̇_i + a_i·ω̇) = u_i
    q̇ = ½ q ⊗ [ω, 0]

and the total angular momentum ``R(q)(Iω + J_s A Ω)`` is conserved when ``T_ext = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.plants import gyrostat_kernels as kernels


@dataclass(frozen=True)
class GyrostatParams:
    """Physical parameters of a rigid body with reaction wheels (SI units)."""

    inertia_kg_m2: np.ndarray
    wheel_axes: np.ndarray
    wheel_inertia_kg_m2: float
    max_wheel_torque_nm: float
    max_wheel_speed_rad_s: float = np.inf
    # m g r_s (N·m, body axes): centre-of-mass offset on an air bearing, see gravity_torque_nm
    offset_torque_nm: np.ndarray | None = None
    inertia_eff_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        inertia = validation.inertia("inertia_kg_m2", self.inertia_kg_m2)
        axes = validation.finite_array("wheel_axes", self.wheel_axes)
        if axes.ndim != 2 or axes.shape[0] != 3 or axes.shape[1] == 0:
            raise ValueError(f"wheel_axes must be a 3xN matrix with N >= 1 wheels, got shape {axes.shape}")
        norms = np.linalg.norm(axes, axis=0)
        if np.any(np.abs(norms - 1.0) > 1e-6):
            raise ValueError(f"wheel_axes columns must be unit vectors, got norms {norms.tolist()}")
        if np.linalg.matrix_rank(axes, tol=1e-9) < 3:
            raise ValueError("wheel_axes must have rank 3 (the wheels must span all three body axes)")
        j_s = validation.positive("wheel_inertia_kg_m2", self.wheel_inertia_kg_m2)
        validation.positive("max_wheel_torque_nm", self.max_wheel_torque_nm)
        validation.positive("max_wheel_speed_rad_s", self.max_wheel_speed_rad_s, allow_inf=True)
        axes = axes / norms
        inertia_eff = inertia - j_s * axes @ axes.T
        if np.linalg.eigvalsh(inertia_eff)[0] <= 0:
            raise ValueError(
                "wheel_inertia_kg_m2 is too large for inertia_kg_m2: I - J_s A A^T must be positive definite"
            )
        object.__setattr__(self, "inertia_kg_m2", np.ascontiguousarray(inertia))
        object.__setattr__(self, "wheel_axes", np.ascontiguousarray(axes))
        object.__setattr__(self, "wheel_inertia_kg_m2", j_s)
        object.__setattr__(self, "max_wheel_torque_nm", float(self.max_wheel_torque_nm))
        object.__setattr__(self, "max_wheel_speed_rad_s", float(self.max_wheel_speed_rad_s))
        object.__setattr__(self, "inertia_eff_inv", np.linalg.inv(inertia_eff))
        offset = np.zeros(3) if self.offset_torque_nm is None else self.offset_torque_nm
        object.__setattr__(self, "offset_torque_nm", validation.finite_array("offset_torque_nm", offset, (3,)).copy())
        for name in ("inertia_kg_m2", "wheel_axes", "inertia_eff_inv", "offset_torque_nm"):
            getattr(self, name).setflags(write=False)

    @property
    def n_wheels(self) -> int:
        return self.wheel_axes.shape[1]

    def with_inertia(self, inertia_kg_m2: np.ndarray) -> GyrostatParams:
        """The same wheels on a body of another inertia."""
        return GyrostatParams(
            inertia_kg_m2,
            self.wheel_axes,
            self.wheel_inertia_kg_m2,
            self.max_wheel_torque_nm,
            self.max_wheel_speed_rad_s,
            self.offset_torque_nm,
        )


def derivative(
    params: GyrostatParams, y: np.ndarray, motor_torque_nm: np.ndarray, external_torque_nm: np.ndarray
) -> np.ndarray:
    """Time derivative of ``y = [q (4, scalar last), ω (3, rad/s), Ω (N, rad/s)]``."""
    n = params.n_wheels
    out = np.empty((7 + n, 1))
    empty = np.zeros(0)
    constants = kernels.pack_constants(
        params.wheel_axes, empty, empty, params.wheel_inertia_kg_m2, 0.0, np.inf, 0.0, params.offset_torque_nm
    )
    kernels.derivative_columns(
        np.ascontiguousarray(y, dtype=float).reshape(7 + n, 1),
        np.ascontiguousarray(motor_torque_nm, dtype=float).reshape(n, 1),
        np.ascontiguousarray(external_torque_nm, dtype=float).reshape(3, 1),
        kernels.pack_matrices(params.inertia_kg_m2, params.inertia_eff_inv).reshape(-1, 1),
        constants,
        out,
    )
    return out[:, 0]


def gravity_torque_nm(params: GyrostatParams, q: np.ndarray) -> np.ndarray:
    """Torque of gravity about the bearing's centre of rotation, N·m, body axes
    (Ahangarani Farahani et al., air-bearing simulator, eqs. 6–9).

    ``p × K`` with ``p = offset_torque_nm = m g r_s`` and ``K = R(q)ᵀ e_Z`` the gravity
    direction (inertial +Z points down) in body axes. With ``p_z > 0`` (centre of mass below
    the centre of rotation) it is restoring in roll and pitch.
    """
    k = quaternion.to_matrix(np.asarray(q, dtype=float)).T[:, 2]
    return np.cross(params.offset_torque_nm, k)


def gravity_potential_j(params: GyrostatParams, q: np.ndarray) -> float:
    """Potential energy of the offset centre of mass, J: ``V = −p·K`` (so ``−∂V/∂θ = p × K``)."""
    k = quaternion.to_matrix(np.asarray(q, dtype=float)).T[:, 2]
    return float(-params.offset_torque_nm @ k)


def body_momentum(params: GyrostatParams, w: np.ndarray, wheel_speed_rad_s: np.ndarray) -> np.ndarray:
    """Total angular momentum (body + wheels) in body axes, N·m·s."""
    return params.inertia_kg_m2 @ w + params.wheel_inertia_kg_m2 * params.wheel_axes @ wheel_speed_rad_s


def kinetic_energy(params: GyrostatParams, w: np.ndarray, wheel_speed_rad_s: np.ndarray) -> float:
    """Rotational kinetic energy of body and wheels, J.

    With ``I`` including the wheels' spin inertia, ``T = ½ωᵀ(I − J_s AAᵀ)ω + ½J_s Σ(Ω_i + a_i·ω)²``.
    """
    inertia_eff = params.inertia_kg_m2 - params.wheel_inertia_kg_m2 * params.wheel_axes @ params.wheel_axes.T
    absolute = wheel_speed_rad_s + params.wheel_axes.T @ w
    return float(0.5 * w @ inertia_eff @ w + 0.5 * params.wheel_inertia_kg_m2 * absolute @ absolute)


def pyramid_axes(tilt_deg: float, n: int = 4, azimuth_offset_deg: float = 0.0) -> np.ndarray:
    """Unit spin axes of ``n`` wheels tilted ``tilt_deg`` out of the body x–y plane,
    evenly spaced in azimuth starting at ``azimuth_offset_deg`` (3×n)."""
    beta = np.radians(tilt_deg)
    az = np.radians(azimuth_offset_deg) + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([np.cos(beta) * np.cos(az), np.cos(beta) * np.sin(az), np.sin(beta) * np.ones(n)])
