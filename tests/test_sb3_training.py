"""SB3 glue: shipped Zoo-format hyperparameters, overrides, checkpoints and --resume (short runs)."""

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import attitude_envs  # noqa: F401,E402
from experiments.training.algorithm import ALGORITHMS, Algorithm, algorithm_class  # noqa: E402
from experiments.training.hyperparams import load_hyperparams, parse_overrides, parse_python_literal, split_hyperparams  # noqa: E402
from experiments.training.training import load_trained, train  # noqa: E402

RW = "attitude_envs/ReactionWheel-v0"
SHORT = {"episode_duration_s": 5.0}  # 50 control steps per episode


@pytest.mark.parametrize("algo", sorted(ALGORITHMS))
@pytest.mark.parametrize("env_id", [RW, "attitude_envs/LinearSystem-v0"])
def test_shipped_hyperparameters_build_every_algorithm(algo, env_id):
    if algo in ("tqc", "recurrentppo"):
        pytest.importorskip("sb3_contrib")
    entry = load_hyperparams(algo, env_id)
    env = gym.make(env_id)
    hp = split_hyperparams(entry, env.action_space.shape[0], Algorithm(algo, entry.get("backend", "sb3")))
    assert hp["n_timesteps"] >= 1e5  # a real budget, not a test budget
    model = algorithm_class(algo)(
        hp["policy"], env, **{**hp["kwargs"], "buffer_size": 1000} if "buffer_size" in hp["kwargs"] else hp["kwargs"]
    )
    assert model.action_space.shape == env.action_space.shape


def test_zoo_strings_are_parsed_without_eval():
    import torch.nn as nn

    value = parse_python_literal("policy_kwargs", "dict(net_arch=[64, 64], activation_fn=nn.Tanh, log_std_init=-2)")
    assert value == {"net_arch": [64, 64], "activation_fn": nn.Tanh, "log_std_init": -2}
    with pytest.raises(ValueError, match="policy_kwargs must be a literal"):
        parse_python_literal("policy_kwargs", "__import__('os').system('true')")
    assert parse_overrides(["learning_rate:1e-3", "batch_size:64", "use_sde:true"]) == {
        "learning_rate": 1e-3,
        "batch_size": 64,
        "use_sde": True,
    }
    with pytest.raises(ValueError, match="key:value"):
        parse_overrides(["learning_rate=1e-3"])
    lr = split_hyperparams({"learning_rate": "lin_3e-4"}, 4, Algorithm("ppo"))["kwargs"]["learning_rate"]
    assert lr(1.0) == pytest.approx(3e-4) and lr(0.5) == pytest.approx(1.5e-4)


SAC_TINY = {
    "learning_starts": 50,
    "batch_size": 32,
    "train_freq": 1,
    "gradient_steps": 1,
    "buffer_size": 10_000,
    "policy_kwargs": "dict(net_arch=[32, 32])",
}


def _sac(out, total, resume=False, seed=3):
    # without the 0-step candidate: step 100 is then the best snapshot (the kill windows below)
    return train(
        "sac",
        RW,
        out,
        env_kwargs=SHORT,
        seed=seed,
        overrides=SAC_TINY,
        total_timesteps=total,
        checkpoint_freq=100,
        eval_freq=100,
        evaluate_initial=False,
        eval_episodes=1,
        resume=resume,
    )


def _weights(run):
    import zipfile

    with zipfile.ZipFile(run / "final" / "model.zip") as zf:  # tensors and optimizer states (not "data": times)
        return {name: zf.read(name) for name in zf.namelist() if name.endswith(".pth")}


@pytest.fixture(scope="module")
def sac_400(tmp_path_factory):
    """An uninterrupted 400-step SAC run: evaluations and checkpoints every 100 steps."""
    out = tmp_path_factory.mktemp("sac") / "reference"
    result = _sac(out, 400)
    assert result.timesteps == 400 and result.resumed_from is None and not result.already_complete
    return out


