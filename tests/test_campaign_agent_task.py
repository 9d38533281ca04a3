"""An agent's own task on a campaign cell's episodes (``agents[i].env_id`` / ``env_kwargs``):
checked at load and before any episode runs, played on the agent's env, scored against the
cell's J* (solved for the cell's kwargs, not the agent's)."""

from __future__ import annotations

import copy

import pytest

from experiments.campaign import load_campaign, run_campaign
from experiments.campaign.jobs import episode_jobs, training_jobs
from experiments.campaign.run import prepare_campaign
from experiments.campaign.spec import play_env
from experiments.optimum_table import episode_specs

CELL = {
    "name": "task",
    "seeds": 2,
    "envs": [
        {
            "name": "ab",
            "id": "attitude_envs/AirBearing-v0",
            "kwargs": {"preset": "air-bearing-85kg", "episode_duration_s": 3.0},
            "faults": {"none": [], "yaw-out": [{"kind": "outage", "target": "actuator", "index": 2, "onset_s": 1.0}]},
        }
    ],
    "agents": [
        {"name": "lqr", "policy": "lqr", "params": {"discretization": "zoh"}},
        {"name": "lqr-slow", "policy": "lqr", "params": {"discretization": "zoh"}, "env_kwargs": {"control_dt_s": 0.5}},
        {"name": "zero-v1", "policy": "zero", "env_id": "attitude_envs/AirBearing-v1"},
    ],
    "optimum": {"solve": False},
}


def _with_agent(agent: dict) -> dict:
    config = copy.deepcopy(CELL)
    config["agents"].append(agent)
    return config


def test_an_agent_plays_the_cells_episodes_on_its_own_env_and_j_star_keys_stay_the_cells(tmp_path):
    campaign = load_campaign(CELL)
    jobs = episode_jobs(campaign, tmp_path)
    by_agent = {j["key"]["agent"]: j for j in jobs if j["key"]["fault"] == "yaw-out" and j["key"]["seed"] == 0}
    assert by_agent["lqr"]["env_id"] == "attitude_envs/AirBearing-v0"
    assert by_agent["lqr-slow"]["env_kwargs"]["control_dt_s"] == 0.5
    assert by_agent["zero-v1"]["env_id"] == "attitude_envs/AirBearing-v1"
    assert "control_dt_s" not in by_agent["zero-v1"]["env_kwargs"]  # the v1 default applies
    assert by_agent["zero-v1"]["env_kwargs"]["faults"] == CELL["envs"][0]["faults"]["yaw-out"]
    # one J* key per episode whatever the agents play it on: the cell's kwargs
    specs = episode_specs(jobs)
    assert len(specs) == 2 * 2
    assert all(s["env_id"] == "attitude_envs/AirBearing-v0" and "control_dt_s" not in s["env_kwargs"] for s in specs)


def test_agents_at_other_periods_score_the_same_integral(tmp_path):
    result = run_campaign(CELL, tmp_path / "out", workers=1)
    rows = {(r["agent"], r["fault"], r["seed"]): r for r in result.rows}
    assert {r["steps"] for r in result.rows if r["agent"] == "lqr-slow"} == {6}  # 3 s at 0.5 s
    assert {r["steps"] for r in result.rows if r["agent"] == "lqr"} == {300}
    for fault in ("none", "yaw-out"):
        for seed in (0, 1):
            # free drift is the same episode and the same integral at 0.01 s and at v1's 0.5 s
            zero_fine = run_zero_fine(seed, fault)
            assert rows[("zero-v1", fault, seed)]["J"] == pytest.approx(zero_fine, rel=1e-9)


def run_zero_fine(seed: int, fault: str) -> float:
    import gymnasium as gym
    import numpy as np

    kwargs = dict(CELL["envs"][0]["kwargs"])
    if CELL["envs"][0]["faults"][fault]:
        kwargs["faults"] = CELL["envs"][0]["faults"][fault]
    env = gym.make("attitude_envs/AirBearing-v0", **kwargs)
    env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        _, _, te, tr, info = env.step(np.zeros(env.action_space.shape, np.float32))
        total += info["cost"]
        done = te or tr
    return total


def test_a_trained_agent_trains_on_its_own_env_with_its_own_entry(tmp_path):
    config = _with_agent(
        {
            "name": "ppo",
            "policy": "sb3",
            "env_id": "attitude_envs/AirBearing-v1",
            "train": {"algo": "ppo", "seeds": [0]},
        }
    )
    (job,) = training_jobs(load_campaign(config), tmp_path)
    assert job["env_id"] == "attitude_envs/AirBearing-v1" and "control_dt_s" not in job["env_kwargs"]
    assert job["env_kwargs"]["episode_duration_s"] == 3.0


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        (
            {"name": "x", "policy": "zero", "env_kwargs": {"episode_duration_s": 9.0}},
            r"agents\[3\] \(x\)\.env_kwargs may set only the task keywords of env 'ab' \['control_dt_s', 'termination_cost'\]",
        ),
        (
            {"name": "x", "policy": "zero", "env_id": "attitude_envs/ReactionWheel-v1"},
            r"agents\[3\] \(x\)\.env_id 'attitude_envs/ReactionWheel-v1' is not a version of env 'ab'",
        ),
        ({"name": "x", "policy": "zero", "env_id": "attitude_envs/Nope-v1"}, r"agents\[3\]\.env_id: unknown env id"),
    ],
)
def test_a_task_that_is_not_the_cells_episodes_is_refused_at_load(agent, message):
    with pytest.raises(ValueError, match=message):
        load_campaign(_with_agent(agent))


def test_an_agent_env_whose_episodes_differ_is_refused_before_anything_runs(tmp_path):
    """FuelSlosh-v1 draws random starts and runs 100 s; a cell on the paper's fixed start
    and 20 s is another episode: refused with the reason, nothing written."""
    config = {
        "name": "differ",
        "seeds": 1,
        "envs": [{"name": "fs", "id": "attitude_envs/FuelSlosh-v0", "kwargs": {"episode_duration_s": 20.0}}],
        "agents": [{"name": "zero-v1", "policy": "zero", "env_id": "attitude_envs/FuelSlosh-v1"}],
        "optimum": {"solve": False},
    }
    with pytest.raises(ValueError, match=r"agent 'zero-v1' plays env 'fs' on attitude_envs/FuelSlosh-v1 .* differ"):
        prepare_campaign(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_play_env_without_a_task_is_the_cell():
    campaign = load_campaign(CELL)
    lqr = campaign.agents[0]
    assert play_env(lqr, "attitude_envs/AirBearing-v0", {"a": 1}) == ("attitude_envs/AirBearing-v0", {"a": 1})
