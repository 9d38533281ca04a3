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
    assert {a for a, _, _ in points} == {"parameters", "delay", "noise", "held-out"}
    held_out = [(level, c) for a, level, c in points if a == "held-out"]
    # the flight cells' conditions, then their parameter tolerances widened beyond training's
    assert held_out == [
        (1.0, "flight"),
        (2.0, {"base": "flight", "parameters": 2.0}),
        (4.0, {"base": "flight", "parameters": 4.0}),
    ]
    for axis, level, conditions in points:
        if axis == "held-out":
            continue
        assert conditions["sensors"] == (level if axis == "noise" else 1.0)
        assert set(conditions) - {"sensors"} == ({"parameters"} if axis == "parameters" else set()) | (
            {"delay_steps"} if axis == "delay" else set()
        )


def test_a_short_run_writes_rows_and_resumes(tmp_path):
    out = tmp_path / "robustness.csv"
    kwargs = {"episode_duration_s": 2.0, "control_dt_s": 0.5}
    rows = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)
    assert len(rows) == len(robustness.axes("attitude_envs/ReactionWheel-v0"))
    assert [r["axis"] for r in rows][-3:] == ["held-out"] * 3
    for row in rows:
        assert row["j_over_j_star"] >= 1.0 - 1e-9  # no controller beats the oracle
    written = list(csv.DictReader(out.open()))
    assert [r["axis"] for r in written] == [r["axis"] for r in rows]
    assert set(written[0]) == {"agent", "axis", "level", "j_over_j_star", "cvar10", "seeds"}
    episodes = out.with_suffix(".episodes.jsonl").read_text().splitlines()
    again = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)  # resumes: nothing replayed
    assert out.with_suffix(".episodes.jsonl").read_text().splitlines() == episodes
    assert [r["j_over_j_star"] for r in again] == [r["j_over_j_star"] for r in rows]


def test_learned_agents_need_the_campaign_models(tmp_path):
    with pytest.raises(ValueError, match=r"--models .* has no trained ppo of the wheel campaign"):
        robustness.learned_models("wheel", tmp_path)


def test_learned_agents_are_every_training_seeds_best_snapshot(tmp_path):
    """Where the wheel campaign trains them: the lab PPO on its lab entry, the flight PPO on its
    flight entry, one run per training seed (0, 1, 2)."""
    for entry, name in (("rw", "ppo"), ("rw-flight", "ppo-flight")):
        for seed in (0, 1, 2):
            run = tmp_path / "models" / entry / name / f"seed{seed}"
            (run / "final").mkdir(parents=True)
            (run / "final" / "model.zip").write_bytes(b"")
            if seed == 0:  # a best snapshot where one was saved, else the final one
                (run / "best").mkdir()
                (run / "best" / "model.zip").write_bytes(b"")
    found = robustness.learned_models("wheel", tmp_path)
    assert {k: [(s, p.relative_to(tmp_path).as_posix()) for s, p in v] for k, v in found.items()} == {
        "ppo": [
            (0, "models/rw/ppo/seed0/best/model.zip"),
            (1, "models/rw/ppo/seed1/final/model.zip"),
            (2, "models/rw/ppo/seed2/final/model.zip"),
        ],
        "ppo-flight": [
            (0, "models/rw-flight/ppo-flight/seed0/best/model.zip"),
            (1, "models/rw-flight/ppo-flight/seed1/final/model.zip"),
            (2, "models/rw-flight/ppo-flight/seed2/final/model.zip"),
        ],
    }
    (tmp_path / "models" / "rw-flight" / "ppo-flight" / "seed2" / "final" / "model.zip").unlink()
    with pytest.raises(ValueError, match=r"no trained ppo-flight of the wheel campaign: .*seed2/final/model.zip"):
        robustness.learned_models("wheel", tmp_path)


def test_the_cell_and_learning_task_are_the_campaigns():
    assert robustness.cell_kwargs("wheel") == {"preset": "pyramid-4wheel", "action_frame": "body"}
    assert robustness.cell_kwargs("air-bearing") == {"preset": "air-bearing-85kg"}
    assert robustness.learning_id("air-bearing") == "attitude_envs/AirBearing-v1"
