"""Earth's magnetic field along an orbit, tesla.

Models (``field_model`` of Magnetorquer-v0):

* ``"dipole"`` (default): the axial dipole of Sadigh et al. (2022) eq. (9), evaluated from the actual
  position: ``B = μ_e/r³ [3(m̂·r̂)r̂ − m̂]`` with ``m̂ = −z_ECI`` (dipole pointing to
  geographic south, so the equatorial field points north). In the LVLH frame of
  :mod:`attitude_envs.plants.orbit` this is ``μ_e/r³ [cos α sin i, −cos i, 2 sin α sin i]``
  (Wertz's form), α the argument of latitude.
* ``"dipole-printed"``: eq. (9) exactly as printed in the orbital frame,
  ``μ_e/r³ [cos α sin i, cos i, −2 sin α sin i]``. It differs from the physical dipole by
  the sign of the y and z components (a half-turn about x: the paper's orbital frame is
  not the LVLH frame its ω_oi = [0, −ω0, 0] implies). Kept for the as-printed reproduction.
* ``"igrf"``: IGRF-14 through the maintained ``ppigrf`` package (optional extra
  ``attitude-envs[igrf]``), for a given epoch. The Earth rotates under the orbit at
  ``EARTH_RATE_RAD_S`` from the Greenwich sidereal angle of the epoch. ``ppigrf`` re-reads its
  coefficient file on every call (~10 ms), so the field is tabulated along the orbit once
  per episode (one vectorized call) and interpolated linearly in ECI in between.

μ_e is not printed in the paper; 7.96e15 T·m³ (Wertz) is assumed.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

from attitude_envs import validation
from attitude_envs.plants import magnetorquer_kernels as kernels
from attitude_envs.plants.orbit import KeplerOrbit, OrbitState

DIPOLE_STRENGTH_T_M3 = 7.96e15  # Earth's dipole strength μ_e, T·m³ (Wertz)
EARTH_RATE_RAD_S = 7.2921150e-5
MODELS = ("dipole", "dipole-printed", "igrf")


def dipole_eci_t(position_m: np.ndarray, strength_t_m3: float = DIPOLE_STRENGTH_T_M3) -> np.ndarray:
    """Axial dipole field at an ECI position (m), tesla; ``m̂ = −z``."""
    out = np.empty(3)
    p = np.asarray(position_m, dtype=float)
    kernels.dipole_eci_into(float(p[0]), float(p[1]), float(p[2]), float(strength_t_m3), out)
    return out


def greenwich_sidereal_angle_rad(epoch: _dt.datetime) -> float:
    """GMST of a UTC epoch (IAU 1982 expression), rad."""
    j2000 = _dt.datetime(2000, 1, 1, 12, 0, 0)
    days = (epoch.replace(tzinfo=None) - j2000).total_seconds() / 86400.0
    centuries = days / 36525.0
    seconds = 67310.54841 + (876600 * 3600 + 8640184.812866) * centuries + 0.093104 * centuries**2
    return float(np.radians((seconds % 86400.0) / 240.0))


def igrf_ecef_t(position_ecef_m: np.ndarray, epoch: _dt.datetime) -> np.ndarray:
    """IGRF field (tesla, ECEF axes) at ECEF positions (…×3, m) via ``ppigrf.igrf_gc``."""
    try:
        import ppigrf  # optional: the igrf extra
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError("field_model='igrf' needs the optional package: pip install 'attitude-envs[igrf]'") from exc
    p = np.atleast_2d(position_ecef_m)
    r = np.linalg.norm(p, axis=1)
    colat = np.arccos(np.clip(p[:, 2] / r, -1.0, 1.0))
    lon = np.arctan2(p[:, 1], p[:, 0])
    br, bth, bph = ppigrf.igrf_gc(r / 1e3, np.degrees(colat), np.degrees(lon), epoch)
    br, bth, bph = (np.asarray(v, dtype=float).reshape(-1) for v in (br, bth, bph))
    st, ct, sp, cp = np.sin(colat), np.cos(colat), np.sin(lon), np.cos(lon)
    r_hat = np.column_stack([st * cp, st * sp, ct])
    th_hat = np.column_stack([ct * cp, ct * sp, -st])
    ph_hat = np.column_stack([-sp, cp, np.zeros_like(sp)])
    b = (br[:, None] * r_hat + bth[:, None] * th_hat + bph[:, None] * ph_hat) * 1e-9
    return b.reshape(np.shape(position_ecef_m))


class FieldModel:
    """Field in the orbital frame along ``orbit``: :meth:`orbital_t` (tesla)."""

    def __init__(
        self,
        model: str = "dipole",
        strength_t_m3: float = DIPOLE_STRENGTH_T_M3,
        epoch: str | _dt.datetime = "2020-01-01T00:00:00",
        igrf_step_s: float = 10.0,
    ) -> None:
        self.model = validation.choice("field_model", model, MODELS)
        self.strength = validation.positive("dipole_strength_t_m3", strength_t_m3)
        if isinstance(epoch, str):
            try:
                epoch = _dt.datetime.fromisoformat(epoch)
            except ValueError as exc:
                raise ValueError(f"field_epoch must be an ISO date-time string, got {epoch!r}") from exc
        if not isinstance(epoch, _dt.datetime):
            raise ValueError(f"field_epoch must be a datetime or ISO string, got {epoch!r}")
        if not _dt.datetime(1900, 1, 1) <= epoch.replace(tzinfo=None) <= _dt.datetime(2030, 1, 1):
            raise ValueError(f"field_epoch must be in [1900-01-01, 2030-01-01] (IGRF-14 validity), got {epoch}")
        self.epoch = epoch
        self.igrf_step_s = validation.positive("igrf_step_s", igrf_step_s)
        self._table_b: np.ndarray | None = None

    @property
    def code(self) -> int:
        """The model's code in the compiled field evaluator."""
        return kernels.FIELD_CODES[self.model]

    @property
    def table(self) -> np.ndarray:
        """The tabulated IGRF field (k × 3, ECI, T) at multiples of ``igrf_step_s`` since the
        episode start; a 2 × 3 dummy for the dipole models."""
        return self._table_b if self._table_b is not None else np.zeros((2, 3))

    def prepare(self, orbit: KeplerOrbit, duration_s: float) -> None:
        """Tabulate the IGRF field along the orbit for one episode (no-op for the dipoles)."""
        if self.model != "igrf":
            return
        n = int(np.ceil(duration_s / self.igrf_step_s)) + 2
        times = np.arange(n) * self.igrf_step_s
        gmst0 = greenwich_sidereal_angle_rad(self.epoch)
        pos_eci = np.array([orbit.state_at(float(t)).position_m for t in times])
        angles = gmst0 + EARTH_RATE_RAD_S * times
        c, s = np.cos(angles), np.sin(angles)
        # ECEF = R_z(−θ) ECI
        ecef = np.column_stack(
            [c * pos_eci[:, 0] + s * pos_eci[:, 1], -s * pos_eci[:, 0] + c * pos_eci[:, 1], pos_eci[:, 2]]
        )
        b_ecef = igrf_ecef_t(ecef, self.epoch)
        b_eci = np.column_stack(
            [c * b_ecef[:, 0] - s * b_ecef[:, 1], s * b_ecef[:, 0] + c * b_ecef[:, 1], b_ecef[:, 2]]
        )
        self._table_b = np.ascontiguousarray(b_eci)

    def eci_t(self, t_s: float, state: OrbitState) -> np.ndarray:
        """Field in ECI axes, tesla (physical models only)."""
        if self.model == "igrf" and self._table_b is None:
            raise RuntimeError("FieldModel.prepare(orbit, duration) must run before igrf lookups")
        if self.model == "dipole-printed":
            raise ValueError("field_model 'dipole-printed' is defined in the orbital frame only")
        identity = _orbit_vector(state, np.eye(3))
        return self._evaluate(t_s, identity, 0.0)

    def orbital_t(self, t_s: float, state: OrbitState, inclination_rad: float) -> np.ndarray:
        """Field in the orbital (LVLH) frame, tesla."""
        if self.model == "igrf" and self._table_b is None:
            raise RuntimeError("FieldModel.prepare(orbit, duration) must run before igrf lookups")
        return self._evaluate(t_s, _orbit_vector(state, state.eci_from_orbital), inclination_rad)

    def _evaluate(self, t_s: float, orbit_vector: np.ndarray, inclination_rad: float) -> np.ndarray:
        out = np.empty(3)
        kernels.field_orbital_into(
            float(t_s),
            orbit_vector,
            0,
            self.code,
            self.strength,
            float(inclination_rad),
            self.table,
            self.igrf_step_s,
            out,
            0,
        )
        return out


def _orbit_vector(state: OrbitState, frame: np.ndarray) -> np.ndarray:
    """``state`` in the compiled layout (``kernels.OS_*``) with ``frame`` as eci_from_orbital."""
    v = np.empty(kernels.ORBIT_STATE_SIZE)
    v[kernels.OS_POS : kernels.OS_POS + 3] = state.position_m
    v[kernels.OS_VEL : kernels.OS_VEL + 3] = state.velocity_m_s
    v[kernels.OS_R] = state.radius_m
    v[kernels.OS_U] = state.argument_of_latitude_rad
    v[kernels.OS_RATE] = state.rate_rad_s
    v[kernels.OS_RATE_DOT] = state.rate_dot_rad_s2
    v[kernels.OS_FRAME :] = np.asarray(frame, dtype=float).reshape(9)
    return v
