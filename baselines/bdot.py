"""B-dot magnetic detumbling, the standard magnetorquer baseline (Magnetorquer-v0).

``m = −(k/|b|) d(b̂)/dt`` with the body-frame field direction differentiated by finite
differences between control steps (a magnetometer-only law: the measured field
``info["measured"]["magnetic_field_body_t"]``, no rate measurement), the
dipole saturated direction-preservingly, the wheel torque zero. Default gain
``k = 2 n (1 + sin ξ_m) J_min`` (Avanzini & Giulietti, "Magnetic detumbling of a rigid
spacecraft", JGCD 35(4), 2012), n the orbital mean motion, ξ_m the inclination of the orbit
to the geomagnetic equator (the orbit inclination for the axial dipole), J_min the smallest
principal moment of inertia; units N·m·s.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.info import MEASURED


class BDotPolicy:
    """B-dot detumbling controller; ``gain_nms`` overrides the default ``k`` (N·m·s)."""

    name = "B-dot"

    def __init__(self, env, gain_nms: float | None = None) -> None:
        model = env.unwrapped.model
        j_min = float(np.linalg.eigvalsh(model.params.inertia_kg_m2)[0])
        default = 2.0 * model.orbital_rate_rad_s * (1.0 + abs(np.sin(model.inclination_rad))) * j_min
        self.gain_nms = validation.positive("gain_nms", default if gain_nms is None else gain_nms)
        self.max_dipole = model.params.max_dipole_am2
        self.dt = model.control_dt_s
        self._previous: np.ndarray | None = None

    def reset(self, seed: int | None = None) -> None:
        self._previous = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        b = np.asarray(info[MEASURED]["magnetic_field_body_t"], dtype=float)
        norm = float(np.linalg.norm(b))
        direction = b / norm
        if self._previous is None:
            self._previous = direction
            return np.zeros(4, dtype=np.float32)
        rate = (direction - self._previous) / self.dt
        self._previous = direction
        m = -self.gain_nms / norm * rate
        peak = float(np.max(np.abs(m)))
        if peak > self.max_dipole:
            m *= self.max_dipole / peak
        return np.concatenate([m / self.max_dipole, [0.0]]).astype(np.float32)