def _same_run(out, ref):
    for name in ("evaluations.csv", "best/best.json", "final/final.json", "checkpoints/latest.json"):
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    assert _weights(out) == _weights(ref)


def test_segments_with_the_full_schedule_budget_train_as_one_run(tmp_path):
    """A tuning trial trains in segments (pruning points): with ``schedule_timesteps`` the full
    budget, a linear learning-rate schedule anneals over the whole run, and two segments are
    bitwise one run. Without it, the first segment anneals to zero by its own end."""
    tiny = {**SAC_TINY, "learning_rate": "lin_1e-3"}
    common = dict(env_kwargs=SHORT, seed=3, overrides=tiny, checkpoint_freq=100, eval_freq=100, eval_episodes=1)
    # 200 steps in two segments of 100 (learning starts at 50: both segments take gradient steps)
    reference = tmp_path / "one-run"
    train("sac", RW, reference, total_timesteps=200, **common)
    segmented = tmp_path / "segments"
    train("sac", RW, segmented, total_timesteps=100, schedule_timesteps=200, **common)
    train("sac", RW, segmented, total_timesteps=200, schedule_timesteps=200, resume=True, **common)
    _same_run(segmented, reference)
    sawtooth = tmp_path / "per-segment"
    train("sac", RW, sawtooth, total_timesteps=100, **common)
    train("sac", RW, sawtooth, total_timesteps=200, resume=True, **common)
    assert _weights(sawtooth) != _weights(reference)
    with pytest.raises(ValueError, match="schedule_timesteps must be >= total_timesteps"):
        train("sac", RW, tmp_path / "bad", total_timesteps=200, schedule_timesteps=100, **common)


def test_resume_continues_a_killed_run_with_its_replay_buffer(tmp_path, sac_400):
    out = tmp_path / "run"
    first = _sac(out, 250)  # checkpoints at 100, 200 and 250 (the budget)
    assert first.timesteps == 250 and first.resumed_from is None
    checkpoints = out / "checkpoints"
    assert sorted(p.name for p in checkpoints.glob("step_*")) == ["step_000000000200", "step_000000000250"]
    assert json.loads((checkpoints / "latest.json").read_text())["timesteps"] == 250  # the finished run
    for name in ("state.pkl", "model.zip", "vecnormalize.pkl"):  # exact state, portable model, obs normalization
        assert (checkpoints / "step_000000000200" / name).is_file()
    # "Kill" at step 230: what the disk holds then is the 200-step checkpoint and its pointer.
    import shutil

    shutil.rmtree(out / "final")
    shutil.rmtree(checkpoints / "step_000000000250")
    (checkpoints / "latest.json").write_text(json.dumps({"timesteps": 200, "dir": "step_000000000200"}))
    with pytest.raises(ValueError, match="already holds a run; pass --resume"):
        _sac(out, 400)
    with pytest.raises(ValueError, match="seed 4 differs"):
        _sac(out, 400, resume=True, seed=4)
    second = _sac(out, 400, resume=True)
    assert second.resumed_from == 200  # lost at most one checkpoint interval
    assert second.timesteps == 400
    # Bitwise the uninterrupted run: the 250-step row of the killed run is gone, the replay buffer,
    # generators, optimizer and env states continued. The buffer holds 200 + 200 transitions.
    _same_run(out, sac_400)
    from experiments.training.checkpoint import read_checkpoint

    model = read_checkpoint(checkpoints / "step_000000000400")[0]
    assert model.replay_buffer.size() == 400
    rows = (out / "evaluations.csv").read_text().splitlines()
    assert rows[0] == "timesteps,J_mean,J_std" and [r.split(",")[0] for r in rows[1:]] == ["100", "200", "300", "400"]
    # A finished run resumed again: nothing to do (was an AttributeError).
    again = _sac(out, 400, resume=True)
    assert again.already_complete and again.timesteps == 400
    _same_run(out, sac_400)
    # The saved model is a Policy for the same env and refuses an env with other spaces.
    predictor = load_trained(out, gym.make(RW, **SHORT))
    action, _ = predictor.predict(np.zeros(6, dtype=np.float32))
    assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
    with pytest.raises(ValueError, match="trained for a different env: its action_space"):
        load_trained(out, gym.make(RW, wheel_axes=np.eye(3)))


