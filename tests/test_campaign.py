"""Campaigns: skip-on-rerun after a crash, Ray vs local pool equality, report statistics."""

import csv
import json

import numpy as np
import pytest

from experiments.campaign import load_campaign, run_campaign
from experiments.report import bootstrap_ci, iqm, leaderboards, write_campaign_report

SMALL = {
    "name": "small",
    "seeds": 5,
    "envs": [
        {
            "name": "rw",
            "id": "attitude_envs/ReactionWheel-v0",
            "kwargs": {"preset": "spec-000", "episode_duration_s": 8.0},
            "scenarios": [{"name": "random-60deg"}],
            "faults": {"none": [], "w0-out": [{"kind": "outage", "target": "actuator", "index": 0, "onset_s": 2.0}]},
        }
    ],
    "agents": [
        {"name": "zero", "policy": "zero"},
        {"name": "lqr", "policy": "lqr", "params": {"discretization": "zoh"}},
        {"name": "q-lqr", "policy": "q-learning-lqr", "optional": True, "envs": []},
    ],
}


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_rerun_after_a_crash_skips_completed_episodes_and_gives_the_same_table(tmp_path):
    full = run_campaign(SMALL, tmp_path / "a", workers=1)
    assert full.episodes_run == 20 and len(full.rows) == 20
    table = (tmp_path / "a" / "episodes.csv").read_text()
    lqr = [r["final_error_deg"] for r in full.rows if r["agent"] == "lqr" and r["fault"] == "none"]
    zero = [r["final_error_deg"] for r in full.rows if r["agent"] == "zero" and r["fault"] == "none"]
    assert np.mean(lqr) < 0.7 * np.mean(zero)  # real closed-loop episodes (8 s of a ≈ 40 s maneuver)

    # Crash: only 7 episodes logged, the 8th line cut in the middle of its write.
    b = tmp_path / "b"
    b.mkdir()
    lines = (tmp_path / "a" / "episodes.jsonl").read_text().splitlines()
    (b / "episodes.jsonl").write_text("\n".join(lines[:7]) + "\n" + lines[7][:40])
    (b / "campaign.json").write_text((tmp_path / "a" / "campaign.json").read_text())
    again = run_campaign(SMALL, b, workers=1)
    assert again.episodes_skipped == 7 and again.episodes_run == 13
    assert (b / "episodes.csv").read_text() == table
    rerun = run_campaign(SMALL, b, workers=1)
    assert rerun.episodes_run == 0 and rerun.episodes_skipped == 20
    assert rerun.runs == 2 and rerun.total_wall_time_s == pytest.approx(
        again.total_wall_time_s + rerun.wall_time_s, abs=2e-3
    )
    assert (b / "episodes.csv").read_text() == table
    report_a = write_campaign_report(full).read_text()
    report_b = write_campaign_report(rerun).read_text()
    assert report_a.split("## Leaderboards")[1] == report_b.split("## Leaderboards")[1]
    assert "| wall_time_all_runs_s | " in report_b and " over 2 run(s)" in report_b
    assert "agent q-lqr skipped" in report_b or "q-lqr" not in report_b


def test_partial_csv_is_readable_mid_campaign(tmp_path, monkeypatch):
    import experiments.campaign as campaign

    real = campaign._run_episode
    calls = {"n": 0}

    def crash_after_five(job):
        calls["n"] += 1
        if calls["n"] > 5:
            raise RuntimeError("simulated crash")
        return real(job)

    monkeypatch.setattr(campaign, "_run_episode", crash_after_five)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run_campaign(SMALL, tmp_path, workers=1)
    rows = _csv(tmp_path / "episodes.csv")
    assert len(rows) == 5 and all(np.isfinite(float(r["J"])) for r in rows)
    (run,) = [json.loads(line) for line in (tmp_path / "runs.jsonl").read_text().splitlines()]
    assert run["completed"] is False and run["episodes_run"] == 5 and run["wall_time_s"] > 0


