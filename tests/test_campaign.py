"""Campaigns: skip-on-rerun after a crash, Ray vs local pool equality, report statistics."""

import csv
import json
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest

from experiments.campaign import load_campaign, read_runs, run_campaign
from experiments.machine_reference import reference_steps_per_s
from experiments.report.leaderboards import leaderboards
from experiments.report.statistics import bootstrap_ci, iqm
from experiments.report.writing import write_campaign_report

SMALL = {
    "name": "small",
    "seeds": 5,
    "envs": [
        {
            "name": "rw",
            "id": "attitude_envs/ReactionWheel-v0",
            "kwargs": {"preset": "pyramid-4wheel", "episode_duration_s": 8.0},
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
    for fault in ("none", "w0-out"):  # time histories of every cell
        assert f"(figures/history-rw-random-60deg-{fault}.png)" in report_a
        assert (tmp_path / "a" / "figures" / f"history-rw-random-60deg-{fault}.png").is_file()
    report_b = write_campaign_report(rerun).read_text()
    results = [r.split("## Leaderboards")[1].split("## Run record")[0] for r in (report_a, report_b)]
    assert results[0] == results[1]  # all but the run record (its wall times and runs differ)
    assert "| wall_time_all_runs_s | " in report_b and " over 2 run(s)" in report_b
    speed = r"Pendulum-v1 at \d+\.\dk → \d+\.\dk steps/s"  # the machine's speed at each run's start and end
    assert re.search(rf"on local-pool\[1\], 13 episodes, {speed}; ", report_b)
    assert re.search(rf"on local-pool\[1\], report only, {speed} \|", report_b)
    assert "agent q-lqr skipped" in report_b or "q-lqr" not in report_b


def test_partial_csv_is_readable_mid_campaign(tmp_path, monkeypatch):
    from experiments.campaign import episode

    real = episode._run_episode
    calls = {"n": 0}

    def crash_after_five(job):
        calls["n"] += 1
        if calls["n"] > 5:
            raise RuntimeError("simulated crash")
        return real(job)

    monkeypatch.setattr(episode, "_run_episode", crash_after_five)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run_campaign(SMALL, tmp_path, workers=1)
    rows = _csv(tmp_path / "episodes.csv")
    assert len(rows) == 5 and all(np.isfinite(float(r["J"])) for r in rows)
    (run,) = read_runs(tmp_path / "runs.jsonl")  # a start line, then the end line of the failed run
    assert run["status"] == "failed" and run["completed"] is False
    assert run["episodes_run"] == 5 and run["wall_time_s"] > 0


def test_different_campaign_in_the_same_directory_is_refused(tmp_path):
    run_campaign({**SMALL, "seeds": [0]}, tmp_path, workers=1)
    with pytest.raises(ValueError, match="different campaign definition.*seeds"):
        run_campaign({**SMALL, "seeds": [1]}, tmp_path, workers=1)


def test_agents_can_be_added_and_removed_but_not_redefined(tmp_path):
    base = {**SMALL, "seeds": [0], "agents": [{"name": "zero", "policy": "zero"}]}
    lqr = {"name": "lqr", "policy": "lqr", "params": {"discretization": "zoh"}}
    first = run_campaign(base, tmp_path, workers=1)
    # an agent added (and a new description): only its episodes run, the others are kept
    added = run_campaign({**base, "description": "more", "agents": [*base["agents"], lqr]}, tmp_path, workers=1)
    assert (first.episodes_run, added.episodes_run, added.episodes_skipped) == (2, 2, 2)
    assert {r["agent"] for r in added.rows} == {"zero", "lqr"}
    removed = run_campaign(base, tmp_path, workers=1)
    assert removed.episodes_run == 0  # removed: its rows leave the result and the table, not the log
    assert {r["agent"] for r in removed.rows} == {r["agent"] for r in _csv(tmp_path / "episodes.csv")} == {"zero"}
    for changed in ({**lqr, "params": {"discretization": "continuous"}}, {"name": "zero", "policy": "lqr"}):
        with pytest.raises(ValueError, match=f"agent\\(s\\) {changed['name']} changed"):
            run_campaign({**base, "agents": [changed]}, tmp_path, workers=1)  # lqr: removed, back changed


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
    with pytest.raises(ValueError, match="seeds must be a count N"):
        load_campaign({**SMALL, "seeds": [-1]})
    with pytest.raises(ValueError, match="unknown keys"):
        load_campaign({**SMALL, "agent": []})
    with pytest.raises(ValueError, match="needs model: PATH, train"):
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


KILL_DRIVER = """
import sys, types
if sys.argv[2] == "forkserver":
    sys.modules["torch"] = types.ModuleType("torch")  # as once torch is imported: the pool starts by forkserver
from experiments.campaign import run_campaign
config = {"name": "k", "seeds": 400, "envs": [{"name": "rw", "id": "attitude_envs/ReactionWheel-v0"}],
          "agents": [{"name": "zero", "policy": "zero"}]}
run_campaign(config, sys.argv[1], workers=2)
"""


def _proc_table() -> dict[int, tuple[int, str]]:
    """pid → (parent pid, state) of every process, from /proc."""
    table = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            table[int(entry)] = (int(fields[1]), fields[0])
    return table


def _descendants(pid: int) -> set[int]:
    table, found = _proc_table(), {pid}
    while True:
        more = {p for p, (parent, _) in table.items() if parent in found} - found
        if not more:
            return found - {pid}
        found |= more


def _running(pid: int) -> bool:
    state = _proc_table().get(pid, (0, "X"))[1]
    return state not in ("Z", "X")  # a zombie is dead, only not yet reaped


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process table from /proc")
@pytest.mark.parametrize("start", ["fork", "forkserver"])
def test_sigkill_of_a_campaign_leaves_no_child_process_and_a_killed_run(start, tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-c", KILL_DRIVER, str(out), start])
    try:
        deadline = time.monotonic() + 60
        log = out / "episodes.jsonl"
        while not (log.is_file() and log.read_text().count("\n") >= 2):  # the pool's workers are busy
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        children = _descendants(proc.pid)
        assert len(children) >= 2  # the two workers (+ forkserver and resource tracker)
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 5.0
        while any(_running(c) for c in children) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [c for c in children if _running(c)]
    finally:
        if proc.poll() is None:
            proc.kill()
    (run,) = read_runs(out / "runs.jsonl")
    assert run["status"] == "killed" and run["executor"] == "local-pool[2]"


def test_runs_log_pairs_start_and_end_lines_and_counts_killed_runs(tmp_path):
    log = tmp_path / "runs.jsonl"
    log.write_text(
        '{"wall_time_s": 2.0, "executor": "x", "completed": true}\n'  # the older one-line format
        '{"event": "start", "run": "a", "executor": "x"}\n'
        '{"event": "progress", "run": "a", "wall_time_s": 30.5}\n'  # then SIGKILL: no end line
        '{"event": "start", "run": "b", "executor": "x"}\n'
        '{"event": "end", "run": "b", "status": "interrupted", "wall_time_s": 4.0, "completed": false}\n'
        '{"event": "start", "run": "c", "exec'  # cut by a crash
    )
    runs = read_runs(log)
    assert [r["status"] for r in runs] == ["completed", "killed", "interrupted"]
    assert [r["wall_time_s"] for r in runs] == [2.0, 30.5, 4.0]
    result = run_campaign({**SMALL, "seeds": [0], "agents": SMALL["agents"][:1]}, tmp_path, workers=1)
    assert result.runs == 4 and result.run_statuses == {"completed": 2, "interrupted": 1, "killed": 1}
    lines = log.read_text().splitlines()
    assert lines[5].endswith('"exec') and json.loads(lines[6])["event"] == "start"  # the cut line was ended
    report = write_campaign_report(result).read_text()
    assert "over 4 run(s) (runs.jsonl, 1 interrupted, 1 killed)" in report
    # the new run records the machine's speed at its start and end; the report names it per run
    last = read_runs(log)[-1]
    assert last["reference_steps_per_s"] > 0 and last["reference_steps_per_s_end"] > 0
    assert report.count("Pendulum-v1 at ") == 1 and " → " in report


def test_machine_reference_is_a_positive_rate_and_rejects_a_bad_duration():
    assert reference_steps_per_s(0.01) > 0
    with pytest.raises(ValueError, match="seconds must be > 0"):
        reference_steps_per_s(0.0)


def test_success_is_per_env_and_a_deterministic_cell_has_no_ci(tmp_path):
    config = {
        "name": "ls",
        "seeds": [0, 1],
        "envs": [{"name": "ls", "id": "attitude_envs/LinearSystem-v0", "kwargs": {"episode_steps": 20000}}],
        "agents": [{"name": "zero", "policy": "zero"}, {"name": "lqr-dare", "policy": "linear-lqr"}],
    }
    result = run_campaign(config, tmp_path, workers=1)
    rows = {r["agent"]: r for r in result.rows if r["seed"] == 0}
    assert rows["zero"]["final_state_norm"] > rows["zero"]["initial_state_norm"] and not rows["zero"]["success"]
    assert rows["lqr-dare"]["final_state_norm"] < 0.1 * rows["lqr-dare"]["initial_state_norm"]
    assert rows["lqr-dare"]["success"]
    report = write_campaign_report(result).read_text()
    assert "| success: ls | final state norm ≤ 0.1 × the initial state norm (true state), not terminated" in report
    assert (
        "| zero | 2 (< 5 episodes) |" in report
        and "| deterministic |" in report
        and "[" not in report.split("## Leaderboards")[1].split("## ")[0]
    )
    board = [e for e in leaderboards(result.rows)[("ls", "default", "none")] if not e.get("oracle")]  # agents
    assert all(e["deterministic"] for e in board) and {e["agent"]: e["success_rate"] for e in board} == {
        "lqr-dare": 1.0,
        "zero": 0.0,
    }


def test_agents_whose_episodes_end_early_rank_after_those_that_finish():
    def row(agent, J, terminated):
        return {
            "env": "e",
            "scenario": "s",
            "fault": "none",
            "agent": agent,
            "seed": 0,
            "J": J,
            "terminated": terminated,
        }

    rows = [row("cut-short", 0.01, True), row("cut-short", 0.02, "True"), row("finisher", 5.0, False)]
    rows += [row("sometimes", 1.0, False), row("sometimes", 1.0, True)]
    board = leaderboards(rows)[("e", "s", "none")]
    assert [e["agent"] for e in board] == ["finisher", "sometimes", "cut-short"]
    assert [e["terminated_rate"] for e in board] == [0.0, 0.5, 1.0]


def test_a_folder_written_before_agent_identities_resumes_under_its_own_definition(tmp_path):
    config = {**SMALL, "seeds": [0], "agents": [{"name": "zero", "policy": "zero"}]}
    run_campaign(config, tmp_path, workers=1)
    marker = tmp_path / "campaign.json"
    old = json.loads(marker.read_text())
    marker.write_text(json.dumps({k: v for k, v in old.items() if k != "parts"}))  # as written before
    more = {**config, "agents": [*config["agents"], {"name": "lqr", "policy": "lqr"}]}
    with pytest.raises(ValueError, match="rerun it once with its own definition"):
        run_campaign(more, tmp_path, workers=1)
    assert run_campaign(config, tmp_path, workers=1).episodes_run == 0
    assert run_campaign(more, tmp_path, workers=1).episodes_run == 2  # now it records its agents