class _Killed(Exception):
    pass


@pytest.mark.parametrize("when, step", [("before-the-pointer-moves", 300), ("after-the-pointer-before-best", 100)])
def test_kill_around_a_checkpoint_resumes_to_the_same_run(tmp_path, monkeypatch, sac_400, when, step):
    """The two windows of an evaluation step: its row is in evaluations.csv but the checkpoint
    pointer has not moved (the step is evaluated again), or the pointer moved but best/ was not
    yet written (it is written from the checkpoint). Step 100 is the first evaluation, which
    always writes best/."""
    import experiments.training.training as training

    assert json.loads((sac_400 / "evaluations.csv").read_text().splitlines()[1].split(",")[0]) == 100
    real = training.write_checkpoint

    def write_checkpoint(root, model, *args, **kwargs):
        if model.num_timesteps == step and when == "before-the-pointer-moves":
            raise _Killed
        directory = real(root, model, *args, **kwargs)
        if model.num_timesteps == step:
            raise _Killed
        return directory

    out = tmp_path / "run"
    monkeypatch.setattr(training, "write_checkpoint", write_checkpoint)
    with pytest.raises(_Killed):
        _sac(out, 400)
    rows = (out / "evaluations.csv").read_text().splitlines()
    assert rows[-1].startswith(f"{step},")  # fsynced before the checkpoint
    pointer = json.loads((out / "checkpoints" / "latest.json").read_text())["timesteps"]
    assert pointer == (step - 100 if when == "before-the-pointer-moves" else step)
    assert (out / "best" / "best.json").is_file() == (when == "before-the-pointer-moves")
    monkeypatch.setattr(training, "write_checkpoint", real)
    assert _sac(out, 400, resume=True).resumed_from == pointer
    _same_run(out, sac_400)


def test_the_initial_policy_is_the_first_candidate_for_the_best_snapshot(tmp_path):
    """Evaluated at 0 steps: a run whose training never beats its untrained policy keeps that
    one as its best snapshot (reports then say so) instead of its least bad trained policy;
    training itself is the same bits as without the evaluation."""
    options = dict(env_kwargs=SHORT, seed=3, overrides=SAC_TINY, total_timesteps=200, eval_episodes=1)
    options |= dict(checkpoint_freq=100, eval_freq=100)
    with_initial = train("sac", RW, tmp_path / "with", **options)
    without = train("sac", RW, tmp_path / "without", evaluate_initial=False, **options)
    rows = (tmp_path / "with" / "evaluations.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["0", "100", "200"]
    assert rows[2:] == (tmp_path / "without" / "evaluations.csv").read_text().splitlines()[1:]
    assert _weights(tmp_path / "with") == _weights(tmp_path / "without")
    J = {int(r.split(",")[0]): float(r.split(",")[1]) for r in rows[1:]}
    best = json.loads((tmp_path / "with" / "best" / "best.json").read_text())
    assert best["timesteps"] == min(J, key=J.get) and best["J_mean"] == min(J.values())
    assert with_initial.timesteps == without.timesteps == 200


def test_resume_without_a_checkpoint_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="no complete checkpoint"):
        _sac(tmp_path / "empty", 100, resume=True)


