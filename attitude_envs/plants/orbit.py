"""Keplerian orbit (two-body, no perturbations) and the orbital (LVLH) frame.

Sadigh, Kashaninia & Dehghan (2022), Table 1, give the orbit by its apogee and perigee
altitudes (1250 km, 311 km) and inclination 69.5°; with a spherical Earth of radius 6371 km
the printed orbital rate ω0 = 10.439e-4 rad/s is the mean motion sqrt(μ/a³) at a = 7151.5 km.

Frames. ECI: x to the ascending-node reference direction (RAAN measured from it), z to
the north pole. The orbital frame is the LVLH frame of the paper's eq. (3): ``x`` completes
the triad (along-track for a circular orbit), ``y = −h/|h|`` (orbit anti-normal), ``z =
−r/|r|`` (nadir). It rotates about ``y`` with the true-anomaly rate, so its angular velocity
in its own axes is ``ω_oi = [0, −ν̇, 0]`` (eq. 3 with ν̇ = ω0 on a circular orbit).

``model="keplerian"`` propagates the ellipse (Kepler's equation by Newton iteration);
``model="circular"`` is the paper's approximation: radius ``a``, argument of latitude
``α = α0 + ω0 t``, constant rate ω0 (the paper's eq. 3 takes ω0 constant).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude_envs import validation
from attitude_envs.plants import magnetorquer_kernels as kernels

MU_EARTH_M3_S2 = 3.986004418e14
EARTH_RADIUS_M = 6371.0e3  # the radius that reproduces Sadigh et al. 2022's printed ω0 (Table 1)
MODELS = ("keplerian", "circular")


@dataclass(frozen=True)
class OrbitState:
    """Where the spacecraft is at one time (SI units, ECI axes)."""

    position_m: np.ndarray
    velocity_m_s: np.ndarray
    radius_m: float
    argument_of_latitude_rad: float
    rate_rad_s: float  # ν̇: the orbital frame's rotation rate about −y
    rate_dot_rad_s2: float  # ν̈
    eci_from_orbital: np.ndarray  # 3×3, columns are the orbital axes in ECI


class KeplerOrbit:
    """A two-body orbit from its elements; angles in degrees, altitudes in km.

    ``mean_anomaly_deg`` is the mean anomaly at t = 0 (the env may draw it from its seed).
    Raises ``ValueError`` for eccentricity outside [0, 1), inclination outside [0, 180], a
    perigee below the Earth's surface or an unknown ``model``.
    """

    def __init__(
        self,
        semi_major_axis_m: float,
        eccentricity: float,
        inclination_deg: float,
        raan_deg: float = 0.0,
        arg_perigee_deg: float = 0.0,
        mean_anomaly_deg: float = 0.0,
        model: str = "keplerian",
        mu_m3_s2: float = MU_EARTH_M3_S2,
    ) -> None:
        self.a = validation.positive("semi_major_axis_m", semi_major_axis_m)
        self.e = validation.in_range("eccentricity", eccentricity, 0.0, 1.0, open_high=True)
        self.inclination_rad = np.radians(validation.in_range("inclination_deg", inclination_deg, 0.0, 180.0))
        self.raan_rad = np.radians(validation.finite_array("raan_deg", raan_deg, ()))
        self.arg_perigee_rad = np.radians(validation.finite_array("arg_perigee_deg", arg_perigee_deg, ()))
        self.mean_anomaly0_rad = np.radians(validation.finite_array("mean_anomaly_deg", mean_anomaly_deg, ()))
        self.model = validation.choice("orbit.model", model, MODELS)
        self.mu = validation.positive("mu_m3_s2", mu_m3_s2)
        if self.a * (1.0 - self.e) <= EARTH_RADIUS_M * 0.5:
            raise ValueError(f"perigee radius {self.a * (1 - self.e):.0f} m is inside the Earth")
        self.mean_motion_rad_s = float(np.sqrt(self.mu / self.a**3))
        self._p = self.a * (1.0 - self.e**2)
        self._h = float(np.sqrt(self.mu * self._p))
        ci, si = np.cos(self.inclination_rad), np.sin(self.inclination_rad)
        co, so = np.cos(self.raan_rad), np.sin(self.raan_rad)
        # perifocal → ECI for node line (ascending node) and orbit normal; argument of
        # latitude u rotates within the plane: r̂ = n̂ cos u + m̂ sin u.
        self._node = np.array([co, so, 0.0])
        self._in_plane = np.array([-so * ci, co * ci, si])
        self._normal = np.array([so * si, -co * si, ci])
        #: the elements in the layout of the compiled propagator (one implementation)
        self.packed = kernels.pack_orbit(
            self.model == "circular",
            self.a,
            self.e,
            float(self.mean_anomaly0_rad),
            self.mean_motion_rad_s,
            self._p,
            self._h,
            self.mu,
            self._node,
            self._in_plane,
            self._normal,
            float(self.arg_perigee_rad),
        )

    @classmethod
    def from_altitudes(
        cls,
        apogee_altitude_km: float,
        perigee_altitude_km: float,
        inclination_deg: float,
        earth_radius_km: float = EARTH_RADIUS_M / 1e3,
        **kwargs,
    ) -> KeplerOrbit:
        """From apogee/perigee altitudes above a spherical Earth, km (as Sadigh et al. 2022, Table 1)."""
        apogee = validation.number("apogee_altitude_km", apogee_altitude_km)
        perigee = validation.number("perigee_altitude_km", perigee_altitude_km)
        ra = (validation.positive("earth_radius_km", earth_radius_km) + apogee) * 1e3
        rp = (earth_radius_km + perigee) * 1e3
        if not (np.isfinite(ra) and np.isfinite(rp)) or rp <= earth_radius_km * 1e3 or ra < rp:
            raise ValueError(
                "apogee_altitude_km and perigee_altitude_km must be positive with apogee >= perigee, "
                f"got {apogee_altitude_km!r}, {perigee_altitude_km!r}"
            )
        return cls(0.5 * (ra + rp), (ra - rp) / (ra + rp), inclination_deg, **kwargs)

    @property
    def period_s(self) -> float:
        return 2.0 * np.pi / self.mean_motion_rad_s

    def true_anomaly_rad(self, t_s: float) -> float:
        """ν(t) from Kepler's equation M = E − e sin E (Newton, |ΔE| < 1e-13)."""
        return float(kernels.true_anomaly(self.packed, 0, float(t_s)))

    def state_at(self, t_s: float) -> OrbitState:
        """Position, velocity, frame and rates at ``t_s`` seconds after epoch."""
        out = np.empty(kernels.ORBIT_STATE_SIZE)
        kernels.orbit_state_into(self.packed, 0, float(t_s), out, 0)
        return OrbitState(
            out[kernels.OS_POS : kernels.OS_POS + 3],
            out[kernels.OS_VEL : kernels.OS_VEL + 3],
            float(out[kernels.OS_R]),
            float(out[kernels.OS_U]),
            float(out[kernels.OS_RATE]),
            float(out[kernels.OS_RATE_DOT]),
            out[kernels.OS_FRAME :].reshape(3, 3),
        )
