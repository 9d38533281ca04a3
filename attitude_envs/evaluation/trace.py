"""Record one episode of a policy on an env as time series (the input of metrics and plots)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from attitude_envs.evaluation.policy import Policy
from attitude_envs.info import TRUTH, policy_view


@dataclass(frozen=True)
class EpisodeTrace:
    """Time series of one episode (ground truth); ``K`` steps, ``K + 1`` samples of the state.

    Sampled at the step boundaries (``t[0] = 0`` after reset): ``time_s`` (K+1), ``attitude``
    (K+1, 4, scalar last), ``target_attitude`` (K+1, 4), ``rate_rad_s`` (K+1, 3),
    ``wheel_speed_rad_s`` (K+1, N), ``error_angle_deg`` (K+1). Held over step k (between
    samples k and k+1): ``action`` (K, N, the policy's raw output, before the env's clip),
    ``commanded_nm`` and ``applied_nm`` (K, N, motor torques), ``cost`` (K).
    """

    time_s: np.ndarray
    attitude: np.ndarray
    target_attitude: np.ndarray
    rate_rad_s: np.ndarray
    wheel_speed_rad_s: np.ndarray
    error_angle_deg: np.ndarray
    action: np.ndarray
    commanded_nm: np.ndarray
    applied_nm: np.ndarray
    cost: np.ndarray
    terminated: bool
    max_wheel_torque_nm: float

    @property
    def steps(self) -> int:
        return len(self.cost)

    @property
    def dt_s(self) -> np.ndarray:
        """Length of each step, s (K)."""
        return np.diff(self.time_s)


def record_episode(env, policy: Policy, seed: int | None = None, options: dict[str, Any] | None = None) -> EpisodeTrace:
    """Run one episode of ``policy`` (``reset(seed)``, ``act(obs, info)``) on a ReactionWheel env.

    The policy acts on :func:`attitude_envs.info.policy_view` of each info (no ground truth);
    the trace records the truth (``info["truth"]``: true state, applied torques, error angle)."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    samples = [info[TRUTH]]
    times = [info["time_s"]]
    actions, commanded, applied, costs = [], [], [], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = np.asarray(policy.act(obs, policy_view(info)), dtype=float)
        obs, _, terminated, truncated, info = env.step(action)
        truth = info[TRUTH]
        actions.append(action)
        commanded.append(info["commanded"])
        applied.append(truth["applied"])
        costs.append(info["cost"])
        times.append(info["time_s"])
        samples.append(truth)

    def stack(key: str) -> np.ndarray:
        return np.array([s["state"][key] for s in samples])

    return EpisodeTrace(
        time_s=np.array(times),
        attitude=stack("attitude"),
        target_attitude=stack("target_attitude"),
        rate_rad_s=stack("rate_rad_s"),
        wheel_speed_rad_s=stack("wheel_speed_rad_s"),
        error_angle_deg=np.array([s["error_angle_deg"] for s in samples]),
        action=np.array(actions),
        commanded_nm=np.array(commanded),
        applied_nm=np.array(applied),
        cost=np.array(costs),
        terminated=bool(terminated),
        max_wheel_torque_nm=float(env.unwrapped.model.params.max_wheel_torque_nm),
    )
