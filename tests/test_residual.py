"""Residual RL on the LQR (baselines.residual): the untrained residual is the LQR (the gyrostat's,
and the fuel-slosh paper's on FuelSlosh), the training wrapper and the policy-side twin give the
same commands, the JAX twin equals the wrapper step for step (x64, under flight's delay and
actuators), and a model trained behind the wrapper (the fused trainer, SB3 on FuelSlosh) plays
behind the policy-side twin as its training evaluated it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import trained_model_plays_as_evaluated

import attitude_envs  # noqa: F401
from attitude_envs.evaluation.rollout import rollout
from baselines.lqr import LQRPolicy
from baselines.residual import LQRResidual, SloshLQRResidual, WithLQR, WithSloshLQR
from baselines.slosh import SloshLQRPolicy

AB = "attitude_envs/AirBearing-v1"
FS = "attitude_envs/FuelSlosh-v1"
#: the delay and the actuators' dynamics, without sensors or drawn parameters
NO_NOISE = {"base": "flight", "sensors": 0, "parameters": 0}


class Constant:
    """A policy that plays the given actions in turn."""

    def __init__(self, actions):
        self.actions, self.i = actions, 0

    def reset(self, seed=None):
        self.i = 0

    def act(self, obs, info):
        self.i += 1
        return self.actions[self.i - 1]


#: (env id, its keywords, the policy-side twin, its training wrapper, the base policy, the name's suffix)
PLANTS = {
    "air-bearing": (AB, {"conditions": NO_NOISE}, WithLQR, LQRResidual, LQRPolicy, "lqr"),
    # at the LQR's own 0.1 s, with the campaign's thruster faults from 5 s
    "fuel-slosh": (
        FS,
        {
            "control_dt_s": 0.1,
            "episode_duration_s": 20.0,
            "faults": [
                {"kind": "loss_of_effectiveness", "target": "actuator", "index": 0, "value": 0.5, "onset_s": 5.0},
                {"kind": "bias", "target": "actuator", "index": 1, "value": 200.0, "onset_s": 5.0},
            ],
        },
        WithSloshLQR,
        SloshLQRResidual,
        SloshLQRPolicy,
        "slosh-lqr",
    ),
}


@pytest.mark.parametrize("plant", PLANTS)
def test_the_untrained_residual_is_the_lqr_and_the_sum_is_clipped(plant):
    env_id, kwargs, twin, _, base, suffix = PLANTS[plant]
    env = gym.make(env_id, **kwargs)
    n = env.action_space.shape[0]
    zero = twin(Constant(np.zeros((400, n), np.float32)), env, scale=0.5)
    lqr = base(env)
    assert rollout(env, zero, seed=4)["J"] == rollout(env, lqr, seed=4)["J"]
    obs, info = env.reset(seed=4)
    full = twin(Constant(np.full((1, n), 7.0)), env, scale=0.5).act(obs, info)
    np.testing.assert_array_equal(full, np.clip(lqr.act(obs, info) + 0.5, -1.0, 1.0))
    assert zero.name == f"Constant+{suffix}"


@pytest.mark.parametrize("plant", PLANTS)
def test_the_wrapper_and_the_policy_twin_give_the_same_episode(plant):
    env_id, kwargs, twin, wrapper, _, _ = PLANTS[plant]
    env = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(1).uniform(-1.2, 1.2, (400, env.action_space.shape[0])).astype(np.float32)
    played = rollout(env, twin(Constant(actions), env, scale=0.3), seed=2)["J"]
    wrapped = wrapper(gym.make(env_id, **kwargs), scale=0.3)
    wrapped.reset(seed=2)
    total, i = 0.0, 0
    while True:
        _, r, term, trunc, _ = wrapped.step(actions[i])
        total, i = total - r, i + 1
        if term or trunc:
            break
    assert total == pytest.approx(played, rel=1e-12)


@pytest.mark.parametrize("bad", [{"scale": 0.0}, {"scale": 3.0}, {"delay_steps": 1}])
def test_bad_settings_are_named(bad):
    with pytest.raises(ValueError, match="scale|delay_steps"):
        LQRResidual(gym.make(AB), **bad)


@pytest.mark.parametrize("bad", [{"scale": -0.1}, {"scale": 2.5}, {"weights": "heavy"}])
def test_bad_slosh_settings_are_named(bad):
    with pytest.raises(ValueError, match="scale|weights"):
        SloshLQRResidual(gym.make(FS), **bad)


def _twin_steps_as_the_wrapper(env, wrapped, params, actions) -> int:
    """Steps the JAX twin ``env`` (x64) from the numba ``wrapped`` env's reset state beside it
    with ``actions``; asserts each step equal (the observation to the numba env's float32
    rounding) and returns the steps taken, to the episode's end at most."""
    import jax
    import jax.numpy as jnp

    from baselines.residual_jax import ResidualState

    state = env.state_from(wrapped)
    assert isinstance(state, ResidualState)
    assert state.obs.dtype == env.reset_env(jax.random.PRNGKey(0), params)[0].dtype  # a scan carries it
    step = jax.jit(env.step_env)
    key = jax.random.PRNGKey(0)
    for i, a in enumerate(actions):
        obs_j, state, reward, terminated, _ = step(key, state, jnp.asarray(a, jnp.float64), params)
        obs, r, term, trunc, _ = wrapped.step(a)
        np.testing.assert_allclose(np.asarray(obs_j, np.float32), obs, rtol=2e-7, atol=1e-9, err_msg=str(i))
        assert float(reward) == pytest.approx(r, rel=1e-10) and bool(terminated) == term
        if term or trunc:
            return i + 1
    return len(actions)


