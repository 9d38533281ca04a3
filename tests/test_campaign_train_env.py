"""An agent trained on one env entry plays its models on the others (``train.env``: trained in
the lab, scored under flight conditions too), and the report sets each row's lab J / J* beside
its flight cells'."""

from __future__ import annotations

import pytest

from experiments.campaign.jobs import episode_jobs, training_jobs
from experiments.campaign.spec import load_campaign
from experiments.report.markdown import conditions_markdown, conditions_pairs

AB1 = "attitude_envs/AirBearing-v1"


def _campaign(train: dict) -> dict:
    return {
        "name": "train-env",
        "seeds": 2,
        "envs": [
            {"name": "lab", "id": "attitude_envs/AirBearing-v0", "faults": {"none": []}},
            {
                "name": "flight",
                "id": "attitude_envs/AirBearing-v0",
                "kwargs": {"conditions": "flight"},
                "faults": {
                    "none": [],
                    "gyro": [{"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "value": 1e-3}],
                },
            },
        ],
        "agents": [
            {"name": "lqr", "policy": "lqr"},
            {"name": "ppo", "policy": "sb3", "env_id": AB1, "train": {"algo": "ppo", "seeds": [0, 1], **train}},
        ],
    }


def test_train_env_trains_once_and_plays_those_models_everywhere(tmp_path):
    campaign = load_campaign(_campaign({"env": "lab"}))
    jobs = training_jobs(campaign, tmp_path)
    assert [(j["out_dir"].split("/")[-3], j["seed"]) for j in jobs] == [("lab", 0), ("lab", 1)]
    assert "conditions" not in jobs[0]["env_kwargs"]
    played = [j for j in episode_jobs(campaign, tmp_path) if j["key"]["agent"] == "ppo"]
    assert {j["key"]["env"] for j in played} == {"lab", "flight"}
    for j in played:  # the lab's models, on each cell's own env (flight conditions there)
        assert f"/models/lab/ppo/seed{j['key']['train_seed']}/" in j["policy"]["model"]
        assert (j["env_kwargs"].get("conditions") == "flight") == (j["key"]["env"] == "flight")


def test_without_train_env_each_entry_trains_its_own(tmp_path):
    campaign = load_campaign(_campaign({}))
    assert sorted({j["out_dir"].split("/")[-3] for j in training_jobs(campaign, tmp_path)}) == ["flight", "lab"]


def test_train_env_must_be_an_entry_the_agent_plays():
    with pytest.raises(
        ValueError, match=r"train\.env names the env entry the agent trains on.*'lab', 'flight'.*'nope'"
    ):
        load_campaign(_campaign({"env": "nope"}))
    only = _campaign({"env": "lab"})
    only["agents"][1]["envs"] = ["flight"]
    with pytest.raises(ValueError, match=r"train\.env.*\['flight'\].*'lab'"):
        load_campaign(only)


def _row(env, fault, agent, J, j_star, conditions):
    return {
        "env": env,
        "scenario": "s",
        "fault": fault,
        "agent": agent,
        "seed": 0,
        "J": J,
        "j_star": j_star,
        "conditions": conditions,
    }


def test_the_lab_and_flight_table_sets_each_agent_beside_itself():
    from experiments.report.leaderboards import leaderboards

    rows = [
        _row("lab", "none", "lqr", 2.0, 1.0, "lab"),
        _row("lab", "outage", "lqr", 5.0, 1.0, "lab"),
        _row("flight", "none", "lqr", 3.0, 1.5, "flight"),
        _row("flight", "gyro", "lqr", 4.5, 1.5, "flight"),
        _row("flight", "none", "lqr+mekf", 1.8, 1.5, "flight"),
    ]
    assert conditions_pairs(rows) == [("lab", "flight", "s")]
    text = conditions_markdown(rows, leaderboards(rows))
    lines = [ln for ln in text.splitlines() if ln.startswith("| ")]
    assert lines[0] == (
        "| agent | lab · none: J / J* (CVaR₀.₁) | flight · none: J / J* (CVaR₀.₁) | flight · gyro: J / J* (CVaR₀.₁) |"
    )
    assert lines[1] == "| lqr | 2.0000 (2.0000) | 2.0000 (2.0000) | 3.0000 (3.0000) |"
    assert lines[2] == "| lqr+mekf | — | 1.2000 (1.2000) | — |"
    assert "J* (oracle)" not in text  # J*'s own line is not an agent
    assert conditions_markdown([r for r in rows if r["env"] == "lab"], leaderboards(rows[:2])) == ""
