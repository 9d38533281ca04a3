"""Run one episode of a policy on an env and summarize it."""

from __future__ import annotations

from typing import Any

import numpy as np


def rollout(env, policy, seed: int | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """One episode; returns the episode cost ``J`` (sum of ``info["cost"]``), steps, how it
    ended and, for attitude envs, the final error angle (deg) and peak wheel speed (rad/s)."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    total, steps = 0.0, 0
    peak_wheel = 0.0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        total += info["cost"]
        steps += 1
        wheel = info.get("state", {}).get("wheel_speed_rad_s") if isinstance(info.get("state"), dict) else None
        if wheel is not None:
            peak_wheel = max(peak_wheel, float(np.max(np.abs(wheel))))
    return {
        "J": total,
        "steps": steps,
        "terminated": bool(terminated),
        "final_error_deg": info.get("error_angle_deg", float("nan")),
        "peak_wheel_speed_rad_s": peak_wheel,
    }
