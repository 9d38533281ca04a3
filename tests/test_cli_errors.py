"""One-line errors (exit 2) before any work, help that lists the valid choices, Ctrl-C (exit
130, no traceback), unknown env keywords, progress, and the benchmarks' output directory."""

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import pytest
import yaml

import attitude_envs
from experiments import cli
from experiments.campaign import read_runs
from experiments.progress import Heartbeat, Progress

ROOT = Path(__file__).resolve().parents[1]


def _cli(*argv, **kw):
    return subprocess.run([sys.executable, "train.py", *argv], capture_output=True, text=True, cwd=ROOT, **kw)


OUT_ARGV = {
    "benchmark": ["benchmark", "--config", "quick"],
    "train": ["train", "--algo", "ppo"],
    "evaluate": ["evaluate", "--policy", "lqr"],
    "reproduce": ["reproduce", "feedback-linearization"],
}


def _refused(target: Path, err: str) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"--out {str(target)!r} is an existing file" in err
    assert target.read_text() == "keep me\n" and sorted(target.parent.iterdir()) == [target]


@pytest.mark.parametrize("command", ["reproduce", "train"])
def test_out_naming_an_existing_file_is_a_one_line_error_before_any_work(command, tmp_path):
    target = tmp_path / "taken.txt"
    target.write_text("keep me\n")
    proc = _cli(*OUT_ARGV[command], "--out", str(target))
    assert proc.returncode == 2, proc.stderr
    _refused(target, proc.stderr)
    assert proc.stdout == ""  # nothing ran (a campaign or training would print its phases)


@pytest.mark.parametrize("command", ["benchmark", "evaluate"])
def test_out_naming_an_existing_file_in_campaign_commands(command, tmp_path, capsys):
    target = tmp_path / "taken.txt"
    target.write_text("keep me\n")
    assert cli.main([*OUT_ARGV[command], "--out", str(target)]) == 2
    out = capsys.readouterr()
    _refused(target, out.err)
    assert out.out == ""