def test_the_jax_twin_equals_the_wrapper_step_for_step():
    jax = pytest.importorskip("jax")
    pytest.importorskip("flax")

    from attitude_envs.jax import make
    from attitude_envs.jax.make import numba_env
    from baselines.residual_jax import LQRResidual as JaxLQRResidual

    actions = np.random.default_rng(0).uniform(-1.5, 1.5, (60, 3)).astype(np.float32)
    with jax.enable_x64(True):
        plant, params = make("AirBearing-v1", conditions=NO_NOISE)
        env = JaxLQRResidual.for_plant(plant, "AirBearing-v1", {"conditions": NO_NOISE}, scale=0.3)
        wrapped = LQRResidual(numba_env("AirBearing-v1", conditions=NO_NOISE), scale=0.3)
        wrapped.reset(seed=3)
        # to the episode's end: the delay and the actuators acted
        assert _twin_steps_as_the_wrapper(env, wrapped, params, actions) > 20
    with pytest.raises(ValueError, match="wrapped in baselines.residual.LQRResidual"):
        env.state_from(numba_env("AirBearing-v1"))


def test_the_slosh_jax_twin_equals_the_wrapper_step_for_step_under_a_fault():
    jax = pytest.importorskip("jax")
    pytest.importorskip("flax")
    import jax.numpy as jnp

    from attitude_envs.jax import make
    from attitude_envs.jax.make import numba_env
    from baselines.residual_jax import SloshLQRResidual as JaxSloshLQRResidual

    kwargs = {
        "control_dt_s": 0.1,
        "faults": [{"kind": "bias", "target": "actuator", "index": 1, "value": 150.0, "onset_s": 5.0}],
    }
    actions = np.random.default_rng(1).uniform(-0.3, 0.3, (150, 2)).astype(np.float32)
    with jax.enable_x64(True):
        plant, params = make("FuelSlosh-v1", **kwargs)
        env = JaxSloshLQRResidual.for_plant(plant, "FuelSlosh-v1", kwargs, scale=0.1)
        wrapped = SloshLQRResidual(numba_env("FuelSlosh-v1", **kwargs), scale=0.1)
        wrapped.reset(seed=3)
        # the whole stretch, the fault's onset (step 50) included
        assert _twin_steps_as_the_wrapper(env, wrapped, params, actions) == 150
    with pytest.raises(ValueError, match="wrapped in baselines.residual.SloshLQRResidual"):
        env.state_from(numba_env("FuelSlosh-v1"))
    with pytest.raises(ValueError, match="8 or 4 entries"):
        env.base_command(jnp.zeros(5))
    with pytest.raises(ValueError, match="inversion must be 'nonlinear'"):
        JaxSloshLQRResidual.for_plant(plant, "FuelSlosh-v1", {}, inversion="linear")


def test_the_fused_trainer_trains_behind_the_twin_and_the_model_plays_behind_the_policy_twin(tmp_path, monkeypatch):
    overrides = {
        "n_envs": 2,
        "n_steps": 8,
        "batch_size": 16,
        "n_epochs": 1,
        "gamma": 0.875,
        "env_wrapper": {"baselines.residual.LQRResidual": {"scale": 0.3}},
    }
    policy, _ = trained_model_plays_as_evaluated(
        tmp_path, monkeypatch, AB, overrides, 32, 16, env_kwargs={"episode_duration_s": 4.0}
    )
    assert isinstance(policy, WithLQR) and policy.scale == 0.3


def test_the_fused_trainer_trains_behind_the_slosh_twin_and_the_model_plays_behind_its_policy_twin(
    tmp_path, monkeypatch
):
    overrides = {
        "n_envs": 2,
        "n_steps": 16,
        "batch_size": 32,
        "n_epochs": 1,
        "gamma": 0.95,
        "env_wrapper": {"baselines.residual.SloshLQRResidual": {"scale": 0.2}},
    }
    kwargs = {"control_dt_s": 0.1, "episode_duration_s": 5.0}
    policy, _ = trained_model_plays_as_evaluated(tmp_path, monkeypatch, FS, overrides, 64, 32, kwargs)
    assert isinstance(policy, WithSloshLQR) and policy.scale == 0.2


def test_sb3_trains_behind_the_slosh_residual_and_the_model_plays_behind_its_twin(tmp_path, monkeypatch):
    overrides = {
        "n_envs": 1,
        "n_steps": 32,
        "batch_size": 32,
        "n_epochs": 1,
        "gamma": 0.95,
        "env_wrapper": {"baselines.residual.SloshLQRResidual": {"scale": 0.2}},
    }
    kwargs = {"control_dt_s": 0.1, "episode_duration_s": 5.0}
    policy, _ = trained_model_plays_as_evaluated(tmp_path, monkeypatch, FS, overrides, 64, 32, kwargs, backend="sb3")
    assert isinstance(policy, WithSloshLQR) and policy.scale == 0.2
