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


def play(env, policy: Policy, seed: int | None = None, options: dict[str, Any] | None = None):
    """Run one episode of ``policy`` (``reset(seed)``, ``act(obs, policy_view(info))``: no ground
    truth reaches it); returns ``(infos, actions, terminated)``: the reset's info and every
    step's (K + 1), the policy's raw actions (K) and whether the episode terminated."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    infos, actions = [info], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = np.asarray(policy.act(obs, policy_view(info)), dtype=float)
        obs, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        actions.append(action)
    return infos, actions, bool(terminated)


def record_episode(env, policy: Policy, seed: int | None = None, options: dict[str, Any] | None = None) -> EpisodeTrace:
    """Run one episode of ``policy`` (``reset(seed)``, ``act(obs, info)``) on a ReactionWheel env.

    The policy acts on :func:`attitude_envs.info.policy_view` of each info (no ground truth);
    the trace records the truth (``info["truth"]``: true state, applied torques, error angle)."""
    return episode_trace(env, *play(env, policy, seed, options))


def episode_trace(env, infos: list[dict[str, Any]], actions: list[np.ndarray], terminated: bool) -> EpisodeTrace:
    """The :class:`EpisodeTrace` of an episode :func:`play` ran on a ReactionWheel env (its
    ``infos``, ``actions`` and ``terminated``), for callers that also read the infos."""
    samples = [i[TRUTH] for i in infos]
    times = [i["time_s"] for i in infos]
    commanded = [i["commanded"] for i in infos[1:]]
    applied = [i[TRUTH]["applied"] for i in infos[1:]]
    costs = [i["cost"] for i in infos[1:]]

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
        terminated=terminated,
        max_wheel_torque_nm=float(env.unwrapped.model.params.max_wheel_torque_nm),
    )


@dataclass(frozen=True)
class StateTrace:
    """Time series of one episode of any env (ground truth); ``K`` steps.

    ``time_s`` (K+1, s); ``state``: each channel of ``info["truth"]["state"]`` (the array itself
    for an env whose state is one array, under ``"state"``) as (K+1, n) in the env's units;
    ``error_angle_deg`` (K+1) for attitude envs, else None; ``applied`` (K, m: the actuator
    outputs after faults, the env's units); ``cost`` (K, the env's J increments)."""

    time_s: np.ndarray
    state: dict[str, np.ndarray]
    error_angle_deg: np.ndarray | None
    applied: np.ndarray
    cost: np.ndarray


def _channels(state: Any) -> dict[str, np.ndarray]:
    if isinstance(state, dict):
        return {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in state.items()}
    return {"state": np.atleast_1d(np.asarray(state, dtype=float))}


def record_state_trace(
    env, policy: Policy, seed: int | None = None, options: dict[str, Any] | None = None
) -> StateTrace:
    """Run one episode of ``policy`` on any env (it acts on :func:`~attitude_envs.info.policy_view`
    of each info) and record the truth: state channels, error angle, applied actuation, cost."""
    infos, _, _ = play(env, policy, seed, options)
    samples = [_channels(i[TRUTH]["state"]) for i in infos]
    times = [i["time_s"] for i in infos]
    errors = [i[TRUTH].get("error_angle_deg") for i in infos]
    applied = [np.atleast_1d(np.asarray(i[TRUTH]["applied"], dtype=float)) for i in infos[1:]]
    costs = [i["cost"] for i in infos[1:]]
    return StateTrace(
        time_s=np.array(times, dtype=float),
        state={k: np.array([s[k] for s in samples]) for k in samples[0]},
        error_angle_deg=None if errors[0] is None else np.array(errors, dtype=float),
        applied=np.array(applied),
        cost=np.array(costs, dtype=float),
    )
