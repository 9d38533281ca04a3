"""The measured full state that state-feedback baselines read from the env's ``info``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class MeasuredState:
    """Attitude ``q`` (scalar last), body rate ``ω`` (rad/s), wheel speeds ``Ω`` relative to
    the body (rad/s, tachometers) and the target attitude, as in ``info["state"]``."""

    attitude: np.ndarray
    rate_rad_s: np.ndarray
    wheel_speed_rad_s: np.ndarray
    target_attitude: np.ndarray

    @classmethod
    def from_info(cls, info: dict[str, Any]) -> MeasuredState:
        try:
            s = info["state"]
            return cls(
                np.asarray(s["attitude"], dtype=float),
                np.asarray(s["rate_rad_s"], dtype=float),
                np.asarray(s["wheel_speed_rad_s"], dtype=float),
                np.asarray(s["target_attitude"], dtype=float),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(
                "info must carry info['state'] with 'attitude', 'rate_rad_s', 'wheel_speed_rad_s' and "
                "'target_attitude' (ReactionWheel-v0 does)"
            ) from exc
