"""The observation with the previous command (attitude_envs.wrappers.LastAction): the Gymnasium
wrapper, its JAX twin step for step (x64, under flight's one-period delay), training behind it on
the fused trainer and on SB3, and the saved model playing behind the policy-side twin."""

from __future__ import annotations

import json
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import trained_model_plays_as_evaluated
from gymnasium.utils.env_checker import check_env

import attitude_envs  # noqa: F401
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.wrappers import LastAction
from attitude_envs.wrappers.last_action import WithLastAction

LS = "attitude_envs/LinearSystem-v1"
LAST_ACTION = "attitude_envs.wrappers.LastAction"
NO_SENSORS = {"base": "flight", "sensors": 0}  # the delay, the actuator gains, no noise


def test_the_observation_ends_with_the_previous_clipped_action():
    env = LastAction(gym.make(LS))
    base = gym.make(LS)
    assert env.observation_space.shape == (base.observation_space.shape[0] + 3,)
    np.testing.assert_array_equal(env.observation_space.low[-3:], -1.0)
    obs, _ = env.reset(seed=4)
    ref, _ = base.reset(seed=4)
    np.testing.assert_array_equal(obs[:-3], ref)
    np.testing.assert_array_equal(obs[-3:], 0.0)
    for action in (np.array([0.5, -2.0, 0.25], np.float32), np.array([3.0, 0.0, -0.5], np.float32)):
        obs, *_ = env.step(action)
        ref, *_ = base.step(action)
        np.testing.assert_array_equal(obs[:-3], ref)
        np.testing.assert_array_equal(obs[-3:], np.clip(action, -1.0, 1.0))
    obs, _ = env.reset(seed=5)
    np.testing.assert_array_equal(obs[-3:], 0.0)  # a new episode forgets the last one's command
    with warnings.catch_warnings():  # check_env's note that a wrapper is not the unwrapped env
        warnings.filterwarnings("ignore", message=".*is different from the unwrapped version")
        check_env(LastAction(gym.make(LS)), skip_render_check=True)


def test_the_policy_side_twin_feeds_the_policy_as_the_wrapper_does():
    seen = []

    class Recorder:
        name = "recorder"

        def reset(self, seed=None):
            pass

        def act(self, obs, info):
            seen.append(np.array(obs))
            return np.array([2.0, -0.5, 0.1], np.float32)

    env = gym.make(LS)
    policy = LastAction.wrap_policy(Recorder(), env)
    assert isinstance(policy, WithLastAction) and policy.name == "recorder"
    wrapped = LastAction(gym.make(LS))
    obs, _ = wrapped.reset(seed=1)
    policy.reset(seed=1)
    raw, info = env.reset(seed=1)
    for i in range(3):
        raw, _, _, _, info = env.step(policy.act(raw, info))
        np.testing.assert_array_equal(seen[i], obs)
        obs, *_ = wrapped.step(np.array([2.0, -0.5, 0.1], np.float32))
    policy.reset(seed=2)
    policy.act(env.reset(seed=2)[0], {})
    np.testing.assert_array_equal(seen[-1][-3:], 0.0)


def test_a_space_it_cannot_extend_is_named():
    with pytest.raises(ValueError, match="LastAction needs a flat Box observation"):
        LastAction(gym.make("CartPole-v1"))  # a discrete action


