"""Planar spacecraft with two-pendulum fuel slosh (Navabi & Davoodi, "Modelling and control
of fuel slosh and its effect on spacecraft attitude"; year not in our copy, ≥ 2012): the
full 5-DOF plant.

Body frame {i, k} with origin at the tank centre O (the paper's frame): i forward (thrust
direction at δ = 0), k transverse, pitch θ about j with θ̇ = Ω. Vehicle point mass m at
x = −b, rigid fuel m0 at x = a0, thrust F (N) applied at x = −(b + d) with gimbal angle δ,
pendulum i hinged at x = a_i with mass at ``(a_i − l_i cos ψ_i, l_i sin ψ_i)`` and absolute
rate Ω + ψ̇_i. No gravity.

Equations of motion in mass-matrix form (the paper's eqs. 11–14, which our copy gives only
as skeletons; re-derived from its Lagrangian, eqs. 1–10)::

    M(ψ) ṡ = f(s, ψ) + G(δ, M_c),   s = [v_x, v_z, Ω, ψ̇1, ψ̇2]

The closed forms were derived once with sympy from the inertial Lagrangian
(``tools/derive_slosh.py``) and are implemented once, compiled, in
:mod:`attitude_envs.plants.slosh_kernels` (the functions below are thin wrappers);
``tests/test_slosh_plant.py`` re-derives them and checks the residual, plus
energy/momentum conservation and the mass matrix's definiteness.

Full state vector ``y`` (10 entries, SI units):
``[X_m, Z_m, θ_rad, ψ1_rad, ψ2_rad, v_x_m_s, v_z_m_s, Ω_rad_s, ψ̇1_rad_s, ψ̇2_rad_s]``;
X, Z is the inertial position of O (Ẋ = v_x cos θ + v_z sin θ, Ż = −v_x sin θ + v_z cos θ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from attitude_envs import validation
from attitude_envs.plants import slosh_kernels as kernels
from attitude_envs.plants.ops import NUMPY
from attitude_envs.plants.slosh_definition import N_STATE, P_IRIGID, P_J1, P_J2, P_ML1, P_ML2, P_MT, P_SZ, define

IX, IZ, ITH, IPSI1, IPSI2, IVX, IVZ, IOM, IDPSI1, IDPSI2 = range(N_STATE)

# Navabi & Davoodi, Table 3 prints the lengths 0.05, 0.6, 0.9, 0.2, 0.1 m, but our copy lost
# which symbol each belongs to. Each mapping assigns them to (a0, a1, a2, l1, l2); mapping
# "i" (the symbol-grouped order, l1 > l2) is the default. They are FuelSlosh-v0's presets
# ``navabi-fill-i`` … ``navabi-fill-iv`` (:mod:`attitude_envs.presets.navabi_slosh`).
FILL_PRESETS: dict[str, tuple[float, float, float, float, float]] = {
    "i": (0.05, 0.6, 0.9, 0.2, 0.1),
    "ii": (0.05, 0.6, 0.2, 0.9, 0.1),
    "iii": (0.05, 0.2, 0.1, 0.6, 0.9),
    "iv": (0.05, 0.9, 0.1, 0.6, 0.2),
}


@dataclass(frozen=True)
class SloshParams:
    """Physical parameters (Navabi & Davoodi, Table 3; defaults = the paper's, mapping (i)).

    Masses in kg, inertias in kg·m² (pitch axis), lengths in m, thrust in N, hinge
    damping in kg·m²/s (N·m·s/rad). ``b`` is the tank-centre position relative to the
    vehicle CM (positive forward; assumed: the paper's sign of b is ambiguous), ``d`` the vehicle-CM-to-gimbal distance.
    """

    mass_kg: float = 590.0
    inertia_kg_m2: float = 400.0
    fuel_mass_kg: float = 480.0
    fuel_inertia_kg_m2: float = 75.0
    slosh_mass_kg: tuple[float, float] = (50.0, 5.0)
    slosh_inertia_kg_m2: tuple[float, float] = (10.0, 1.0)
    hinge_m: tuple[float, float] = (0.6, 0.9)
    length_m: tuple[float, float] = (0.2, 0.1)
    fuel_offset_m: float = 0.05
    b_m: float = -0.6
    d_m: float = 1.5
    thrust_n: float = 2250.0
    damping_kg_m2_s: tuple[float, float] = (3.7, 0.5)
    # derived constants (filled in __post_init__)
    total_mass_kg: float = field(init=False, compare=False)
    ml: np.ndarray = field(init=False, repr=False, compare=False)
    J: np.ndarray = field(init=False, repr=False, compare=False)
    S_z: float = field(init=False, compare=False)
    I_rigid: float = field(init=False, compare=False)
    packed: np.ndarray = field(init=False, repr=False, compare=False)  # compiled kernels' constants

    def __post_init__(self) -> None:
        validation.positive("mass_kg", self.mass_kg)
        validation.positive("inertia_kg_m2", self.inertia_kg_m2)
        validation.nonnegative("fuel_mass_kg", self.fuel_mass_kg)
        validation.nonnegative("fuel_inertia_kg_m2", self.fuel_inertia_kg_m2)
        for name in ("slosh_mass_kg", "length_m"):
            arr = validation.finite_array(name, getattr(self, name), (2,))
            if np.any(arr <= 0):
                raise ValueError(f"{name} must have both entries in (0, inf), got {arr.tolist()}")
        for name in ("slosh_inertia_kg_m2", "damping_kg_m2_s"):
            arr = validation.finite_array(name, getattr(self, name), (2,))
            if np.any(arr < 0):
                raise ValueError(f"{name} must have both entries in [0, inf), got {arr.tolist()}")
        validation.finite_array("hinge_m", self.hinge_m, (2,))
        for name in ("fuel_offset_m", "b_m", "d_m"):
            validation.finite_array(name, getattr(self, name), ())
        validation.nonnegative("thrust_n", self.thrust_n)
        packed = np.array(define(NUMPY).packed_constants(self), dtype=float)
        packed.setflags(write=False)
        set_ = object.__setattr__
        set_(self, "total_mass_kg", float(packed[P_MT]))
        set_(self, "ml", packed[[P_ML1, P_ML2]].copy())
        set_(self, "J", packed[[P_J1, P_J2]].copy())
        set_(self, "S_z", float(packed[P_SZ]))
        set_(self, "I_rigid", float(packed[P_IRIGID]))
        set_(self, "packed", packed)

    @classmethod
    def from_fill_preset(cls, fill_preset: str = "i", **overrides) -> SloshParams:
        """The paper's parameters (Table 3) with the length mapping ``fill_preset``
        (``"i"`` … ``"iv"``, :data:`FILL_PRESETS`)."""
        validation.choice("fill_preset", fill_preset, set(FILL_PRESETS))
        a0, a1, a2, l1, l2 = FILL_PRESETS[fill_preset]
        base = {"fuel_offset_m": a0, "hinge_m": (a1, a2), "length_m": (l1, l2)}
        base.update(overrides)
        return cls(**base)

    def with_(self, **changes) -> SloshParams:
        """A copy with some fields changed (derived constants recomputed)."""
        return replace(self, **changes)

    @property
    def axial_acceleration_m_s2(self) -> float:
        """Nominal a_x = F / m_t (the paper's eq. 20), m/s²."""
        return self.thrust_n / self.total_mass_kg

    @property
    def lever_arm_m(self) -> float:
        """Thrust lever arm about O, ``b + d`` (m)."""
        return self.b_m + self.d_m

    def pitch_inertia(self, psi: np.ndarray) -> float:
        """I_θθ(ψ) about O, kg·m²."""
        return float(mass_matrix(self, psi)[2, 2])


def checked_state(y) -> np.ndarray:
    """``y`` as a contiguous float array of the full state's shape (10,); a ``ValueError``
    otherwise."""
    y = np.ascontiguousarray(y, dtype=float)
    if y.shape != (N_STATE,):
        raise ValueError(f"y must have shape ({N_STATE},), got {y.shape}")
    return y


def mass_matrix(p: SloshParams, psi: np.ndarray) -> np.ndarray:
    """The symmetric 5×5 mass matrix M(ψ) of ``s = [v_x, v_z, Ω, ψ̇1, ψ̇2]`` (eqs. 11–14);
    ``psi`` = [ψ1, ψ2] in rad."""
    M = np.empty((5, 5))
    kernels.mass_matrix_into(p.packed, float(psi[0]), float(psi[1]), M)
    return M


def forces(p: SloshParams, y: np.ndarray, delta_rad: float, moment_nm: float) -> np.ndarray:
    """Right-hand side f(s, ψ) + G(δ, M_c) of the mass-matrix form (eqs. 11–14), SI units."""
    out = np.empty(5)
    kernels.forces_into(p.packed, checked_state(y), float(delta_rad), float(moment_nm), out)
    return out


def derivative(p: SloshParams, y: np.ndarray, delta_rad: float, moment_nm: float) -> np.ndarray:
    """ẏ of the full state (10 entries) under gimbal angle δ (rad) and pitch moment (N·m)."""
    dy = np.empty(N_STATE)
    d = float(delta_rad)
    kernels.derivative_into(p.packed, checked_state(y), math.sin(d), math.cos(d), float(moment_nm), dy)
    return dy


def tank_accelerations(y: np.ndarray, dy: np.ndarray) -> tuple[float, float, float]:
    """``(a_x, a_z, Ω̇)`` of the tank centre (m/s², m/s², rad/s²):
    a_x = v̇_x + Ω v_z, a_z = v̇_z − Ω v_x (the paper's "new inputs" are a_z and Ω̇)."""
    om = y[IOM]
    return dy[IVX] + om * y[IVZ], dy[IVZ] - om * y[IVX], dy[IOM]


# ---------------------------------------------------------------------- invariants
def _bodies(p: SloshParams, y: np.ndarray):
    """(mass, body-frame position, body-frame velocity, inertia, absolute rate) of each body."""
    vx, vz, om = y[IVX], y[IVZ], y[IOM]
    out = [
        (p.mass_kg, (-p.b_m, 0.0), (vx, vz + p.b_m * om), p.inertia_kg_m2, om),
        (p.fuel_mass_kg, (p.fuel_offset_m, 0.0), (vx, vz - p.fuel_offset_m * om), p.fuel_inertia_kg_m2, om),
    ]
    for i in range(2):
        psi, dpsi = y[IPSI1 + i], y[IDPSI1 + i]
        m_i, l_i, a_i = p.slosh_mass_kg[i], p.length_m[i], p.hinge_m[i]
        w = om + dpsi
        pos = (a_i - l_i * math.cos(psi), l_i * math.sin(psi))
        vel = (vx + l_i * w * math.sin(psi), vz - a_i * om + l_i * w * math.cos(psi))
        out.append((m_i, pos, vel, p.slosh_inertia_kg_m2[i], w))
    return out


def kinetic_energy(p: SloshParams, y: np.ndarray) -> float:
    """Total kinetic energy T (J), the paper's eq. 5."""
    return sum(0.5 * m * (v[0] ** 2 + v[1] ** 2) + 0.5 * inertia * w**2 for m, _, v, inertia, w in _bodies(p, y))


def momenta(p: SloshParams, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Inertial linear momentum ``[P_X, P_Z]`` (kg·m/s) and angular momentum about the
    inertial origin in the sense of θ (kg·m²/s): ``H = Σ m (Z Ẋ − X Ż) + Σ I ω``."""
    th = y[ITH]
    ix = np.array([math.cos(th), -math.sin(th)])
    kz = np.array([math.sin(th), math.cos(th)])
    origin = y[IX : IZ + 1]
    P = np.zeros(2)
    H = 0.0
    for m, pos, vel, inertia, w in _bodies(p, y):
        r = origin + pos[0] * ix + pos[1] * kz
        v = vel[0] * ix + vel[1] * kz
        P += m * v
        H += m * (r[1] * v[0] - r[0] * v[1]) + inertia * w
    return P, H
