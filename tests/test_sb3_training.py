"""SB3 glue: shipped Zoo-format hyperparameters, overrides, checkpoints and --resume (short runs)."""

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import attitude_envs  # noqa: F401,E402
from experiments.sb3.hyperparams import load_hyperparams, parse_overrides, parse_python_literal, split_hyperparams  # noqa: E402
from experiments.sb3.registry import ALGORITHMS, algorithm_class  # noqa: E402
from experiments.sb3.training import load_trained, train  # noqa: E402

RW = "attitude_envs/ReactionWheel-v0"
SHORT = {"episode_duration_s": 5.0}  # 50 control steps per episode


@pytest.mark.parametrize("algo", sorted(ALGORITHMS))
@pytest.mark.parametrize("env_id", [RW, "attitude_envs/LinearSystem-v0"])
def test_shipped_hyperparameters_build_every_algorithm(algo, env_id):
    if algo in ("tqc", "recurrentppo"):
        pytest.importorskip("sb3_contrib")
    entry = load_hyperparams(algo, env_id)
    env = gym.make(env_id)
    hp = split_hyperparams(entry, env.action_space.shape[0])
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
    lr = split_hyperparams({"learning_rate": "lin_3e-4"}, 4)["kwargs"]["learning_rate"]
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
    return train(
        "sac",
        RW,
        out,
        env_kwargs=SHORT,
        seed=seed,
        overrides=SAC_TINY,
        total_timesteps=total,
        checkpoint_freq=100,
        eval_freq=10_000,
        eval_episodes=1,
        resume=resume,
    )


def test_resume_continues_a_killed_run_with_its_replay_buffer(tmp_path):
    out = tmp_path / "run"
    first = _sac(out, 250)  # checkpoints at 100 and 200 steps
    assert first.timesteps == 250 and first.resumed_from is None
    checkpoints = out / "checkpoints"
    assert sorted(p.name for p in checkpoints.glob("step_*")) == ["step_000000000200", "step_000000000250"]
    assert json.loads((checkpoints / "latest.json").read_text())["timesteps"] == 250  # the finished run
    assert (checkpoints / "step_000000000200" / "replay_buffer.pkl").is_file()
    assert (checkpoints / "step_000000000200" / "vecnormalize.pkl").is_file()  # obs normalization saved
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
    # The 400-step checkpoint holds the buffer of before the kill plus the new transitions. SB3
    # calls the callback before it stores the step's transition: a checkpoint at step n holds
    # n - 1 of them, so 199 + 199 (199 alone had the buffer not been restored).
    from stable_baselines3 import SAC

    model = SAC.load(out / "checkpoints" / "step_000000000400" / "model.zip")
    model.load_replay_buffer(out / "checkpoints" / "step_000000000400" / "replay_buffer.pkl")
    assert model.replay_buffer.size() == 398
    rows = (out / "evaluations.csv").read_text().splitlines()
    assert rows[0] == "timesteps,J_mean,J_std" and len(rows) >= 3
    # The saved model is a Policy for the same env and refuses an env with other spaces.
    predictor = load_trained(out, gym.make(RW, **SHORT))
    action, _ = predictor.predict(np.zeros(6, dtype=np.float32))
    assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
    with pytest.raises(ValueError, match="trained for a different env: its action_space"):
        load_trained(out, gym.make(RW, wheel_axes=np.eye(3)))


def test_resume_without_a_checkpoint_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="no complete checkpoint"):
        _sac(tmp_path / "empty", 100, resume=True)


def test_rl_zoo3_trains_on_the_envs_with_the_shipped_file(tmp_path):
    """Runs only where rl_zoo3 is installed (not in this project's CI)."""
    pytest.importorskip("rl_zoo3")
    import subprocess
    import sys

    from experiments.sb3.hyperparams import hyperparams_path

    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", RW, "--gym-packages", "attitude_envs"]
    cmd += ["--conf-file", str(hyperparams_path("ppo")), "-n", "128", "--log-folder", str(tmp_path), "--seed", "0"]
    cmd += ["--hyperparams", "n_envs:1", "n_steps:64", "batch_size:32", "--eval-freq", "-1"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert list(tmp_path.rglob("*.zip"))
