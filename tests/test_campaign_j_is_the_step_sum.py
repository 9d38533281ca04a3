"""The campaign's J of an episode is the sum of every step's cost, on every plant's path
(dropping the last step's cost in ``experiments/campaign/episode.py``'s generic
metrics passed the whole suite).

For each plant campaign of ``--config all``, the ``zero`` agent's first episode job of each cell
and the same episode on the learning task (``-v1``) the learned agents play it on runs through
the campaign's own worker (:func:`experiments.campaign.episode.run_job`: the wheel path
``episode_metrics`` for ReactionWheel and AirBearing, the generic path for FuelSlosh,
LinearSystem and Magnetorquer). An independent loop plays the same episode and sums
``info["cost"]`` of every step; the two J agree to rounding, and the last step's cost is far
above that rounding, so a J that leaves out a step (the first or the last) fails.
"""

from __future__ import annotations

import copy
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)
from attitude_envs.info import policy_view
from experiments.campaign.episode import run_job
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.spec import load_campaign
from experiments.policies import build_policy

PLANT_CAMPAIGNS = ("wheel", "air-bearing", "magnetorquer", "slosh", "linear")


def _cases() -> list[tuple[str, dict]]:
    cases = []
    for name in PLANT_CAMPAIGNS:
        jobs = episode_jobs(load_campaign(name), out_dir=Path("/nonexistent"))
        zero = next(j for j in jobs if j["key"]["agent"] == "zero" and j["key"]["seed"] == 1)
        cases.append((f"{name}-v0", zero))
        learned = next(j for j in jobs if j["env_id"].endswith("-v1") and j["key"]["seed"] == 1)
        task = copy.deepcopy(learned)  # the learned agents' env and episode, played by the zero policy
        task["policy"] = {"policy": "zero"}
        task["key"] = {**task["key"], "agent": "zero-on-v1"}
        cases.append((f"{name}-v1", task))
    return cases


CASES = _cases()


def _step_costs(job: dict) -> list[float]:
    env = gym.make(job["env_id"], **job["env_kwargs"])
    policy = build_policy(job["policy"], env)
    obs, info = env.reset(seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    policy.reset(job["key"]["seed"])
    costs, done = [], False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        costs.append(float(info["cost"]))
        done = terminated or truncated
    return costs


@pytest.mark.parametrize("job", [c[1] for c in CASES], ids=[c[0] for c in CASES])
def test_the_campaigns_j_is_the_sum_of_every_steps_cost(job):
    row = run_job(copy.deepcopy(job))
    costs = _step_costs(job)
    total = float(np.sum(costs))
    rounding = 4 * len(costs) * np.finfo(float).eps * float(np.sum(np.abs(costs)))  # a bound on summing's
    # the test can fail: leaving out the first or the last step moves J far beyond rounding
    assert min(abs(costs[0]), abs(costs[-1])) > 1e3 * rounding, (costs[0], costs[-1], total)
    assert abs(row["J"] - total) <= rounding, (
        f"{job['env_id']} seed {job['key']['seed']}: the campaign's J {row['J']!r} is not the sum of the "
        f"{len(costs)} steps' costs {total!r} (last step {costs[-1]!r})"
    )
