"""Run one episode of a policy on an env and summarize it."""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs.evaluation.policy import Policy
from attitude_envs.info import TRUTH, policy_view


def rollout(env, policy: Policy, seed: int | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """One episode; returns the episode cost ``J`` (sum of ``info["cost"]``), steps, how it
    ended and, for attitude envs, the true final error angle (deg) and peak wheel speed (rad/s);
    for an env with constraints, its violating steps (``violations``).

    The policy acts on :func:`attitude_envs.info.policy_view` of each info (no ground truth);
    the metrics come from ``info["truth"]``."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    total, steps = 0.0, 0
    peak_wheel = 0.0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += info["cost"]
        steps += 1
        state = info[TRUTH]["state"]
        wheel = state.get("wheel_speed_rad_s") if isinstance(state, dict) else None
        if wheel is not None:
            peak_wheel = max(peak_wheel, float(np.max(np.abs(wheel))))
    out = {
        "J": total,
        "steps": steps,
        "terminated": bool(terminated),
        "final_error_deg": info[TRUTH].get("error_angle_deg", float("nan")),
        "peak_wheel_speed_rad_s": peak_wheel,
    }
    if "violations" in info:  # an env with constraints: the episode's violating steps
        out["violations"] = int(info["violations"])
    return out
