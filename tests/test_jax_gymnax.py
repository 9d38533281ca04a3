"""gymnax's own wrappers, unmodified, on the five JAX plants: ``GymnaxToGymWrapper`` (a
Gymnasium env whose spaces gymnax converts from ours), ``LogWrapper`` (episode returns and
lengths), on one plant ``GymnaxToVectorGymWrapper``, and rejax 0.1.3's PPO through
:class:`attitude_envs.jax.DoneStep` where rejax is installed. Skipped without gymnax (not a
dependency: its 1.0.1 pins gymnasium<1.4; the JAX guide installs it beside gymnasium 1.4 with
``pip install --no-deps gymnax==1.0.1`` after the ``gymnax`` extra)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("gymnax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from gymnasium import spaces as gspaces  # noqa: E402
from gymnax.environments import spaces as gymnax_spaces  # noqa: E402
from gymnax.wrappers.gym import GymnaxToGymWrapper, GymnaxToVectorGymWrapper  # noqa: E402
from gymnax.wrappers.purerl import LogWrapper  # noqa: E402

import attitude_envs.jax as aej  # noqa: E402
from attitude_envs.jax.make import numba_env  # noqa: E402

PLANTS = ["ReactionWheel-v1", "AirBearing-v1", "FuelSlosh-v1", "Magnetorquer-v1", "LinearSystem-v1"]
STEPS = 12


@pytest.mark.parametrize("env_id", PLANTS)
def test_gymnax_wrappers_run_unmodified(env_id):
    env, params = aej.make(env_id)
    space = env.observation_space(params)
    assert isinstance(space, gymnax_spaces.Box) and isinstance(env.action_space(params), gymnax_spaces.Box)

    # GymnaxToGymWrapper: gymnax converts our boxes to the numba env's Gymnasium boxes
    gym_env = GymnaxToGymWrapper(env, params, seed=0)
    ours = numba_env(env_id).observation_space
    assert isinstance(gym_env.observation_space, gspaces.Box)
    np.testing.assert_array_equal(gym_env.observation_space.low, ours.low)
    np.testing.assert_array_equal(gym_env.observation_space.high, ours.high)
    assert gym_env.action_space == gspaces.Box(-1.0, 1.0, (env.num_actions,), np.float32)
    obs, _ = gym_env.reset(seed=1)
    gym_env.action_space.seed(1)
    for _ in range(STEPS):
        obs, reward, terminated, truncated, _ = gym_env.step(gym_env.action_space.sample())
        assert gym_env.observation_space.contains(np.asarray(obs)) and np.isfinite(float(reward))
        if terminated or truncated:
            break

    # LogWrapper: its running return is the sum of the rewards since the episode began
    logged = LogWrapper(env)

    def rollout(key):
        obs, state = logged.reset(key, params)

        def body(carry, k):
            state, total = carry
            ka, ks = jax.random.split(k)
            action = jnp.sign(env.action_space(params).sample(ka))
            obs, state, reward, terminated, truncated, info = logged.step(ks, state, action, params)
            total = total + reward
            done = terminated | truncated
            out = (info["returned_episode"], info["returned_episode_returns"], total, state.episode_returns, done)
            return (state, jnp.where(done, 0.0, total)), out

        _, outs = jax.lax.scan(body, (state, jnp.zeros((), jnp.float32)), jax.random.split(key, STEPS))
        return outs

    returned, returned_returns, totals, running, done = jax.jit(rollout)(jax.random.key(2))
    np.testing.assert_allclose(np.where(done, 0.0, totals), running, rtol=1e-5)
    np.testing.assert_array_equal(returned, done)
    for i in np.flatnonzero(np.asarray(done)):
        assert np.isclose(returned_returns[i], totals[i], rtol=1e-5)


def test_gymnax_vector_wrapper():
    env, params = aej.make("FuelSlosh-v1")
    vec = GymnaxToVectorGymWrapper(env, num_envs=4, params=params, seed=0)
    assert vec.single_observation_space == numba_env("FuelSlosh-v1").observation_space
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (4, 8)
    ended = 0
    for _ in range(6):  # full pitch moment: every episode crosses a limit within a few decisions
        obs, reward, terminated, truncated, info = vec.step(np.tile([0.0, 1.0], (4, 1)).astype(np.float32))
        assert all(vec.single_observation_space.contains(np.asarray(o)) for o in obs)
        ended += int(np.sum(terminated))
    assert ended >= 4


def test_rejax_ppo_trains_through_done_step():
    """rejax 0.1.3 unpacks gymnax 0.0.x's 5-tuple: a plant fails there as it is and trains
    through :class:`attitude_envs.jax.DoneStep` (a few thousand steps: the contract, not
    the learning)."""
    rejax = pytest.importorskip("rejax")
    env, params = aej.make("LinearSystem-v1")
    kwargs = {"env_params": params, "total_timesteps": 2048, "num_envs": 8, "num_steps": 32, "eval_freq": 1024}
    with pytest.raises(ValueError, match="too many values to unpack"):
        jax.jit(rejax.PPO.create(env=env, **kwargs).train)(jax.random.key(0))
    _, (lengths, returns) = jax.jit(rejax.PPO.create(env=aej.DoneStep(env), **kwargs).train)(jax.random.key(0))
    assert returns.shape[0] == 3 and bool(jnp.all(jnp.isfinite(returns))) and bool(jnp.all(lengths == 80))
