"""The Optuna hyperparameter search (`attitude-envs tune`): trials train through train(), the
study is a journal file that a second call resumes, and best.yml is a Zoo-format entry."""

from __future__ import annotations

import csv

import pytest
import yaml

pytest.importorskip("optuna")
pytest.importorskip("stable_baselines3")

from experiments.cli import main  # noqa: E402
from experiments.training.tuning import tune  # noqa: E402

ENV = "attitude_envs/LinearSystem-v0"
KWARGS = {"episode_steps": 50}
# Fixed overrides win over the sampled values (the sampler still draws every parameter, and
# trials.csv lists them): one short rollout size and one epoch keep each trial to a few
# seconds of PPO; what is checked is the search (trials, journal, resume, pruning hooks, best.yml).
FIXED = {"n_envs": 1, "batch_size": 64, "n_steps": 256, "n_epochs": 1}


def _rows(out):
    with open(out / "trials.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_tune_runs_trials_resumes_and_writes_a_zoo_entry(tmp_path):
    out = tmp_path / "study"
    # 2 evaluations of 2 rollouts each (n_steps fixed: a budget of 2 × the largest sampled n_steps is not needed)
    common = dict(env_kwargs=KWARGS, timesteps=1024, n_evaluations=2, eval_episodes=2, overrides=FIXED, backend="sb3")
    first = tune("ppo", ENV, out, n_trials=2, **common)
    assert first["n_complete"] == 2 and first["n_pruned"] == 0
    rows = _rows(out)
    assert [r["state"] for r in rows] == ["COMPLETE", "COMPLETE"]
    # a trial's value is its best evaluation J, read from its own run
    for r in rows:
        with open(out / f"trial-{int(r['number']):03d}" / "evaluations.csv", newline="", encoding="utf-8") as fh:
            js = [float(e["J_mean"]) for e in csv.DictReader(fh)]
        assert len(js) == 2 and float(r["value"]) == pytest.approx(min(js))
    # the second call continues the same study: one more trial, not three
    again = tune("ppo", ENV, out, n_trials=3, **common)
    assert again["n_complete"] == 3 and len(_rows(out)) == 3
    entry = yaml.safe_load((out / "best.yml").read_text(encoding="utf-8"))[ENV]
    assert entry["n_envs"] == 1 and entry["batch_size"] == 64  # the fixed overrides win
    assert entry["policy_kwargs"].startswith("dict(log_std_init=") and entry["learning_rate"].startswith("lin_")
    assert again["best_value"] == min(float(r["value"]) for r in _rows(out))


def test_tune_rejects_bad_arguments_by_name(tmp_path):
    with pytest.raises(ValueError, match=r"no sampler for algo 'td3' \(accepted: \['ppo', 'sac'\]\)"):
        tune("td3", ENV, tmp_path / "a")
    with pytest.raises(ValueError, match=r"n_evaluations must be in \[1, timesteps\], got 0"):
        tune("ppo", ENV, tmp_path / "b", n_evaluations=0)


def test_tune_command_line(tmp_path, capsys):
    out = tmp_path / "cli"
    argv = ["tune", "--algo", "ppo", "--env", ENV, "--env-kwargs", "{episode_steps: 50}", "--out", str(out)]
    # the fixed --params win over the sampled ones (n_steps and n_epochs too: two short rollouts of one
    # epoch, not up to 2000 steps x 20 epochs); what is checked is the command line, not the search
    argv += ["--trials", "1", "--timesteps", "512", "--evaluations", "1", "--eval-episodes", "2", "--backend", "sb3"]
    argv += ["--params", "n_envs:1", "batch_size:64", "n_steps:256", "n_epochs:1"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "1 trials complete, 0 pruned" in printed and "best eval J = " in printed
    assert (out / "best.yml").is_file()


def test_parallel_workers_share_one_study(tmp_path):
    """Two worker processes draw from one journal and stop at the study's trial count (a trial
    still running when the other worker reaches it finishes too: at most one extra)."""
    out = tmp_path / "jobs"
    summary = tune(
        "ppo",
        ENV,
        out,
        env_kwargs=KWARGS,
        n_trials=2,
        timesteps=1000,
        n_evaluations=1,
        eval_episodes=1,
        overrides=FIXED,
        backend="sb3",
        jobs=2,
    )
    rows = _rows(out)
    assert 2 <= summary["n_complete"] <= 3 and len(rows) == summary["n_complete"]
    assert len({r["number"] for r in rows}) == len(rows)
    # each worker samples with its own seed: no point is trained twice (one seed made pairs)
    points = {tuple(sorted((k, v) for k, v in r.items() if k.startswith("param_"))) for r in rows}
    assert len(points) == len(rows), rows


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_every_drawn_setting_is_an_entry_the_algorithm_builds(algo):
    """Each algorithm's sampler draws Zoo overrides that its hyperparameter entry takes and
    Stable-Baselines3 builds (here the extremes of every range), with γ within the task's episode."""
    import gymnasium as gym
    import optuna
    from stable_baselines3 import PPO, SAC

    from experiments.training.algorithm import Algorithm
    from experiments.training.hyperparams import load_hyperparams, split_hyperparams
    from experiments.training.tuning import sample, search_space, task_decisions

    env_id = "attitude_envs/AirBearing-v1"
    space = search_space(algo, task_decisions(env_id))
    assert max(space["gamma"]) <= 1 - 1 / 40  # 40 decisions per episode
    for pick in (0, -1):
        params = {k: (v[pick] if isinstance(v, list) else v[1:][pick]) for k, v in space.items()}
        overrides = sample(optuna.trial.FixedTrial(params), algo, space)
        entry = load_hyperparams(algo, env_id, overrides={**overrides, "backend": "sb3"})
        split = split_hyperparams(entry, n_actions=3, algorithm=Algorithm(algo))
        assert split["kwargs"]["gamma"] == params["gamma"]
        env = gym.make(env_id)
        model = {"ppo": PPO, "sac": SAC}[algo](split["policy"], env, **split["kwargs"])
        assert model.gamma == params["gamma"]
        env.close()
