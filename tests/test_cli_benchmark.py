"""train.py train / evaluate / benchmark: end to end on tiny budgets, and one-line errors (exit 2)."""

import json
import subprocess
import sys

import pytest
import yaml

pytest.importorskip("stable_baselines3")

from experiments import cli  # noqa: E402

TINY_CAMPAIGN = {
    "name": "tiny",
    "seeds": 5,
    "envs": [
        {
            "name": "rw",
            "id": "attitude_envs/ReactionWheel-v0",
            "kwargs": {"episode_duration_s": 3.0},
            "faults": {"none": [], "w0-out": [{"kind": "outage", "target": "actuator", "index": 0, "onset_s": 1.0}]},
        }
    ],
    "agents": [
        {"name": "lqr", "policy": "lqr"},
        {
            "name": "ppo",
            "policy": "sb3",
            "train": {
                "algo": "ppo",
                "timesteps": 128,
                "seeds": [0],
                "checkpoint_freq": 64,
                "eval_freq": 64,
                "overrides": {"n_envs": 1, "n_steps": 64, "batch_size": 32, "n_epochs": 1},
            },
        },
    ],
}


@pytest.fixture(scope="module")
def benchmark_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("bench")
    config = root / "tiny.yml"
    config.write_text(yaml.safe_dump(TINY_CAMPAIGN))
    code = cli.main(["benchmark", "--config", str(config), "--out", str(root / "out"), "--workers", "1"])
    return root, code


