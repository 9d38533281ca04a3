"""``benchmarks/mpc_solve_times.py``: each plant's MPC rows are taken from its campaign YAML
(its parameters and decision period), and a measured episode reports its solve-time
statistics in ms and as a share of the MPC's own period. No time is asserted."""

from __future__ import annotations

import math

import pytest

from benchmarks import mpc_solve_times as mst


def test_every_plant_campaign_has_an_mpc_row_on_its_nominal_cell():
    for name in mst.CAMPAIGNS:
        jobs = mst.mpc_jobs(name, [0])
        assert jobs, name
        assert {j["key"]["fault"] for j in jobs} == {"none"}
        assert {j["key"]["seed"] for j in jobs} == {0}
        assert all(j["policy"]["policy"] in mst.MPC_POLICIES for j in jobs)


def test_the_jobs_carry_the_campaigns_decision_period_and_parameters():
    jobs = {j["key"]["agent"]: j for j in mst.mpc_jobs("air-bearing", [0, 1])}
    assert set(jobs) == {"mpc", "mpc-ft"}
    assert jobs["mpc"]["env_kwargs"]["control_dt_s"] == 0.5
    assert jobs["mpc"]["policy"]["params"] == {"horizon_steps": 10, "model_substeps": 2}
    assert len(mst.mpc_jobs("air-bearing", [0, 1])) == 4
    (slosh,) = mst.mpc_jobs("slosh", [3])
    assert slosh["env_id"] == "attitude_envs/FuelSlosh-v0" and "control_dt_s" not in slosh["env_kwargs"]


def test_a_measured_episode_reports_its_solves_against_its_period():
    pytest.importorskip("casadi")
    (job,) = mst.mpc_jobs("linear", [0])
    job["env_kwargs"] = {**job["env_kwargs"], "episode_steps": 1000}  # 10 s: ten 1 s decisions
    row = mst.measure(job)
    assert row["decisions"] == 10 and row["control_dt_s"] == 1.0
    s, p = row["solve_ms"], row["solve_percent_of_period"]
    assert 0 < s["median"] <= s["p90"] <= s["max"]
    assert p["median"] == pytest.approx(s["median"] / 10.0) and p["max"] == pytest.approx(s["max"] / 10.0)
    assert math.isfinite(row["J"]) and row["failures"] == 0


def test_the_built_policies_apply_the_campaigns_parameters_and_seeds_outside_are_refused():
    pytest.importorskip("casadi")
    import gymnasium as gym

    from experiments.policies import build_policy

    job = next(j for j in mst.mpc_jobs("air-bearing", [0]) if j["key"]["agent"] == "mpc-ft")
    policy = build_policy(job["policy"], gym.make(job["env_id"], **job["env_kwargs"]), name="mpc-ft")
    assert policy.model_parameters.n_substeps == 2 and policy.horizon_steps == 10
    with pytest.raises(ValueError, match=r"seeds \[20\] are not seeds of campaign 'slosh'"):
        mst.mpc_jobs("slosh", [0, 20])
