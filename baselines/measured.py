"""The measured state a state-feedback controller may read: ``info["measured"]``.

Controllers see what a flight computer has (:mod:`attitude_envs.info`): the state built from
the env's sensor layer, never the ground truth in ``info["truth"]``. With sensors off the
measured state equals the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from attitude_envs.info import MEASURED


@dataclass(frozen=True)
class MeasuredState:
    """Measured attitude ``q`` (scalar last), body rate ``ω`` (rad/s), wheel speeds ``Ω``
    relative to the body (rad/s, tachometers) and the commanded target attitude, as in
    ``info["measured"]`` of ReactionWheel-v0 and AirBearing-v0."""

    attitude: np.ndarray
    rate_rad_s: np.ndarray
    wheel_speed_rad_s: np.ndarray
    target_attitude: np.ndarray

    @classmethod
    def from_info(cls, info: dict[str, Any]) -> MeasuredState:
        """From ``info["measured"]`` (the policy's view of the info: no truth needed)."""
        try:
            s = info[MEASURED]
            return cls(
                np.asarray(s["attitude"], dtype=float),
                np.asarray(s["rate_rad_s"], dtype=float),
                np.asarray(s["wheel_speed_rad_s"], dtype=float),
                np.asarray(s["target_attitude"], dtype=float),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(
                "info must carry info['measured'] with 'attitude', 'rate_rad_s', 'wheel_speed_rad_s' and "
                "'target_attitude' (ReactionWheel-v0 and AirBearing-v0 do)"
            ) from exc
