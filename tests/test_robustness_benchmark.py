"""The robustness curves' protocol (benchmarks/robustness.py) on a short episode."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from benchmarks import robustness

pytest.importorskip("casadi")


def test_cvar_is_the_mean_of_the_worst_tenth():
    ratios = np.arange(1.0, 21.0)
    assert robustness.cvar(ratios) == pytest.approx((20.0 + 19.0) / 2)
    assert robustness.cvar(np.array([1.5])) == 1.5


def test_every_point_has_the_flight_sensors_and_one_feature():
    points = robustness.axes("attitude_envs/ReactionWheel-v0")
    assert {a for a, _, _ in points} == {"parameters", "delay", "noise"}
    for axis, level, conditions in points:
        assert conditions["sensors"] == (level if axis == "noise" else 1.0)
        assert set(conditions) - {"sensors"} == ({"parameters"} if axis == "parameters" else set()) | (
            {"delay_steps"} if axis == "delay" else set()
        )


def test_a_short_run_writes_rows_and_resumes(tmp_path):
    out = tmp_path / "robustness.csv"
    kwargs = {"episode_duration_s": 2.0, "control_dt_s": 0.5}
    rows = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)
    assert len(rows) == len(robustness.axes("attitude_envs/ReactionWheel-v0"))
    for row in rows:
        assert row["j_over_j_star"] >= 1.0 - 1e-9  # no controller beats the oracle
    written = list(csv.DictReader(out.open()))
    assert [r["axis"] for r in written] == [r["axis"] for r in rows]
    assert set(written[0]) == {"agent", "axis", "level", "j_over_j_star", "cvar10", "seeds"}
    episodes = out.with_suffix(".episodes.jsonl").read_text().splitlines()
    again = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)  # resumes: nothing replayed
    assert out.with_suffix(".episodes.jsonl").read_text().splitlines() == episodes
    assert [r["j_over_j_star"] for r in again] == [r["j_over_j_star"] for r in rows]
