"""A campaign cell under flight conditions: its rows say so, an estimator row plays it, and J*
is the flight oracle's (solved under the same conditions) where the plant's symbolic model has
them, and refused (never a lab J* in its place) where it has not."""

from __future__ import annotations

import math

import pytest

from experiments.campaign import run_campaign

pytest.importorskip("casadi")


def _campaign(env_id: str, agents: list[dict]) -> dict:
    return {
        "name": "flight-cells",
        "seeds": 2,
        "optimum": {"solve": True},  # short episodes: each J* solves in well under a second
        "envs": [
            {
                "name": "lab",
                "id": env_id,
                "kwargs": {"episode_duration_s": 2.0, "control_dt_s": 0.5},
                "scenarios": [{"name": "default"}],
                "faults": {"none": []},
            },
            {
                "name": "flight",
                "id": env_id,
                "kwargs": {"episode_duration_s": 2.0, "control_dt_s": 0.5, "conditions": "flight"},
                "scenarios": [{"name": "default"}],
                "faults": {"none": []},
            },
        ],
        "agents": agents,
    }


def test_flight_cells_carry_their_conditions_and_the_flight_oracle(tmp_path):
    agents = [{"name": "lqr", "policy": "lqr"}, {"name": "lqr+mekf", "policy": "lqr+mekf", "envs": ["flight"]}]
    result = run_campaign(_campaign("attitude_envs/ReactionWheel-v0", agents), tmp_path, workers=1)
    rows = result.rows
    assert {r["conditions"] for r in rows if r["env"] == "lab"} == {"lab"}
    assert {r["conditions"] for r in rows if r["env"] == "flight"} == {"flight"}
    assert {r["agent"] for r in rows if r["env"] == "flight"} == {"lqr", "lqr+mekf"}
    for r in rows:
        assert r["j_star_source"] in ("solved", "cache")  # the cache: another run solved the same episode
        assert r["J"] >= r["j_star"] * (1 - 1e-9)
    lab_star = {r["seed"]: r["j_star"] for r in rows if r["env"] == "lab"}
    flight_star = {r["seed"]: r["j_star"] for r in rows if r["env"] == "flight"}
    assert all(flight_star[s] != lab_star[s] for s in lab_star)  # the flight oracle, not the lab's


def test_a_plant_without_a_flight_oracle_gets_no_lab_j_star(tmp_path):
    agents = [{"name": "linear-lqr", "policy": "linear-lqr"}]
    config = _campaign("attitude_envs/LinearSystem-v0", agents)
    for env in config["envs"]:
        env["kwargs"] = {k: v for k, v in env["kwargs"].items() if k == "conditions"} | {"episode_steps": 5}
    rows = run_campaign(config, tmp_path, workers=1).rows
    flight = [r for r in rows if r["env"] == "flight"]
    assert flight and all(r["j_star_source"] == "unsupported" and math.isnan(r["j_star"]) for r in flight)
