"""The JAX plants' space and step conventions, without gymnax installed: the box a gymnax
wrapper converts (a ``gymnax.environments.spaces.Box`` once that module is loaded, here a
stand-in module), the gymnax-1.0 flags (``truncated`` never with ``terminated``), every
returned observation in the space, and :class:`attitude_envs.jax.DoneStep`, the 5-tuple step
PureJaxRL-style trainers (rejax) unpack. gymnax's own wrappers: tests/test_jax_gymnax.py."""

from __future__ import annotations

import pickle
import sys
import types
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import attitude_envs.jax as aej
from attitude_envs.jax import spaces
from attitude_envs.jax.spaces import Box, is_gymnax_space


@pytest.fixture
def fake_gymnax_spaces(monkeypatch):
    """A stand-in ``gymnax.environments.spaces`` module (the two classes the conversion
    tests, ``Space`` and ``Box``), loaded as gymnax's would be."""
    module = types.ModuleType(spaces.GYMNAX_SPACES_MODULE)

    class Space:
        pass

    class GymnaxBox(Space):
        def __init__(self, low, high, shape, dtype=jnp.float32):
            raise AssertionError("our __init__ runs, not gymnax's")

    module.Space, module.Box = Space, GymnaxBox
    monkeypatch.setitem(sys.modules, spaces.GYMNAX_SPACES_MODULE, module)
    return module


def test_box_is_a_gymnax_box_once_gymnax_spaces_are_loaded(fake_gymnax_spaces):
    box = Box(-np.ones(3), np.ones(3), (3,))
    assert isinstance(box, fake_gymnax_spaces.Box) and isinstance(box, Box) and is_gymnax_space(box)
    assert type(box) is type(Box(0.0, 1.0, (2,)))  # one subclass, made once
    assert box.shape == (3,) and box.low.dtype == np.float32 and bool(box.contains(jnp.zeros(3)))
    back = pickle.loads(pickle.dumps(box))  # by the plain class's name
    np.testing.assert_array_equal(back.high, box.high)


def test_box_stands_alone_without_gymnax():
    assert spaces.GYMNAX_SPACES_MODULE not in sys.modules or is_gymnax_space(Box(0.0, 1.0, (1,)))
    if spaces.GYMNAX_SPACES_MODULE not in sys.modules:
        box = Box(0.0, 1.0, (2,))
        assert type(box) is Box and not is_gymnax_space(box)


def test_box_bounds_have_the_observation_precision():
    """float32 bounds (the numba env's exactly): a Gymnasium box from them, as gymnax's
    conversion builds one, gives no precision warning."""
    from gymnasium import spaces as gspaces

    box = Box(np.array([-1.1, -2.0]), np.array([1.1, 2.0]), (2,))
    assert box.low.dtype == box.high.dtype == np.float32
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        converted = gspaces.Box(box.low, box.high, box.shape, box.dtype)
        assert converted == box.to_gymnasium()
    assert Box(0.0, 1.0, (2,), jnp.float64).low.dtype == np.float64


@pytest.fixture(scope="module")
def slosh():
    """FuelSlosh-v1: random actions cross its limits within a few decisions."""
    return aej.make("FuelSlosh-v1")


def _scan(step, params, n_envs: int, n_steps: int, seed: int):
    """A PureJaxRL-style rollout: vmapped reset, then ``lax.scan`` of a vmapped step under
    bang-bang actions; returns the stacked outputs."""
    env = step.__self__
    keys = jax.random.split(jax.random.key(seed), n_envs)
    obs, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

    def body(carry, k):
        states = carry
        ka, ks = jax.random.split(k)
        actions = jnp.sign(jax.random.uniform(ka, (n_envs, env.num_actions), minval=-1.0, maxval=1.0))
        out = jax.vmap(step, in_axes=(0, 0, 0, None))(jax.random.split(ks, n_envs), states, actions, params)
        return out[1], out

    _, outs = jax.lax.scan(body, states, jax.random.split(jax.random.key(seed + 1), n_steps))
    return obs, outs


def test_step_flags_and_observations(slosh):
    """``truncated`` excludes ``terminated`` (the numba envs' rule, not gymnax 1.0.1's);
    every returned observation is in the space, the limit crossings' too (the step returns
    the next episode's first observation; ``final_observation`` holds the crossing's)."""
    env, params = slosh
    space = env.observation_space(params)
    obs0, (obs, _, _, terminated, truncated, info) = jax.jit(lambda: _scan(env.step, params, 16, 30, 0))()
    assert bool(jnp.all(jax.vmap(space.contains)(obs0)))
    assert bool(jnp.all(jax.vmap(jax.vmap(space.contains))(obs)))
    assert int(terminated.sum()) >= 16 and not bool(jnp.any(terminated & truncated))
    np.testing.assert_array_equal(info["terminated"], terminated)
    final = np.asarray(info["final_observation"])[np.asarray(terminated)]
    # the raw crossing: some beyond the box (the numba env clips it; see environment.py)
    assert np.any((final > space.high) | (final < space.low))


def test_done_step_is_the_five_tuple_step(slosh):
    env, params = slosh
    wrapped = aej.DoneStep(env)
    assert wrapped.observation_space(params).shape == env.observation_space(params).shape
    assert wrapped.action_space(params).shape == (2,) and wrapped.num_actions == 2
    assert int(wrapped.default_params.max_steps_in_episode) == 400 and wrapped.name == env.name
    assert wrapped.n_substeps == env.n_substeps  # anything else reads through
    run = jax.jit(lambda: (_scan(env.step, params, 8, 20, 3), _scan(wrapped.step, params, 8, 20, 3)))
    (obs0, six), (obs0_w, five) = run()
    obs, _, reward, terminated, truncated, info = six
    obs_w, _, reward_w, done, info_w = five
    np.testing.assert_array_equal(obs0_w, obs0)
    np.testing.assert_array_equal(obs_w, obs)
    np.testing.assert_array_equal(reward_w, reward)
    np.testing.assert_array_equal(done, terminated | truncated)
    assert done.dtype == jnp.bool_ and bool(done.any())
    np.testing.assert_array_equal(info_w["truncated"], truncated)
    np.testing.assert_array_equal(info_w["final_observation"], info["final_observation"])


def test_done_step_refuses_what_is_not_a_jax_plant():
    with pytest.raises(ValueError, match="env must be a JAX plant"):
        aej.DoneStep("FuelSlosh-v1")


def test_a_crossing_on_the_last_decision_is_terminated_only():
    """The one step where the rule differs from gymnax 1.0.1's (``truncated`` = the time
    limit, whatever ``terminated``): full pitch moment crosses FuelSlosh's rate limit on the
    first decision of a one-decision episode. Here ``terminated`` alone; gymnax's rule would
    set both; ``done`` (DoneStep) is the same under either."""
    env, params = aej.make("FuelSlosh-v1", randomize_initial_state=False, episode_duration_s=0.25)
    assert int(params.max_steps_in_episode) == 1
    _, state = env.reset(jax.random.key(0), params)
    action = jnp.array([0.0, 1.0])
    _, state_st, _, terminated_env, _ = env.step_env(jax.random.key(1), state, action, params)
    assert bool(terminated_env) and bool(env.is_truncated(state_st, params))  # gymnax: both flags
    _, _, _, terminated, truncated, info = env.step(jax.random.key(1), state, action, params)
    assert bool(terminated) and not bool(truncated) and not bool(info["truncated"])
    _, _, _, done, _ = aej.DoneStep(env).step(jax.random.key(1), state, action, params)
    assert bool(done)