def test_budget_is_rounded_up_to_whole_rollouts_the_same_way_when_resumed(tmp_path):
    """PPO trains in rollouts of n_steps × n_envs = 300 steps: 1000 asked → 1200 trained, with or without a kill."""

    def ppo(out, resume=False):
        overrides = {"n_envs": 2, "n_steps": 150, "batch_size": 150, "n_epochs": 1}
        kwargs = {"env_kwargs": SHORT, "overrides": overrides, "total_timesteps": 1000, "eval_episodes": 1}
        return train("ppo", RW, out, checkpoint_freq=400, eval_freq=500, resume=resume, **kwargs)

    ref = ppo(tmp_path / "ref")
    assert ref.timesteps == 1200
    rows = (tmp_path / "ref" / "evaluations.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == [
        "0",
        "600",
        "1200",
    ]  # the initial policy; the first rollout ends at or after 500, 1000
    import shutil

    shutil.copytree(tmp_path / "ref", tmp_path / "killed")  # killed after the 600-step checkpoint
    checkpoints = tmp_path / "killed" / "checkpoints"
    shutil.rmtree(tmp_path / "killed" / "final")
    (checkpoints / "latest.json").write_text(json.dumps({"timesteps": 900, "dir": "step_000000000900"}))
    resumed = ppo(tmp_path / "killed", resume=True)
    assert (resumed.resumed_from, resumed.timesteps) == (900, 1200)
    _same_run(tmp_path / "killed", tmp_path / "ref")


def test_rl_zoo3_trains_on_the_envs_with_the_shipped_file(tmp_path):
    """Runs only where rl_zoo3 is installed (not in this project's CI)."""
    pytest.importorskip("rl_zoo3")
    import subprocess
    import sys

    from experiments.training.hyperparams import hyperparams_path

    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", RW, "--gym-packages", "attitude_envs"]
    cmd += ["--conf-file", str(hyperparams_path("ppo")), "-n", "128", "--log-folder", str(tmp_path), "--seed", "0"]
    cmd += ["--hyperparams", "n_envs:1", "n_steps:64", "batch_size:32", "--eval-freq", "-1"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert list(tmp_path.rglob("*.zip"))


def test_training_without_tensorboard_leaves_no_folders_in_the_temp_dir(tmp_path, monkeypatch):
    """SB3's ``learn()`` makes an empty ``$TMPDIR/SB3-<time>`` folder per call unless the model
    has a logger; training calls it once per evaluation segment, so it gets one without a folder."""
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    options = dict(env_kwargs=SHORT, seed=3, overrides=SAC_TINY, total_timesteps=200, eval_episodes=1)
    train("sac", RW, tmp_path / "run", checkpoint_freq=100, eval_freq=100, tensorboard=False, **options)
    assert list(scratch.iterdir()) == []


def test_a_model_whose_schedules_name_a_moved_module_still_plays(tmp_path, sac_400):
    """Schedules are pickled into model.zip naming their module; a model file written before the
    module moved (experiments.sb3 → experiments.training) plays: loading replaces what only
    training needs, and the actions are the same."""
    import base64
    import shutil
    import zipfile

    gone = base64.b64encode(b"cexperiments.sb3.checkpoint\nBudgetSchedule\n.").decode()  # a pickle of a moved class
    old = tmp_path / "old" / "final" / "model.zip"
    shutil.copytree(sac_400 / "final", old.parent)  # with its vecnormalize.pkl
    shutil.copy(sac_400 / "config.json", tmp_path / "old" / "config.json")
    with zipfile.ZipFile(sac_400 / "final" / "model.zip") as src, zipfile.ZipFile(old, "w") as dst:
        for name in src.namelist():
            content = src.read(name)
            if name == "data":
                data = json.loads(content)
                for key in ("learning_rate", "lr_schedule"):
                    data[key] = {":type:": "<class 'function'>", ":serialized:": gone}
                content = json.dumps(data).encode()
            dst.writestr(name, content)
    env = gym.make(RW, **SHORT)
    obs = np.stack([env.observation_space.sample() for _ in range(8)])
    actions = {run: load_trained(run, env).predict(obs, deterministic=True)[0] for run in (old, sac_400 / "final")}
    np.testing.assert_array_equal(actions[old], actions[sac_400 / "final"])
