"""Wrappers of the JAX plants: :class:`LastAction`, the observation with the previous command
(the twin of :class:`attitude_envs.wrappers.LastAction`), and :class:`DoneStep`, an adapter for
PureJaxRL-style trainers that step an env with gymnax 0.0.x's 5-tuple.

gymnax 1.0 (and the JAX plants, :mod:`attitude_envs.jax.environment`) returns
``(obs, state, reward, terminated, truncated, info)`` from ``step``. PureJaxRL (Lu et al.
2022) and rejax 0.1.3 were written against gymnax 0.0.x, whose ``step`` returned
``(obs, state, reward, done, info)``; rejax's PPO, SAC and evaluation unpack five values, so
a 1.0 env, gymnax's own Pendulum included, fails there. :class:`DoneStep` gives such a
trainer what it calls:

* ``reset(key, params) -> (obs, state)``;
* ``step(key, state, action, params) -> (obs, state, reward, done, info)`` with
  ``done = terminated or truncated`` (autoreset as before: when ``done``, ``obs`` and
  ``state`` start the next episode);
* ``observation_space(params)``, ``action_space(params)`` (with ``shape``, ``low``,
  ``high``), ``default_params`` (with ``max_steps_in_episode``, which rejax's evaluation
  reads), ``name``, ``num_actions``.

``info`` keeps ``terminated``, ``truncated`` and ``final_observation`` for a trainer that
bootstraps at the time limit; trainers that read only ``done`` (PureJaxRL's PPO, rejax's)
treat the time limit as a terminal state. Anything else is read through to the wrapped env.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.jax.environment import Environment
from attitude_envs.jax.spaces import Box


class Wrapper:
    """A JAX plant ``env`` wrapped: anything not defined here is read through to it (the base of
    the wrappers here and of the JAX twins of training wrappers elsewhere,
    :class:`baselines.residual_jax.LQRResidual`)."""

    def __init__(self, env: Environment) -> None:
        if not isinstance(env, Environment):
            raise ValueError(
                f"env must be a JAX plant of attitude_envs.jax.make(...) (an attitude_envs.jax.Environment), "
                f"got {type(env).__name__}"
            )
        self.env = env

    def __getattr__(self, name: str) -> Any:
        if name == "env":  # not set yet (e.g. during unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.env, name)

    @property
    def default_params(self) -> Any:
        """The wrapped env's default ``EnvParams``."""
        return self.env.default_params


class DoneStep(Wrapper):
    """``env`` (a JAX plant, :func:`attitude_envs.jax.make`) with gymnax 0.0.x's
    ``step -> (obs, state, reward, done, info)``; see the module docstring.

    ``jax.jit`` and ``jax.vmap`` apply as to the env itself (``self`` is static: it hashes by
    identity, as a flax ``struct.field(pytree_node=False)`` needs)."""

    @partial(jax.jit, static_argnames=("self",))
    def reset(self, key: jax.Array, params: Any = None) -> tuple[jax.Array, Any]:
        """A fresh episode drawn with ``key``: ``(obs, state)``."""
        return self.env.reset(key, params)

    @partial(jax.jit, static_argnames=("self",))
    def step(
        self, key: jax.Array, state: Any, action: jax.Array, params: Any = None
    ) -> tuple[jax.Array, Any, jax.Array, jax.Array, dict[str, Any]]:
        """One decision with autoreset: ``(obs, state, reward, done, info)``,
        ``done = terminated | truncated`` (a boolean)."""
        obs, state, reward, terminated, truncated, info = self.env.step(key, state, action, params)
        return obs, state, reward, jnp.logical_or(terminated, truncated), info

    def observation_space(self, params: Any = None) -> Any:
        """The wrapped env's observation space."""
        return self.env.observation_space(params)

    def action_space(self, params: Any = None) -> Any:
        """The wrapped env's action space (``Box(-1, 1)``)."""
        return self.env.action_space(params)

    @property
    def name(self) -> str:
        return self.env.name

    @property
    def num_actions(self) -> int:
        return self.env.num_actions

    def __repr__(self) -> str:
        return f"DoneStep({self.env.name})"


@struct.dataclass
class LastActionState:
    """:class:`LastAction`'s state: the plant's ``env_state`` and the ``last_action`` applied
    (clipped to the action box; zeros at an episode's start)."""

    env_state: Any
    last_action: jax.Array


class LastAction(Wrapper, Environment):
    """``env`` whose observation ends with the previous action, clipped to the action box (zeros
    at an episode's start): the JAX twin of :class:`attitude_envs.wrappers.LastAction`, equal to
    it step for step. Under a command delay of one control period the command in flight is
    part of the state; with it a policy can act on where the plant will be when its command
    acts (the delay-augmented state of Katsikopoulos & Engelbrecht 2003). ``params`` are the
    wrapped env's; ``time`` and the time limit are its."""

    def _with_action(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        return jnp.concatenate([obs, action.astype(obs.dtype)])

    def reset_env(self, key: jax.Array, params: Any):
        obs, env_state = self.env.reset_env(key, params)
        last = jnp.zeros(self.action_space(params).shape, obs.dtype)
        return self._with_action(obs, last), LastActionState(env_state, last)

    def step_env(self, key: jax.Array, state: LastActionState, action: jax.Array, params: Any):
        space = self.action_space(params)
        applied = jnp.clip(action, jnp.asarray(space.low, action.dtype), jnp.asarray(space.high, action.dtype))
        obs, env_state, reward, terminated, info = self.env.step_env(key, state.env_state, action, params)
        applied = applied.astype(obs.dtype)
        return self._with_action(obs, applied), LastActionState(env_state, applied), reward, terminated, info

    def state_from(self, numba_env: Any, *args: Any) -> LastActionState:
        """The JAX state of a numba env's episode played behind
        :class:`attitude_envs.wrappers.LastAction` (anywhere in its wrapper chain): the plant's
        (the wrapped twin's ``state_from``, ``args`` passed on) and the wrapper's last action; a
        ``ValueError`` for an env without that wrapper (its last action is not known)."""
        from attitude_envs.wrappers.last_action import LastAction as GymLastAction

        wrapper = numba_env
        while not isinstance(wrapper, GymLastAction):
            if not hasattr(wrapper, "env"):
                raise ValueError("state_from needs the numba env wrapped in attitude_envs.wrappers.LastAction")
            wrapper = wrapper.env
        return LastActionState(self.env.state_from(wrapper.env, *args), jnp.asarray(wrapper.last_action))

    def is_truncated(self, state: LastActionState, params: Any) -> jax.Array:
        return self.env.is_truncated(state.env_state, params)

    def action_space(self, params: Any = None) -> Box:
        return self.env.action_space(params)

    def observation_space(self, params: Any = None) -> Box:
        """The wrapped env's box, then the action box."""
        obs, act = self.env.observation_space(params), self.env.action_space(params)
        low = np.concatenate([obs.low, np.asarray(act.low, obs.low.dtype)])
        high = np.concatenate([obs.high, np.asarray(act.high, obs.high.dtype)])
        return Box(low, high, (obs.shape[0] + act.shape[0],), obs.dtype)

    @property
    def name(self) -> str:
        return f"LastAction({self.env.name})"
