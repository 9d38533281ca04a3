"""Observation wrapper: agents see the MEKF's estimate instead of raw (or true) states."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.estimation.estimators import SampleGate, _mekf_params
from attitude_envs.estimation.mekf import AttitudeMEKF


class EstimatedAttitude(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replaces the first six observation entries ``[q_e,vec, ω]`` of ReactionWheel-v0 by
    those of the MEKF estimate (attitude ``q̂``, rate ``ω_m − b̂``); further entries
    (wheel momentum, wheel speeds, fault hints) pass through as measured.

    The wrapped env must have sensors on (``sensors={...}`` or a sensor fault); the filter
    uses the env's *nominal* sensor parameters unless ``filter_params`` overrides them
    (keys of :class:`AttitudeMEKF`). A star tracker slower than the loop (``period_s``)
    updates the filter only when its sample changes (:class:`SampleGate`).
    ``info["measured"]`` becomes the estimate (``attitude`` q̂, ``rate_rad_s`` ω_m − b̂;
    ``wheel_speed_rad_s`` and ``target_attitude`` as the env measured them), and ``info["estimate"]`` holds ``attitude``, ``gyro_bias_rad_s``,
    ``rate_rad_s`` and ``covariance`` (6×6, [δθ rad, δb rad/s]).
    """

    def __init__(self, env: gym.Env, filter_params: dict | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, filter_params=filter_params)
        gym.Wrapper.__init__(self, env)
        base = env.unwrapped
        sensors = getattr(base, "sensor_layer", None)
        if sensors is None or "star_tracker" not in sensors.channels or "gyro" not in sensors.channels:
            raise ValueError("EstimatedAttitude needs an env with gyro and star_tracker sensors (ReactionWheel-v0)")
        if not sensors.enabled:
            raise ValueError("EstimatedAttitude needs sensors on: pass sensors={'gyro': ..., 'star_tracker': ...}")
        params = _mekf_params(sensors, filter_params)
        self.filter = AttitudeMEKF(**params)
        # a star tracker slower than the loop repeats its sample: only new ones update
        self._star_gate = SampleGate()
        self._t = 0.0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.filter.reset(info["sensors"]["star_tracker"], info["sensors"]["gyro"])
        self._star_gate.reset(info["sensors"]["star_tracker"])
        self._t = info["time_s"]
        return self._estimated(obs, info), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if "sensors" in info:
            star = info["sensors"]["star_tracker"]
            self.filter.step(
                info["sensors"]["gyro"], star if self._star_gate.is_new(star) else None, info["time_s"] - self._t
            )
        self._t = info["time_s"]
        return self._estimated(obs, info), reward, terminated, truncated, info

    def _estimated(self, obs: np.ndarray, info: dict) -> np.ndarray:
        f = self.filter
        base = self.env.unwrapped
        measured = info["measured"]
        target = measured["target_attitude"]
        x = base.model.error_state(f.attitude, f.rate, np.zeros(base.model.params.n_wheels), target)
        info["estimate"] = {
            "attitude": f.attitude.copy(),
            "gyro_bias_rad_s": f.bias.copy(),
            "rate_rad_s": f.rate.copy(),
            "covariance": f.covariance.copy(),
        }
        info["measured"] = dict(measured, attitude=f.attitude.copy(), rate_rad_s=f.rate.copy())
        out = np.array(obs, dtype=np.float32)
        out[:6] = x[:6]
        return out