def test_the_jax_twin_equals_the_wrapper_step_for_step_under_the_delay():
    jax = pytest.importorskip("jax")
    pytest.importorskip("flax")
    import jax.numpy as jnp

    from attitude_envs.jax import make
    from attitude_envs.jax.make import numba_env
    from attitude_envs.jax.wrappers import LastAction as JaxLastAction
    from attitude_envs.jax.wrappers import LastActionState

    actions = np.random.default_rng(0).uniform(-1.5, 1.5, (80, 3)).astype(np.float32)
    with jax.enable_x64(True):
        ne = numba_env("LinearSystem-v1", conditions=NO_SENSORS)
        plant, params = make("LinearSystem-v1", conditions=NO_SENSORS)
        env = JaxLastAction(plant)
        wrapped = LastAction(ne)
        wrapped.reset(seed=3)
        state = env.state_from(wrapped)
        assert isinstance(state, LastActionState)
        step = jax.jit(env.step_env)
        assert env.observation_space(params).shape == wrapped.observation_space.shape
        np.testing.assert_array_equal(env.observation_space(params).high, wrapped.observation_space.high)
        key = jax.random.PRNGKey(0)
        for i, a in enumerate(actions):
            state_before_end = state
            obs_j, state, reward, terminated, _ = step(key, state, jnp.asarray(a, jnp.float64), params)
            obs, r, term, trunc, info = wrapped.step(a)
            assert np.all(np.abs(obs - np.asarray(obs_j)) <= np.spacing(np.abs(obs))), i
            assert float(reward) == pytest.approx(r, rel=1e-12) and bool(terminated) == term
            if term or trunc:
                break
        assert i == 79 and trunc
        reset_obs, _ = env.reset(jax.random.PRNGKey(1), params)
        np.testing.assert_array_equal(np.asarray(reset_obs)[-3:], 0.0)
        # the autoreset: the last step's final observation ends with its command, the next episode with zeros
        obs, state, _, terminated, truncated, info = jax.jit(env.step)(key, state_before_end, actions[79], params)
        assert bool(truncated) and not bool(terminated)
        np.testing.assert_array_equal(np.asarray(info["final_observation"])[-3:], np.clip(actions[79], -1, 1))
        np.testing.assert_array_equal(np.asarray(obs)[-3:], 0.0)
        np.testing.assert_array_equal(np.asarray(state.last_action), 0.0)
    with pytest.raises(ValueError, match="wrapped in attitude_envs.wrappers.LastAction"):
        env.state_from(numba_env("LinearSystem-v1"))


def test_the_fused_trainer_trains_behind_the_twin_and_the_model_plays_behind_the_policy_twin(tmp_path, monkeypatch):
    overrides = {"n_envs": 2, "n_steps": 80, "batch_size": 80, "n_epochs": 2, "env_wrapper": LAST_ACTION}
    policy, env = trained_model_plays_as_evaluated(tmp_path, monkeypatch, LS, overrides, 320, 160)
    assert isinstance(policy, WithLastAction)
    assert policy.policy.model.model.observation_space.shape == (env.observation_space.shape[0] + 3,)


def test_the_jax_backend_names_a_wrapper_without_a_twin_and_one_left_unapplied(tmp_path):
    pytest.importorskip("jax")
    from agents.fused_ppo import from_zoo
    from experiments.training.training import train

    overrides = {"backend": "jax", "env_wrapper": "attitude_envs.wrappers.ConstraintPenalty"}
    with pytest.raises(ValueError, match="ConstraintPenalty has none"):
        train("ppo", LS, tmp_path / "run", total_timesteps=160, overrides=overrides)
    with pytest.raises(ValueError, match="env_wrapper is applied by the caller"):
        from_zoo({"env_wrapper": LAST_ACTION})  # a program built on the bare plant would drop it
    assert from_zoo({"env_wrapper": LAST_ACTION}, wrapped=True)[0] == from_zoo({})[0]


def test_sb3_trains_behind_the_wrapper_and_the_model_plays_behind_the_policy_twin(tmp_path):
    from experiments.policies import build_policy
    from experiments.training.training import load_trained, train

    overrides = {"n_envs": 2, "n_steps": 16, "batch_size": 32, "n_epochs": 1, "env_wrapper": LAST_ACTION}
    result = train(
        "ppo",
        LS,
        tmp_path / "run",
        total_timesteps=64,
        overrides=overrides,
        eval_episodes=1,
        eval_freq=64,
        backend="sb3",
    )
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["hyperparams"]["env_wrapper"] == LAST_ACTION
    env = gym.make(LS)
    predictor = load_trained(result.model_path, env)  # the space check adds the action to the env's
    assert predictor.model.observation_space.shape == (env.observation_space.shape[0] + 3,)
    policy = build_policy({"policy": "sb3", "model": str(result.model_path)}, env, name="ppo-last")
    assert isinstance(policy, WithLastAction) and policy.name == "ppo-last"
    episode = rollout(env, policy, seed=10_000)
    log = (tmp_path / "run" / "evaluations.csv").read_text().splitlines()
    assert float(log[-1].split(",")[1]) == pytest.approx(episode["J"], rel=1e-5)
    # a deployment shield would change the command the twin records as in flight
    shielded = {"policy": "sb3", "model": str(result.model_path), "params": {"shield": "cbf"}}
    with pytest.raises(ValueError, match="was trained behind attitude_envs.wrappers.LastAction"):
        build_policy(shielded, env)
