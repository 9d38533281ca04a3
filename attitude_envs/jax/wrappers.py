"""An adapter for PureJaxRL-style trainers that step an env with gymnax 0.0.x's 5-tuple.

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

from attitude_envs.jax.environment import Environment


class DoneStep:
    """``env`` (a JAX plant, :func:`attitude_envs.jax.make`) with gymnax 0.0.x's
    ``step -> (obs, state, reward, done, info)``; see the module docstring.

    ``jax.jit`` and ``jax.vmap`` apply as to the env itself (``self`` is static: it hashes by
    identity, as a flax ``struct.field(pytree_node=False)`` needs)."""

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
