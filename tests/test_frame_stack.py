"""The Zoo's ``frame_stack``: training stacks normalized observations with VecFrameStack, and
every predictor built from the run (eval callback, ``load_trained``, campaigns) stacks them the
same way, one episode at a time or batched."""

import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import VecFrameStack  # noqa: E402

import attitude_envs  # noqa: F401,E402
from attitude_envs.evaluation.rollout import rollout  # noqa: E402
from experiments.training.algorithm import Algorithm  # noqa: E402
from experiments.training.callbacks import NormalizedPredictor, episode_costs  # noqa: E402
from experiments.training.hyperparams import split_hyperparams  # noqa: E402
from experiments.training.policy import SB3Policy  # noqa: E402
from experiments.training.sb3_vec_env import SB3VecEnv  # noqa: E402
from experiments.training.training import load_trained, train  # noqa: E402
from experiments.training.vec_envs import make_eval_env  # noqa: E402

AB = "attitude_envs/AirBearing-v0"
SHORT = {"episode_duration_s": 0.3}  # 30 steps: several episode boundaries in 80 steps


class Recorder:
    """A stand-in model that records the observations it is asked about."""

    def __init__(self, n_actions):
        self.seen, self.n_actions = [], n_actions

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.seen.append(np.array(obs))
        return np.zeros((*np.shape(obs)[:-1], self.n_actions), np.float32), None


def test_the_predictor_stacks_like_vec_frame_stack_across_episode_ends():
    venv = SB3VecEnv(AB, num_envs=3, **SHORT)
    venv.seed(5)
    stacked = VecFrameStack(venv, 4)
    n_actions = venv.action_space.shape[0]
    predictor = NormalizedPredictor(Recorder(n_actions), None, frame_stack=4)
    rng = np.random.default_rng(0)
    raw_venv = SB3VecEnv(AB, num_envs=3, **SHORT)
    raw_venv.seed(5)
    want, raw = stacked.reset(), raw_venv.reset()
    starts, crossed = np.ones(3, dtype=bool), False
    for _ in range(80):
        predictor.predict(raw, episode_start=starts)
        np.testing.assert_array_equal(predictor.model.seen[-1], want)
        action = rng.uniform(-1, 1, (3, n_actions)).astype(np.float32)
        want, _, dones, _ = stacked.step(action)
        raw, _, starts, _ = raw_venv.step(action)
        crossed |= bool(dones.any())
        assert want.shape == (3, 4 * raw.shape[1])
    assert crossed  # episodes of 30 steps: the comparison covered episode ends
    single = NormalizedPredictor(Recorder(n_actions), None, frame_stack=2)
    single.predict(raw[0], episode_start=np.ones(1, bool))
    single.predict(raw[1], episode_start=np.zeros(1, bool))
    np.testing.assert_array_equal(single.model.seen[-1], np.concatenate([raw[0], raw[1]]))


def test_frame_stack_is_validated():
    with pytest.raises(ValueError, match="frame_stack must be an integer >= 1"):
        split_hyperparams({"frame_stack": 0}, 3, Algorithm("ppo"))
    assert split_hyperparams({"frame_stack": 3}, 3, Algorithm("ppo"))["frame_stack"] == 3
    assert split_hyperparams({}, 3, Algorithm("ppo"))["frame_stack"] == 1


def test_a_frame_stacked_run_trains_resumes_loads_and_plays(tmp_path):
    hyperparams = tmp_path / "ppo.yml"
    hyperparams.write_text(f"{AB}:\n  policy: 'MlpPolicy'\n  n_timesteps: 1000\n  normalize: true\n  frame_stack: 3\n")
    options = dict(env_kwargs=SHORT, hyperparams_file=hyperparams, eval_freq=120, checkpoint_freq=120, eval_episodes=2)
    options["overrides"] = {"n_envs": 2, "n_steps": 60, "batch_size": 60, "n_epochs": 1}
    out = tmp_path / "run"
    train("ppo", AB, out, total_timesteps=120, **options)
    result = train("ppo", AB, out, total_timesteps=240, resume=True, **options)  # the pickled stack resumes
    train("ppo", AB, tmp_path / "straight", total_timesteps=240, **options)
    assert (out / "evaluations.csv").read_text() == (tmp_path / "straight" / "evaluations.csv").read_text()
    assert result.timesteps == 240 and json.loads((out / "config.json").read_text())["hyperparams"]["frame_stack"] == 3
    import gymnasium as gym

    env = gym.make(AB, **SHORT)
    predictor = load_trained(out / "final" / "model.zip", env)
    assert predictor.frame_stack == 3 and predictor.model.observation_space.shape == (
        3 * env.observation_space.shape[0],
    )
    j_single = [rollout(env, SB3Policy(predictor), seed=s)["J"] for s in (7, 8)]
    j_batched = episode_costs(load_trained(out / "final" / "model.zip"), make_eval_env(AB, SHORT, 2, True), [7, 8])
    np.testing.assert_allclose(j_batched, j_single, rtol=1e-5)
