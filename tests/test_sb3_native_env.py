"""train() on the natively batched env: every env id, bitwise the single envs, pickled whole for
exact resume, and batched evaluation (all episodes in one policy call per step)."""

import json
import pickle
import zipfile

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import attitude_envs  # noqa: F401,E402
from attitude_envs.registration import VECTOR_ENTRY_POINTS  # noqa: E402
from experiments.training.callbacks import episode_costs  # noqa: E402
from experiments.training.training import load_trained, train  # noqa: E402
from experiments.training.vec_envs import (  # noqa: E402
    PicklableVecMonitor,
    TrainingSeeds,
    make_eval_env,
    make_training_env,
)

RW, LS = "attitude_envs/ReactionWheel-v0", "attitude_envs/LinearSystem-v0"
SHORT = {env_id: {"episode_duration_s": 5.0} for env_id in VECTOR_ENTRY_POINTS} | {
    LS: {"episode_steps": 40, "x0_std": 0.1}
}
SHORT["attitude_envs/AirBearing-v0"] = {"episode_duration_s": 0.5}  # 100 Hz control: 50 steps
PPO_TINY = {"n_envs": 2, "n_steps": 125, "batch_size": 125, "n_epochs": 1, "policy_kwargs": "dict(net_arch=[16])"}
HYPERPARAMS = "{id}:\n  policy: 'MlpPolicy'\n  n_timesteps: 1000\n  normalize: true\n"


def _weights(model_zip):
    with zipfile.ZipFile(model_zip) as zf:
        return {name: zf.read(name) for name in zf.namelist() if name.endswith(".pth")}