def test_different_campaign_in_the_same_directory_is_refused(tmp_path):
    run_campaign({**SMALL, "seeds": [0]}, tmp_path, workers=1)
    with pytest.raises(ValueError, match="different campaign definition"):
        run_campaign({**SMALL, "seeds": [1]}, tmp_path, workers=1)


def test_ray_gives_the_same_table_as_the_local_pool(tmp_path):
    ray = pytest.importorskip("ray")
    config = {**SMALL, "seeds": [0, 1]}
    local = run_campaign(config, tmp_path / "pool", workers=2)
    try:
        remote = run_campaign(config, tmp_path / "ray", ray_address="local", workers=2)
    finally:
        if ray.is_initialized():
            ray.shutdown()
    assert remote.executor == "ray[local]" and local.executor == "local-pool[2]"
    assert (tmp_path / "ray" / "episodes.csv").read_bytes() == (tmp_path / "pool" / "episodes.csv").read_bytes()
    assert len(local.rows) == 8


def test_campaign_validation_names_the_problem():
    with pytest.raises(ValueError, match="unknown policy 'nope'; accepted"):
        load_campaign({**SMALL, "agents": [{"name": "x", "policy": "nope"}]})
    with pytest.raises(ValueError, match="unknown env id"):
        load_campaign({**SMALL, "envs": [{"id": "nope/Nope-v0"}]})
    with pytest.raises(ValueError, match="seeds must be a non-empty list"):
        load_campaign({**SMALL, "seeds": [-1]})
    with pytest.raises(ValueError, match="unknown keys"):
        load_campaign({**SMALL, "agent": []})
    with pytest.raises(ValueError, match="needs model: PATH or train"):
        load_campaign({**SMALL, "agents": [{"name": "x", "policy": "sb3"}]})
    with pytest.raises(ValueError, match=r"train.select must be one of \['best', 'final'\], got 'worst'"):
        load_campaign(
            {**SMALL, "agents": [{"name": "x", "policy": "sb3", "train": {"algo": "ppo", "select": "worst"}}]}
        )
    assert load_campaign("quick").name == "quick" and load_campaign("full").name == "full"


def test_bootstrap_ci_and_iqm():
    assert iqm([1, 2, 3, 4, 5, 6, 7, 8]) == pytest.approx(4.5)  # mean of 3, 4, 5, 6
    assert iqm([1, 2, 3, 4, 100]) < np.mean([1, 2, 3, 4, 100]) / 3
    x = np.random.default_rng(1).normal(10.0, 2.0, size=200)
    lo, hi = bootstrap_ci(x)
    half = 1.96 * x.std(ddof=1) / np.sqrt(len(x))  # normal-theory interval for comparison
    assert lo < x.mean() < hi
    assert hi - lo == pytest.approx(2 * half, rel=0.15)
    assert bootstrap_ci(x) == (lo, hi)  # reproducible
    rows = [
        {"env": "e", "scenario": "s", "fault": "f", "agent": a, "seed": i, "J": j, "success": True}
        for a, js in (("b", [3.0, 4.0]), ("a", [1.0, 2.0]))
        for i, j in enumerate(js)
    ]
    board = leaderboards(rows)[("e", "s", "f")]
    assert [e["agent"] for e in board] == ["a", "b"] and board[0]["J_mean"] == 1.5


def test_episode_rows_carry_recovery_after_the_fault(tmp_path):
    result = run_campaign({**SMALL, "seeds": [0]}, tmp_path, workers=1)
    rows = {(r["agent"], r["fault"]): r for r in result.rows}
    assert np.isnan(rows[("lqr", "none")]["recovery_time_s"])
    assert rows[("lqr", "w0-out")]["recovery_time_s"] >= 0.0 or np.isnan(rows[("lqr", "w0-out")]["recovery_time_s"])
    assert rows[("zero", "w0-out")]["success"] is False
    data = json.loads((tmp_path / "episodes.json").read_text())
    assert len(data) == 4
