"""Running one campaign job in a worker: a training run, a J* solve or an episode and its metrics.

Every env says how it is measured (:mod:`attitude_envs.evaluation.success`): envs with
``wheel_trace`` record an :class:`~attitude_envs.evaluation.trace.EpisodeTrace` and take the full
:func:`~attitude_envs.evaluation.metrics.episode_metrics` plus the recovery time after the
earliest fault onset; the others J, the step count and the true state norms. Success: J finite,
the episode not terminated, and the env's ``success_metric`` met at the campaign's threshold.
An env with constraints (its info has ``violations``: ConstrainedSlew-v0) adds
:func:`attitude_envs.constraints.episode_summary`: the violating steps, those per constraint and the
least cone margin.
"""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the env ids, also in pool and Ray workers)
from attitude_envs.constraints import episode_summary
from attitude_envs.evaluation.metrics import episode_metrics, settling_time_s
from attitude_envs.evaluation.success import SuccessMetric, true_state_norm
from attitude_envs.evaluation.trace import episode_trace, play
from attitude_envs.info import fault_onsets_s, policy_view
from experiments.campaign.spec import SUCCESS_KEYS, Campaign
from experiments.optimum_table import solve_job
from experiments.policies import build_policy

#: what success needs besides the env's metric (the report's wording)
ALSO_REQUIRED = "not terminated, J finite"

_CACHE: dict[str, tuple[Any, Any]] = {}


def run_job(job: dict[str, Any]) -> dict[str, Any]:
    """Run one job (``kind`` ``train``, ``optimum`` or ``episode``) in this process; returns its result row."""
    if job["kind"] == "optimum":  # J* of one episode key (experiments.optimum_table)
        return solve_job(job)
    if job["kind"] == "train" or job.get("policy", {}).get("policy") == "sb3":
        import torch  # only for jobs that need it: importing torch costs seconds per worker

        torch.set_num_threads(1)  # episodes and small networks: threads only contend
    if job["kind"] == "train":
        return _run_training(job)
    return _run_episode(job)


def _run_training(job: dict[str, Any]) -> dict[str, Any]:
    # optional: the sb3 extra (importing stable-baselines3 and torch costs seconds; episode workers skip it)
    from experiments.training.run_dir import latest_checkpoint
    from experiments.training.training import train

    out_dir = Path(job["out_dir"])
    final = out_dir / "final" / "model.zip"
    if final.is_file():
        return {"kind": "train", "out_dir": str(out_dir), "status": "done-before"}
    result = train(
        job["algo"],
        job["env_id"],
        out_dir,
        env_kwargs=job["env_kwargs"],
        seed=job["seed"],
        hyperparams_file=job["hyperparams_file"],
        overrides=job["overrides"],
        total_timesteps=job["timesteps"],
        checkpoint_freq=job["checkpoint_freq"],
        eval_freq=job["eval_freq"],
        eval_episodes=job.get("eval_episodes", 5),  # absent from jobs listed before the key existed
        resume=latest_checkpoint(out_dir) is not None,
        progress=job.get("progress", False),
    )
    return {
        "kind": "train",
        "out_dir": str(out_dir),
        "status": "trained",
        "timesteps": result.timesteps,
        "wall_time_s": result.wall_time_s,
        "J_eval": (result.last_eval or {}).get("J_mean"),
    }


def _env_and_policy(job: dict[str, Any]):
    group = json.dumps(
        [job["env_id"], job["env_kwargs"], job["policy"], job["key"]["agent"]], sort_keys=True, default=str
    )
    if group not in _CACHE:
        for old in list(_CACHE)[:-3]:
            _CACHE.pop(old)[0].close()
        env = gym.make(job["env_id"], **job["env_kwargs"])
        _CACHE[group] = (env, build_policy(job["policy"], env, name=job["key"]["agent"]))
    return _CACHE[group]


def _run_episode(job: dict[str, Any]) -> dict[str, Any]:
    env, policy = _env_and_policy(job)
    key = job["key"]
    start = time.perf_counter()
    if env.unwrapped.wheel_trace:
        metrics = _wheel_metrics(env, policy, job)
    else:
        metrics = _generic_metrics(env, policy, job)
    metrics["episode_wall_s"] = time.perf_counter() - start
    metrics["conditions"] = env.unwrapped.conditions.name  # lab, flight or custom (attitude_envs.conditions)
    return {**key, **{k: (v.item() if isinstance(v, np.generic) else v) for k, v in metrics.items()}}


def _threshold(job: dict[str, Any], metric: SuccessMetric) -> float:
    """The job's threshold for ``metric`` (its campaign key, :data:`SUCCESS_KEYS`), else the metric's default."""
    return float(job.get(SUCCESS_KEYS.get(metric.name, ""), metric.threshold))


def _wheel_metrics(env, policy, job: dict[str, Any]) -> dict[str, Any]:
    """A wheel env's episode: :func:`episode_metrics` of its trace, the success metric's
    measurements, success, and ``recovery_time_s`` (settling after the earliest realized fault onset, s)."""
    infos, actions, terminated = play(env, policy, job["key"]["seed"], copy.deepcopy(job["options"]) or None)
    trace = episode_trace(env, infos, actions, terminated)
    m = episode_metrics(trace, **job["metrics"])
    metric: SuccessMetric = env.unwrapped.success_metric
    first, last = infos[0], infos[-1]
    m |= metric.measurements(first, last)
    m |= episode_summary(infos)
    met = metric.succeeded(first, last, _threshold(job, metric))
    m["success"] = bool(np.isfinite(m["J"]) and not trace.terminated and met)
    onsets = fault_onsets_s(first)
    if onsets:
        onset = min(onsets)
        band = float(job["metrics"].get("settling_band_deg", 1.0))
        after = trace.time_s >= onset
        t_settle = settling_time_s(trace.time_s[after], trace.error_angle_deg[after], band) if after.any() else np.nan
        m["recovery_time_s"] = float(t_settle - onset) if np.isfinite(t_settle) else float("nan")
    else:
        m["recovery_time_s"] = float("nan")
    return m


def _generic_metrics(env, policy, job: dict[str, Any]) -> dict[str, Any]:
    """Any env: J, the step count, the success metric's measurements, the true state norms at
    the start and the end (:func:`true_state_norm`) and success."""
    obs, info = env.reset(seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    policy.reset(job["key"]["seed"])
    first = info
    constrained = [info] if "violations" in info else None
    total, steps, terminated, truncated = 0.0, 0, False, False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += float(info["cost"])
        steps += 1
        if constrained is not None:
            constrained.append(info)
    metric: SuccessMetric = env.unwrapped.success_metric
    met = metric.succeeded(first, info, _threshold(job, metric))
    m = {"J": total, "steps": steps, "terminated": bool(terminated), **metric.measurements(first, info)}
    m |= {"initial_state_norm": true_state_norm(first), "final_state_norm": true_state_norm(info)}
    m |= {"success": bool(np.isfinite(total) and not terminated and met), "recovery_time_s": float("nan")}
    return m | episode_summary(constrained or [])


def success_criterion(env_id: str, env_kwargs: dict[str, Any], campaign: Campaign) -> str:
    """The success criterion of an episode of ``env_id`` at ``campaign``'s threshold, as the report states it."""
    env = gym.make(env_id, **env_kwargs)
    try:
        metric: SuccessMetric = env.unwrapped.success_metric
    finally:
        env.close()
    return f"{metric.describe(campaign.success_threshold(metric))}, {ALSO_REQUIRED}"
