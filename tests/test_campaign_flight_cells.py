"""A campaign cell under flight conditions: its rows say so, an estimator row plays it, and J*
is the flight oracle's (solved under the same conditions) where the plant's symbolic model has
them, and refused (never a lab J* in its place) where it has not."""

from __future__ import annotations

import math

import pytest

from experiments.campaign import run_campaign

pytest.importorskip("casadi")


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    """J* solved here, not read from another test's cache (the refusal test needs a solve)."""
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))


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
        assert r["j_star_source"] == "solved"
        assert r["J"] >= r["j_star"] * (1 - 1e-9)
    lab_star = {r["seed"]: r["j_star"] for r in rows if r["env"] == "lab"}
    flight_star = {r["seed"]: r["j_star"] for r in rows if r["env"] == "flight"}
    assert all(flight_star[s] != lab_star[s] for s in lab_star)  # the flight oracle, not the lab's


def _linear_config() -> dict:
    config = _campaign("attitude_envs/LinearSystem-v0", [{"name": "linear-lqr", "policy": "linear-lqr"}])
    for env in config["envs"]:  # the double integrator: flight shows within a short episode
        env["kwargs"] = {k: v for k, v in env["kwargs"].items() if k == "conditions"} | {
            "A": [[1.0, 0.1], [0.0, 1.0]],
            "B": [[0.005], [0.1]],
            "x0_mean": [1.0, 0.0],
            "x0_std": 0.2,
            "episode_steps": 30,
        }
    return config


def test_a_plant_without_a_flight_oracle_gets_no_lab_j_star(tmp_path, monkeypatch):
    import attitude_envs.symbolic as symbolic

    monkeypatch.setattr(symbolic, "FLIGHT_BUILDERS", symbolic.FLIGHT_BUILDERS - {"LinearSystem-v0"})
    rows = run_campaign(_linear_config(), tmp_path, workers=1).rows
    flight = [r for r in rows if r["env"] == "flight"]
    assert flight and all(r["j_star_source"] == "unsupported" and math.isnan(r["j_star"]) for r in flight)


def test_linear_system_flight_cells_get_their_oracle(tmp_path):
    rows = run_campaign(_linear_config(), tmp_path, workers=1).rows
    star = {(r["env"], r["seed"]): r["j_star"] for r in rows}
    for seed in (0, 1):
        assert star[("flight", seed)] > star[("lab", seed)]  # the delay and B's gain error cost the oracle