def test_reproduce_checks_out_before_it_computes(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(cli.REPRODUCTIONS, "ga-pid", "no_such_module_the_check_comes_first:reproduce")
    (tmp_path / "f").write_text("")
    assert cli.main(["reproduce", "ga-pid", "--out", str(tmp_path / "f")]) == 2
    assert "is an existing file" in capsys.readouterr().err


def test_out_below_a_file_is_refused_too(tmp_path, capsys):
    (tmp_path / "f").write_text("")
    assert cli.main(["evaluate", "--policy", "zero", "--out", str(tmp_path / "f" / "sub")]) == 2
    assert "is an existing file; --out names a directory" in capsys.readouterr().err


def test_table_options_without_write_table_are_refused_by_name(capsys):
    for argv in (["optimum", "--keep-table"], ["optimum", "--table", "t.json"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert "--campaign, --table and --keep-table go with --write-table" in err and err.count("\n") == 1, err


def test_seeds_0_is_a_one_line_error_naming_seeds_not_the_usage():
    proc = _cli("evaluate", "--policy", "lqr", "--seeds", "0", "--out", "X")
    assert proc.returncode == 2
    assert (
        proc.stderr == "error: argument --seeds: must be a count N (seeds 0..N-1), a range A-B, or a comma list like "
        "0,3,7-9 (seeds distinct, in [0, 2147483647], at most 100000 of them): a count must be >= 1, got 0 "
        "(see attitude-envs evaluate --help)\n"
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["demo", "--seeds", "0"], "argument --seeds: must be a count N (seeds 0..N-1)"),
        (["evaluate", "--policy", "lqr", "--seeds", "two", "--out", "X"], "'two' is not an integer or a range"),
        (["benchmark", "--jobs", "0", "--out", "X"], "argument --jobs/-j: must be an integer >= 1, got 0"),
        (["benchmark", "--workers", "0", "--out", "X"], "argument --workers: must be an integer >= 1, got 0"),
        (
            ["train", "--algo", "ppo", "--out", "X", "--verbose", "3"],
            "argument --verbose: must be an integer in [0, 2]",
        ),
        (["evaluate", "--out", "X", "--select", "worst"], "argument --select: invalid choice: 'worst'"),
        (["train", "--algo", "ppo"], "the following arguments are required: --out"),
    ],
)
def test_bad_arguments_are_one_line_errors_naming_the_option(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert "usage:" not in err and "--help" in err


def test_help_lists_the_valid_choices(capsys):
    from experiments.policies import POLICIES
    from experiments.reproductions import REPRODUCTIONS

    for argv in (["reproduce", "--help"], ["evaluate", "--help"], ["train", "--help"]):
        with pytest.raises(SystemExit) as exc:
            cli.main(argv)
        assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert all(paper in text for paper in REPRODUCTIONS)
    assert all(name in text for name in POLICIES if name != "sb3")
    assert "wheel-failure" in text and "attitude_envs/Magnetorquer-v0" in text
    assert "--select {best,final}" in text and "recurrentppo" in text


@pytest.mark.parametrize("env_id", list(attitude_envs.ENV_IDS))
def test_unknown_env_keyword_through_plain_gym_make_names_the_env_and_suggests(env_id):
    with pytest.raises(ValueError) as e:
        gym.make(env_id, control_dt=0.1)
    msg = str(e.value)
    assert f"bad keyword arguments for env {env_id!r}: it has no keyword argument 'control_dt'" in msg
    assert "did you mean 'control_dt_s'?" in msg or env_id.endswith("LinearSystem-v0")  # its period is dt_s
    assert "__init__" not in msg and "\n" not in msg
    with pytest.raises(ValueError, match="did you mean 'initial_euler_max_deg'"):
        gym.make_vec("attitude_envs/AirBearing-v0", num_envs=2, initial_euler_max=[1, 1, 1])


def test_unknown_env_keyword_costs_nothing_for_good_keywords():
    env = gym.make("attitude_envs/AirBearing-v0", control_dt_s=0.02, initial_euler_max_deg=[5, 5, 5])
    assert env.unwrapped.control_dt_s == 0.02


# --------------------------------------------------------------------------- Ctrl-C

SLOW_CAMPAIGN = {
    "name": "slow",
    "seeds": 400,
    "envs": [{"name": "rw", "id": "attitude_envs/ReactionWheel-v0"}],
    "agents": [{"name": "zero", "policy": "zero"}, {"name": "lqr", "policy": "lqr"}],
}


@pytest.mark.parametrize("workers", ["2", "1"])
def test_ctrl_c_is_one_line_exit_130_quick_and_logged_as_interrupted(workers, tmp_path):
    config = tmp_path / "slow.yml"
    config.write_text(yaml.safe_dump(SLOW_CAMPAIGN))
    out = tmp_path / "out"
    argv = [sys.executable, "train.py", "benchmark", "--config", str(config), "--out", str(out), "--workers", workers]
    # a shell's background job (`pytest &`, `nohup .ci/run &`) ignores SIGINT, the child would
    # inherit that and Python would then install no KeyboardInterrupt handler: the test runs the
    # command as a terminal's foreground job does, with SIGINT at its default (a Python handler in
    # this process is reset to the default in the exec'd child)
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(
            argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
        )
    finally:
        signal.signal(signal.SIGINT, inherited)
    try:
        deadline = time.monotonic() + 60
        log = out / "episodes.jsonl"
        while not (log.is_file() and log.read_text().count("\n") >= 2):  # episodes are running
            assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
            time.sleep(0.05)
        sent = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C does: SIGINT to the whole foreground group
        stdout, stderr = proc.communicate(timeout=20)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and stderr.count("\n") == 1, stderr
    assert stderr.startswith("interrupted: finished episodes are kept") and "rerun the same command" in stderr
    assert took < 2.0
    (run,) = read_runs(out / "runs.jsonl")
    assert run["status"] == "interrupted" and 0 < run["episodes_run"] < 800
    assert len((out / "episodes.jsonl").read_text().splitlines()) == run["episodes_run"]


# --------------------------------------------------------------------------- progress


def test_progress_writes_status_lines_off_a_terminal_and_a_bar_on_one():
    lines = io.StringIO()
    with Progress(4, "campaign episodes", "episode", stream=lines, interval_s=0.0) as p:
        for _ in range(4):
            p.update()
    text = lines.getvalue().splitlines()
    assert text[0] == "campaign episodes: 1/4 (25 %), 0:00 elapsed, ETA ?"  # no rate before a second item
    assert text[1].startswith("campaign episodes: 2/4 (50 %), 0:00 elapsed, ETA 0:0")
    assert text[-1].startswith("campaign episodes: 4/4 done in 0:00")
    bar = io.StringIO()
    with Progress(10, "train ppo", "steps", bar=True, stream=bar) as p:
        p.update_to(5)
    assert "train ppo" in bar.getvalue() and "5/10" in bar.getvalue()
    quiet = io.StringIO()
    with Progress(10, "x", stream=quiet, interval_s=3600.0) as p:
        p.update(10)
    assert quiet.getvalue() == ""  # a short job off a terminal: no noise
    beat = io.StringIO()
    with Heartbeat("reproduce x", 60, stream=beat, interval_s=0.05):
        time.sleep(0.2)
    assert beat.getvalue().startswith("reproduce x: 0:00 elapsed (typically 1:00)")


def test_campaign_reports_progress_lines_when_not_on_a_terminal(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ATTITUDE_ENVS_PROGRESS_S", "0")
    config = tmp_path / "c.yml"
    small = {**SLOW_CAMPAIGN, "seeds": 3, "envs": [{**SLOW_CAMPAIGN["envs"][0], "kwargs": {"episode_duration_s": 2.0}}]}
    config.write_text(yaml.safe_dump(small))
    assert cli.main(["benchmark", "--config", str(config), "--out", str(tmp_path / "o"), "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert "campaign episodes: 1/6 (17 %)" in err and "ETA" in err
    assert "campaign episodes: 6/6 done in" in err
    runs = read_runs(tmp_path / "o" / "runs.jsonl")
    assert [r["status"] for r in runs] == ["completed"] and runs[0]["episodes_run"] == 6


# --------------------------------------------------------------------------- benchmarks


def test_benchmarks_write_to_an_ignored_directory_and_refuse_a_file(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))  # benchmarks/ is a folder of the checkout, not an installed package
    from benchmarks import __main__ as bench
    from benchmarks import env_speed

    assert bench.DEFAULT_OUT == "results/benchmarks" and "results/" in (ROOT / ".gitignore").read_text().split()
    taken = tmp_path / "results.json"
    taken.write_text("{}")
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks", "--quick", "--out", str(taken)], capture_output=True, text=True, cwd=ROOT
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "must be a directory" in proc.stderr
    assert taken.read_text() == "{}"
    (row,) = env_speed.evaluator(episodes=1, rounds=3)
    lo, hi = row["episodes_per_s_range"]
    assert row["rounds"] == 3 and lo <= row["episodes_per_s"] <= hi


def test_benchmark_rows_are_medians_of_alternating_rounds(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))
    from benchmarks import env_speed

    rows = env_speed.batched(sizes=(1,), seconds=0.06, rounds=3)
    sync = [r for r in rows if r["env"].endswith("SyncVectorEnv")]
    assert len(sync) == len(env_speed.BATCHED_ENV_IDS)
    for r in rows:
        assert r["rounds"] == 3
        lo, hi = r["steps_per_s_range"]
        assert lo <= r["steps_per_s"] <= hi
    assert all(r["native_speedup_range"][0] <= r["native_speedup"] for r in sync)
    json.dumps(rows)  # JSON-ready
