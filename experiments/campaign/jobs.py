"""The jobs of a campaign: one per training run, one per episode, each a plain dict a worker runs
(:func:`experiments.campaign.episode.run_job`); J* jobs come from :mod:`experiments.optimum_table`."""

from __future__ import annotations

import copy
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from experiments.campaign.spec import Campaign, play_env

KEY_COLUMNS = ("env", "scenario", "fault", "agent", "train_seed", "seed")


def train_dir(out_dir: Path, env: str, agent: str, seed: int) -> Path:
    """Where the training run of ``agent`` on ``env`` with training seed ``seed`` writes."""
    return out_dir / "models" / env / agent / f"seed{seed}"


def trained_model(run_dir: Path, select: str) -> Path:
    """The snapshot a trained agent is evaluated with: ``best`` (lowest J on the training's
    own eval env, seeds 10000+, disjoint from the campaign's) when one was saved, else ``final``."""
    best = run_dir / "best" / "model.zip"
    return best if select == "best" and best.is_file() else run_dir / "final" / "model.zip"


def _backend_override(train: dict[str, Any]) -> dict[str, Any]:
    """``train.backend`` of an agent as a hyperparameter override (absent: the entry's own)."""
    return {"backend": train["backend"]} if "backend" in train else {}


def training_jobs(campaign: Campaign, out_dir: Path, skip_agents: Iterable[str] = ()) -> list[dict[str, Any]]:
    """One job per SB3 agent with ``train`` × env × training seed."""
    skip = set(skip_agents)
    jobs = []
    for env in campaign.envs:
        for agent in campaign.agents_for(env):
            if agent.train is None or agent.name in skip:
                continue
            t = agent.train
            if t.get("env", env.name) != env.name:  # trains on another entry only (train.env)
                continue
            env_id, kwargs = play_env(agent, env.id, env.kwargs)
            for seed in t["seeds"]:
                jobs.append(
                    {
                        "kind": "train",
                        "algo": t["algo"],
                        "env_id": env_id,
                        "env_kwargs": {**kwargs, **copy.deepcopy(dict(t.get("env_kwargs") or {}))},
                        "seed": int(seed),
                        "timesteps": t.get("timesteps"),
                        "overrides": {**dict(t.get("overrides") or {}), **_backend_override(t)},
                        "hyperparams_file": t.get("hyperparams_file"),
                        "checkpoint_freq": int(t.get("checkpoint_freq", 10_000)),
                        "eval_freq": int(t.get("eval_freq", 10_000)),
                        "eval_episodes": int(t.get("eval_episodes", 5)),
                        "out_dir": str(train_dir(out_dir, env.name, agent.name, seed)),
                    }
                )
    return jobs


def episode_jobs(campaign: Campaign, out_dir: Path, skip_agents: Iterable[str] = ()) -> list[dict[str, Any]]:
    """One job per env × scenario × fault × agent (× training seed) × seed, in key order. A job
    plays on the agent's env (``env_id``, ``env_kwargs``: :func:`~experiments.campaign.spec.play_env`)
    the episode of its cell (``cell_env_id``, ``cell_env_kwargs``: what J* is solved for)."""
    skip = set(skip_agents)
    jobs = []
    for env in campaign.envs:
        for scenario in env.scenarios:
            for fault_name, faults in env.faults.items():
                kwargs = {**env.kwargs, **dict(scenario.get("env_kwargs") or {})}
                if faults:
                    kwargs["faults"] = copy.deepcopy(faults)
                for agent in campaign.agents_for(env):
                    if agent.name in skip:
                        continue
                    play_id, play_kwargs = play_env(agent, env.id, kwargs)
                    source = campaign.trained_by(agent)  # itself, or the agent whose models it plays
                    train_seeds = source.train["seeds"] if source is not None else [None]
                    for tseed in train_seeds:
                        spec = dict(agent.spec)
                        if tseed is not None:
                            run_dir = train_dir(out_dir, campaign.trained_on(agent, env), source.name, tseed)
                            spec["model"] = str(trained_model(run_dir, source.train.get("select", "best")))
                        for seed in campaign.seeds:
                            key = {
                                "env": env.name,
                                "scenario": scenario["name"],
                                "fault": fault_name,
                                "agent": agent.name,
                                "train_seed": tseed,
                                "seed": int(seed),
                            }
                            jobs.append(
                                {
                                    "kind": "episode",
                                    "key": key,
                                    "env_id": play_id,
                                    "env_kwargs": play_kwargs,
                                    "cell_env_id": env.id,  # the episode J* is solved for
                                    "cell_env_kwargs": kwargs,
                                    "options": dict(scenario.get("options") or {}),
                                    "policy": spec,
                                    "metrics": dict(campaign.metrics),
                                    "success_error_deg": campaign.success_error_deg,
                                    "success_state_fraction": campaign.success_state_fraction,
                                }
                            )
    return jobs


def key_of(row: dict[str, Any]) -> tuple:
    """An episode's key (:data:`KEY_COLUMNS`) as a tuple, from its job key or its result row."""
    return tuple(row.get(k) for k in KEY_COLUMNS)


def sort_key(key: tuple) -> tuple:
    """An order of episode keys with None (no training seed) after every number."""
    return tuple((v is None, v if v is not None else 0) if not isinstance(v, str) else (False, v) for v in key)
