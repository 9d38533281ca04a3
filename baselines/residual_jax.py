"""The JAX plants' twin of :class:`baselines.residual.LQRResidual`, for the fused trainer."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from attitude_envs.jax.environment import Environment
from attitude_envs.jax.make import numba_env
from attitude_envs.jax.wrappers import Wrapper
from baselines.residual import base_lqr, check_scale


@struct.dataclass
class ResidualState:
    """:class:`LQRResidual`'s state: the plant's ``env_state`` and the observation ``obs`` the
    learner last saw, which the LQR acts on."""

    env_state: Any
    obs: jax.Array


class LQRResidual(Wrapper, Environment):
    """``env`` whose action is a residual on the LQR, ``clip(u_LQR(o) + scale · clip(a, −1, 1),
    −1, 1)``, computed as :class:`baselines.residual.WithLQR` computes it on the numba envs'
    float32 observation (the LQR's command rounded to float32 too). Built by :meth:`for_plant`, which designs the LQR on the numba
    env of the same keywords; ``params`` are the wrapped env's."""

    def __init__(self, env: Environment, base, scale: float) -> None:
        super().__init__(env)
        self.n_state = int(base.n_state)
        self.neg_gain_t = -base.gain.T
        self.to_motor_t = base.to_motor.T
        self.max_torque = float(base.max_torque)
        self.scale = check_scale(scale)

    @classmethod
    def for_plant(cls, env: Environment, env_id: str, env_kwargs: dict[str, Any], scale: float = 0.25, **lqr: Any):
        """The twin on the JAX plant ``env`` of ``env_id`` with ``env_kwargs``."""
        return cls(env, base_lqr(numba_env(env_id, **env_kwargs), **lqr), scale)

    def command(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        """The env's action for the residual ``action`` given the observation ``obs``."""
        # the numba envs observe in float32, which the LQR then reads in float64
        x = obs[: self.n_state].astype(jnp.float32).astype(jnp.float64 if jax.config.jax_enable_x64 else jnp.float32)
        motor = (x @ jnp.asarray(self.neg_gain_t, x.dtype)) @ jnp.asarray(self.to_motor_t, x.dtype)
        base = jnp.clip(motor / self.max_torque, -1.0, 1.0).astype(jnp.float32).astype(x.dtype)
        residual = jnp.clip(action.astype(x.dtype), -1.0, 1.0)
        return jnp.clip(base + self.scale * residual, -1.0, 1.0).astype(jnp.float32).astype(action.dtype)

    def reset_env(self, key: jax.Array, params: Any):
        obs, env_state = self.env.reset_env(key, params)
        return obs, ResidualState(env_state, obs)

    def step_env(self, key: jax.Array, state: ResidualState, action: jax.Array, params: Any):
        applied = self.command(state.obs, action)
        obs, env_state, reward, terminated, info = self.env.step_env(key, state.env_state, applied, params)
        return obs, ResidualState(env_state, obs), reward, terminated, info

    def state_from(self, numba_env: Any, *args: Any) -> ResidualState:
        """The JAX state of a numba env's episode played behind
        :class:`baselines.residual.LQRResidual` (anywhere in its wrapper chain): the plant's (the
        wrapped twin's ``state_from``, ``args`` passed on) and the observation last seen."""
        from baselines.residual import LQRResidual as GymLQRResidual

        wrapper = numba_env
        while not isinstance(wrapper, GymLQRResidual):
            if not hasattr(wrapper, "env"):
                raise ValueError("state_from needs the numba env wrapped in baselines.residual.LQRResidual")
            wrapper = wrapper.env
        plant = self.env.state_from(wrapper.env, *args)
        # the numba env observes in float32; the JAX plant in its own float type
        return ResidualState(plant, jnp.asarray(wrapper.last_observation, jnp.result_type(float)))

    def is_truncated(self, state: ResidualState, params: Any) -> jax.Array:
        return self.env.is_truncated(state.env_state, params)

    def action_space(self, params: Any = None):
        return self.env.action_space(params)

    def observation_space(self, params: Any = None):
        return self.env.observation_space(params)

    @property
    def name(self) -> str:
        return f"LQRResidual({self.env.name})"
