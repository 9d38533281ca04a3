"""The benchmark's task: a campaign agent's (the env it trains on, the cell episodes it is
scored on, their J*), its PPO recipe, and the progress lines every section prints."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
ENV_ID = "attitude_envs/AirBearing-v1"
#: the campaign whose ``ppo`` agent trains on an env id (task kwargs, cell episodes, J*)
CAMPAIGNS = {"attitude_envs/AirBearing-v1": "air-bearing", "attitude_envs/LinearSystem-v1": "linear"}
#: the J / J* a fused run's evaluation must reach (``time_to_target``)
J_STAR_TARGET = 1.05


@dataclass
class Task:
    """A campaign agent's task: the env it trains and plays on, the cell episodes it is scored
    on (one campaign episode job per seed) and their J* (from the shipped table)."""

    env_id: str
    env_kwargs: dict[str, Any]
    campaign: str
    cell: tuple[str, str, str]
    jobs: list[dict[str, Any]]
    j_star: dict[int, float]

    @property
    def seeds(self) -> list[int]:
        return [int(j["key"]["seed"]) for j in self.jobs]


def campaign_task(env_id: str, agent: str = "ppo") -> Task:
    """The task of ``agent`` in the campaign that trains it on ``env_id`` (:data:`CAMPAIGNS`):
    its first env's first scenario without faults; kwargs ``{}`` and no episodes for an env id
    no campaign trains on."""
    from experiments.campaign.jobs import episode_jobs
    from experiments.campaign.spec import load_campaign
    from experiments.optimum_table import table_value

    name = CAMPAIGNS.get(env_id)
    if name is None:
        return Task(env_id, {}, "", ("", "", ""), [], {})
    campaign = load_campaign(name)
    others = [a.name for a in campaign.agents if a.name != agent]
    jobs = episode_jobs(campaign, ROOT / "results" / "unused", skip_agents=others)
    first = jobs[0]["key"]
    cell = (first["env"], first["scenario"], "none")
    jobs = [
        j
        for j in jobs
        if (j["key"]["env"], j["key"]["scenario"], j["key"]["fault"]) == cell
        and j["key"]["train_seed"] == first["train_seed"]
    ]
    if jobs[0]["env_id"] != env_id:
        raise ValueError(f"campaign {name!r}: agent {agent!r} plays {jobs[0]['env_id']}, not {env_id}")
    j_star = {}
    for j in jobs:
        value = table_value(j["cell_env_id"], j["cell_env_kwargs"], j["key"]["seed"], j.get("options") or None)
        j_star[int(j["key"]["seed"])] = float("nan") if value is None else value
    return Task(env_id, dict(jobs[0]["env_kwargs"]), name, cell, jobs, j_star)


def recipe(env_id: str) -> dict[str, Any]:
    from experiments.training.hyperparams import load_hyperparams

    return load_hyperparams("ppo", env_id, None, {"backend": "jax"})


def say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)