def _train(out, env_id, **kwargs):
    hyperparams = out.parent / f"{out.name}-ppo.yml"
    hyperparams.write_text(HYPERPARAMS.format(id=env_id))  # a Zoo file for any id (shipped ones: RW, LS)
    options = {"env_kwargs": SHORT[env_id], "overrides": PPO_TINY, "total_timesteps": 500}
    options.update(eval_freq=250, checkpoint_freq=250, eval_episodes=3, hyperparams_file=hyperparams)
    options.update(kwargs)
    return train("ppo", env_id, out, **options)


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_train_runs_on_the_native_batched_env_of_every_env_id(tmp_path, env_id):
    result = _train(tmp_path / "run", env_id)
    assert result.timesteps == 500 and np.isfinite(result.last_eval["J_mean"])
    rows = (tmp_path / "run" / "evaluations.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["0", "250", "500"]
    from experiments.training.checkpoint import read_checkpoint

    model = read_checkpoint(tmp_path / "run" / "checkpoints" / "step_000000000500")[0]
    seeds = model.get_env().venv
    assert isinstance(seeds, TrainingSeeds)
    monitor = seeds.venv
    assert isinstance(monitor, PicklableVecMonitor) and type(monitor.venv).__name__ == "SB3VecEnv"
    assert model.ep_info_buffer and {"r", "l", "t"} <= set(model.ep_info_buffer[0])  # Monitor's statistics


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_sbx_trains_on_every_env_id_and_loads_back(tmp_path, env_id):
    pytest.importorskip("sbx")
    result = _train(tmp_path / "run", env_id, backend="sbx")
    assert result.timesteps == 500 and np.isfinite(result.last_eval["J_mean"])
    assert json.loads((tmp_path / "run" / "config.json").read_text())["backend"] == "sbx"
    predictor = load_trained(result.model_path, gym.make(env_id, **SHORT[env_id]))
    assert type(predictor.model).__module__.startswith("sbx.")
    obs = np.zeros((3, predictor.model.observation_space.shape[0]), dtype=np.float32)
    actions, _ = predictor.predict(obs, deterministic=True)
    assert actions.shape == (3, *predictor.model.action_space.shape) and np.all(np.isfinite(actions))


_SAME_RUN = """
import sys, pathlib
sys.path.insert(0, "tests")
import experiments.training.training as training
from test_sb3_native_env import RW, _train, _weights
native = _train(pathlib.Path(sys.argv[1]) / "native", RW)
training.batched_supported = lambda env_id, env: False
single = _train(pathlib.Path(sys.argv[1]) / "single", RW)
print(_weights(native.model_path) == _weights(single.model_path))
"""


def test_native_training_is_bitwise_the_single_env_training(tmp_path):
    """The same run on SB3's DummyVecEnv of single envs (the fallback) ends with the same weights.
    MKL's sgemm rounds depending on memory alignment unless told not to (MKL_CBWR), so the two
    runs, whose buffers lie at different addresses, are compared with MKL's strict mode."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "MKL_CBWR": "AVX2,STRICT", "OMP_NUM_THREADS": "1", "PYTHONPATH": str(root)}
    proc = subprocess.run(
        [sys.executable, "-c", _SAME_RUN, str(tmp_path)], cwd=root, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "True"


def test_sensors_fall_back_to_single_envs(tmp_path):
    from experiments.training.checkpoint import read_checkpoint
    from experiments.training.vec_envs import batched_supported

    kwargs = {**SHORT[RW], "sensors": {"gyro": {"noise_std": 1e-3}}}

    assert not batched_supported(RW, gym.make(RW, **kwargs)) and batched_supported(RW, gym.make(RW))
    result = _train(tmp_path / "run", RW, env_kwargs=kwargs)
    assert result.timesteps == 500
    model = read_checkpoint(tmp_path / "run" / "checkpoints" / "step_000000000500")[0]
    assert type(model.get_env().venv.venv).__name__ == "DummyVecEnv"


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_training_env_pickles_and_continues_bitwise(env_id):
    venv = make_training_env(env_id, SHORT[env_id], 3, seed=7, batched=True)
    venv.reset()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (400, 3, *venv.action_space.shape)).astype(np.float32)
    for a in actions[:37]:  # mid-episode
        venv.step(a)
    copy = pickle.loads(cloudpickle.dumps(venv))
    for a in actions[37:]:
        obs, rewards, dones, infos = venv.step(a)
        obs2, rewards2, dones2, infos2 = copy.step(a)
        assert np.array_equal(obs, obs2) and np.array_equal(rewards, rewards2) and np.array_equal(dones, dones2)
        for info, info2 in zip(infos, infos2, strict=True):
            assert info.keys() == info2.keys() and info.get("cost") == info2.get("cost")
            if "episode" in info:
                assert (info["episode"]["r"], info["episode"]["l"]) == (info2["episode"]["r"], info2["episode"]["l"])
            if "terminal_observation" in info:
                assert np.array_equal(info["terminal_observation"], info2["terminal_observation"])


class _RowWisePolicy:
    """A deterministic policy whose arithmetic is elementwise (each row computed alone)."""

    def __init__(self, n_obs, n_actions):
        self.gains = np.random.default_rng(1).normal(0.0, 0.3, (n_obs, n_actions)).astype(np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(obs, dtype=np.float32)
        action = np.zeros((*obs.shape[:-1], self.gains.shape[1]), dtype=np.float32)
        for j in range(self.gains.shape[0]):
            action += obs[..., j : j + 1] * self.gains[j]
        return np.clip(np.tanh(action), -1, 1), None


TUMBLING = {"episode_duration_s": 20.0, "max_rate_rad_s": 0.05}  # episodes of 172, 101, 200, 31, 43 steps


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        (RW, {"episode_duration_s": 20.0}),
        (RW, TUMBLING),
        (LS, {"episode_steps": 60, "x0_std": 0.1, "process_noise_std": 0.01}),
        ("attitude_envs/Magnetorquer-v0", {"episode_duration_s": 20.0}),
    ],
)
def test_batched_evaluation_is_bitwise_the_sequential_one_for_the_same_actions(env_id, kwargs):
    """Episodes that end early stop contributing; J per episode is the single env's bit for bit."""
    from attitude_envs.evaluation.rollout import rollout
    from experiments.training.policy import SB3Policy

    seeds = [11, 12, 13, 14, 15]
    single = make_eval_env(env_id, kwargs, len(seeds), batched=False)
    policy = _RowWisePolicy(single.observation_space.shape[0], single.action_space.shape[0])
    sequential = episode_costs(policy, single, seeds)
    batched = episode_costs(policy, make_eval_env(env_id, kwargs, len(seeds), batched=True), seeds)
    assert np.array_equal(batched, sequential) and np.unique(sequential).size == len(seeds)
    if kwargs is TUMBLING:
        lengths = [rollout(single, SB3Policy(policy), seed=s)["steps"] for s in seeds]
        assert lengths == [172, 101, 200, 31, 43]


@pytest.mark.parametrize("env_id", [RW, LS])
def test_batched_evaluation_of_a_trained_model_matches_the_sequential_one(tmp_path, env_id):
    """A trained model's batched matrix products round differently from one-row ones (MKL's sgemm is
    not row-invariant), so J agrees to ~1e-10 relative, not bit for bit; repeated runs are bitwise."""
    result = _train(tmp_path / "run", env_id)
    predictor = load_trained(result.model_path)
    seeds = [100, 101, 102, 103, 104]
    sequential = episode_costs(predictor, make_eval_env(env_id, SHORT[env_id], 5, batched=False), seeds)
    batched_env = make_eval_env(env_id, SHORT[env_id], 5, batched=True)
    batched = episode_costs(predictor, batched_env, seeds)
    np.testing.assert_allclose(batched, sequential, rtol=1e-8)
    assert np.array_equal(batched, episode_costs(predictor, batched_env, seeds))  # the same env again