def test_benchmark_trains_evaluates_and_reports(benchmark_run, capsys):
    root, code = benchmark_run
    assert code == 0
    out = root / "out"
    assert (out / "models" / "rw" / "ppo" / "seed0" / "final" / "model.zip").is_file()
    report = (out / "report.md").read_text()
    assert "### rw · default · fault: w0-out" in report and "| lqr | 5 |" in report and "| ppo | 5 |" in report
    for name in ("leaderboard.png", "faults-rw.png"):
        assert (out / "figures" / name).stat().st_size > 1000
    # the campaign evaluates the best eval snapshot (eval seeds 10000+), not the final one
    best = json.loads((out / "models" / "rw" / "ppo" / "seed0" / "best" / "best.json").read_text())
    steps = f"{best['timesteps']} (the untrained policy)" if best["timesteps"] == 0 else str(best["timesteps"])
    assert (
        f"training budget: ppo | ppo (sb3), 128 steps × seeds [0], evaluated: best snapshot at {steps} steps" in report
    )
    # the run's validation J (eval seeds 10000+) of its best and final policy, and its task
    assert "validation J (5 episodes, seeds 10000+) best/final per seed: " in report
    assert "training task: ppo | ReactionWheel-v0: decisions every 0.1 s, γ 0.998" in report
    # Rerun: nothing to train or evaluate again, same leaderboard printed.
    assert cli.main(["benchmark", "--config", str(root / "tiny.yml"), "--out", str(out), "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "0 episodes run, 20 already done" in printed and "| lqr | 5 |" in printed


def test_train_and_evaluate_commands(benchmark_run, tmp_path, capsys, monkeypatch):
    run = tmp_path / "run"
    argv = ["train", "--algo", "a2c", "--env-kwargs", "{episode_duration_s: 2.0}", "--out", str(run)]
    argv += ["--timesteps", "40", "--params", "n_envs:1", "n_steps:8", "--eval-freq", "20", "--eval-episodes", "1"]
    monkeypatch.setenv("ATTITUDE_ENVS_PROGRESS_S", "0")  # a status line per step (not on a terminal)
    assert cli.main(argv) == 0
    out = capsys.readouterr()
    assert "trained a2c (sb3) on attitude_envs/ReactionWheel-v0: 40 steps" in out.out
    assert "train a2c ReactionWheel-v0: 8/40 steps (20 %)" in out.err and "ETA" in out.err
    resume = ["train", "--algo", "a2c", "--env-kwargs", "{episode_duration_s: 2.0}", "--out", str(run)]
    resume += ["--timesteps", "60", "--params", "n_envs:1", "n_steps:8", "--eval-freq", "20", "--eval-episodes", "1"]
    assert cli.main([*resume, "--resume"]) == 0  # continues the finished 40-step run to 60 steps
    line = capsys.readouterr().out.splitlines()[0]
    assert "(resumed at 40 steps)" in line
    assert int(line.split(": ")[1].split()[0]) >= 60  # A2C finishes its 8-step rollout: 64
    ev = tmp_path / "ev"
    code = cli.main(
        ["evaluate", "--env-kwargs", "{episode_duration_s: 2.0}", "--model", str(run), "--policy", "zero"]
        + ["--policy", "lqr:discretization:continuous", "--seeds", "5", "--out", str(ev), "--workers", "1"]
    )
    assert code == 0
    rows = (ev / "episodes.csv").read_text().splitlines()
    assert len(rows) == 1 + 15 and rows[0].startswith("env,scenario,fault,agent,train_seed,seed,J")
    assert (ev / "episodes.json").is_file() and (ev / "report.md").is_file()
    # like a campaign, evaluate loads the run's best snapshot; the report names it and the algorithm
    report = (ev / "report.md").read_text()
    best = json.loads((run / "best" / "best.json").read_text())
    assert f"| model: a2c | {run / 'best' / 'model.zip'} (best snapshot at {best['timesteps']} steps) |" in report
    assert "| a2c | 5 |" in report and "| model |" not in report and "<dict>" not in report
    assert "| command | attitude-envs evaluate --env-kwargs '{episode_duration_s: 2.0}' --model" in report
    final = tmp_path / "ev-final"
    argv = ["evaluate", "--env-kwargs", "{episode_duration_s: 2.0}", "--model", str(run), "--model", str(run)]
    assert cli.main([*argv, "--select", "final", "--seeds", "1", "--out", str(final), "--workers", "1"]) == 0
    report = (final / "report.md").read_text()
    assert f"| model: a2c-1 | {run / 'final' / 'model.zip'} (final snapshot at 64 steps) |" in report
    assert "| model: a2c-2 |" in report


def test_train_progress_bar_works_with_the_sb3_extra(tmp_path, capsys):
    pytest.importorskip("rich")  # SB3's progress bar needs it; it is in the sb3 extra
    argv = ["train", "--algo", "a2c", "--env-kwargs", "{episode_duration_s: 1.0}", "--out", str(tmp_path / "r")]
    argv += ["--timesteps", "16", "--params", "n_envs:1", "n_steps:8", "--eval-freq", "16", "--eval-episodes", "1"]
    assert cli.main([*argv, "--progress-bar"]) == 0
    assert "trained a2c (sb3) on attitude_envs/ReactionWheel-v0: 16 steps" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "--algo", "dqn", "--out", "X"], "algorithm must be one of ['a2c', 'ddpg', 'ppo', 'recurrentppo'"),
        (["train", "--algo", "ppo", "--env", "Nope-v9", "--out", "X"], "unknown env id 'Nope-v9'; accepted:"),
        (["evaluate", "--policy", "mpc2", "--out", "X"], "unknown policy 'mpc2'; accepted: ['amnftsmc'"),
        (["evaluate", "--policy", "lqr", "--env-kwargs", "{preset: x}", "--out", "X"], "preset must be one of"),
        (
            ["evaluate", "--policy", "zero", "--env-kwargs", "{wheels: 3}", "--out", "X"],
            "bad keyword arguments for env",
        ),
        (
            ["benchmark", "--config", "medium", "--out", "X"],
            "--config must be one of ['quick', 'full', 'wheel', 'air-bearing', 'magnetorquer', 'slosh', 'linear', 'slew'] or a YAML",
        ),
        (["train", "--algo", "ppo", "--env-kwargs", "{a: [", "--out", "X"], "--env-kwargs is malformed YAML"),
        (["train", "--algo", "ppo", "--params", "gamma=0.9", "--out", "X"], "override must look like key:value"),
        (["train", "--algo", "ppo", "--params", "n_envs:1", "gama:0.9", "--out", "X"], "bad hyperparameters for ppo"),
    ],
)
def test_bad_input_is_a_one_line_error(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_malformed_yaml_and_model_for_another_env_exit_2_without_traceback(benchmark_run, tmp_path):
    root, _ = benchmark_run
    bad = tmp_path / "bad.yml"
    bad.write_text("name: x\nenvs: [\n")
    assert cli.main(["benchmark", "--config", str(bad), "--out", str(tmp_path / "o")]) == 2
    model = root / "out" / "models" / "rw" / "ppo" / "seed0"
    for argv, message in (
        (
            ["evaluate", "--env", "attitude_envs/LinearSystem-v0", "--model", str(model), "--out", str(tmp_path / "e")],
            "was trained on attitude_envs/ReactionWheel-v0 (its run's config.json), not on attitude_envs/LinearSystem-v0",
        ),
    ):
        proc = subprocess.run([sys.executable, "train.py", *argv], capture_output=True, text=True)
        assert proc.returncode == 2, proc.stderr
        assert message in proc.stderr and "Traceback" not in proc.stderr
        assert proc.stderr.count("\n") == 1
