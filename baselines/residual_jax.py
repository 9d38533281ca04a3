"""The JAX plants' twins of the residual wrappers of :mod:`baselines.residual`, for the fused
trainer: :class:`LQRResidual` (the gyrostat's LQR) and :class:`SloshLQRResidual` (the fuel-slosh
LQR with its input inversion)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.jax.environment import Environment
from attitude_envs.jax.make import numba_env
from attitude_envs.jax.ops import JAX
from attitude_envs.jax.wrappers import Wrapper
from attitude_envs.plants import slosh
from attitude_envs.plants.slosh_definition import define
from attitude_envs.plants.slosh_model import INVERSION_ITERATIONS, REDUCED_INDEX
from baselines import residual
from baselines.residual import base_lqr, check_scale
from baselines.slosh import SloshLQRPolicy, observes_slosh

_SLOSH = define(JAX)


@struct.dataclass
class ResidualState:
    """A :class:`ResidualTwin`'s state: the plant's ``env_state`` and the observation ``obs`` the
    learner last saw, which the base policy acts on."""

    env_state: Any
    obs: jax.Array


class ResidualTwin(Wrapper, Environment):
    """``env`` whose action is a residual on a base policy, ``clip(u_base(o) + scale · clip(a,
    −1, 1), −1, 1)``, computed as the Gymnasium wrapper :attr:`gym_wrapper` (a
    :class:`baselines.residual.ResidualWrapper`) computes it on the numba envs' float32
    observation (the base command rounded to float32 too). Subclasses give the base command
    (:meth:`base_command`) and build it in :meth:`for_plant` from the numba env of the same
    keywords; ``params`` are the wrapped env's."""

    #: the Gymnasium wrapper this twins
    gym_wrapper: type[residual.ResidualWrapper]

    def __init__(self, env: Environment, scale: float) -> None:
        super().__init__(env)
        self.scale = check_scale(scale)

    def base_command(self, obs: jax.Array) -> jax.Array:
        """The base policy's action (float32 values) for the float32-rounded observation ``obs``."""
        raise NotImplementedError

    def command(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        """The env's action for the residual ``action`` given the observation ``obs``."""
        # the numba envs observe in float32, which the base policy then reads in float64
        x = obs.astype(jnp.float32).astype(jnp.float64 if jax.config.jax_enable_x64 else jnp.float32)
        base = self.base_command(x).astype(jnp.float32).astype(x.dtype)
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
        """The JAX state of a numba env's episode played behind the Gymnasium wrapper
        :attr:`gym_wrapper` (anywhere in its wrapper chain): the plant's (the wrapped twin's
        ``state_from``, ``args`` passed on) and the observation last seen."""
        wrapper = numba_env
        while not isinstance(wrapper, self.gym_wrapper):
            if not hasattr(wrapper, "env"):
                raise ValueError(
                    f"state_from needs the numba env wrapped in baselines.residual.{self.gym_wrapper.__name__}"
                )
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
        return f"{type(self).__name__}({self.env.name})"


class LQRResidual(ResidualTwin):
    """The twin of :class:`baselines.residual.LQRResidual`: the base is the gyrostat's LQR,
    designed by :meth:`for_plant` on the numba env of the same keywords."""

    gym_wrapper = residual.LQRResidual

    def __init__(self, env: Environment, base, scale: float) -> None:
        super().__init__(env, scale)
        self.n_state = int(base.n_state)
        self.neg_gain_t = -base.gain.T
        self.to_motor_t = base.to_motor.T
        self.max_torque = float(base.max_torque)

    @classmethod
    def for_plant(cls, env: Environment, env_id: str, env_kwargs: dict[str, Any], scale: float = 0.25, **lqr: Any):
        """The twin on the JAX plant ``env`` of ``env_id`` with ``env_kwargs``."""
        return cls(env, base_lqr(numba_env(env_id, **env_kwargs), **lqr), scale)

    def base_command(self, obs: jax.Array) -> jax.Array:
        x = obs[: self.n_state]
        motor = (x @ jnp.asarray(self.neg_gain_t, x.dtype)) @ jnp.asarray(self.to_motor_t, x.dtype)
        return jnp.clip(motor / self.max_torque, -1.0, 1.0)


class SloshLQRResidual(ResidualTwin):
    """The twin of :class:`baselines.residual.SloshLQRResidual`: the base is Navabi & Davoodi's
    LQR (:class:`baselines.slosh.SloshLQRPolicy`) with its nonlinear input inversion (the plant
    definition's ``invert_inputs`` on the nominal model), designed by :meth:`for_plant` on the
    numba env of the same keywords."""

    gym_wrapper = residual.SloshLQRResidual

    def __init__(self, env: Environment, base: SloshLQRPolicy, scale: float) -> None:
        super().__init__(env, scale)
        if base.inversion != "nonlinear":
            raise ValueError(
                f"the JAX twin inverts the inputs exactly: inversion must be 'nonlinear', got {base.inversion!r}"
            )
        self.neg_gain = -np.asarray(base.gain, float)
        self.packed = np.asarray(base.params.packed, float)
        self.limits = np.array([base.model.max_gimbal_rad, base.model.max_moment_nm])

    @classmethod
    def for_plant(cls, env: Environment, env_id: str, env_kwargs: dict[str, Any], scale: float = 0.25, **lqr: Any):
        """The twin on the JAX plant ``env`` of ``env_id`` with ``env_kwargs``."""
        return cls(env, SloshLQRPolicy(numba_env(env_id, **env_kwargs), **lqr), scale)

    def base_command(self, obs: jax.Array) -> jax.Array:
        if observes_slosh(obs.shape[-1]):  # split_observation's layouts
            x, v_x = obs[:7], obs[7]
        else:
            x, v_x = jnp.zeros(7, obs.dtype).at[:3].set(obs[:3]), obs[3]
        u = jnp.asarray(self.neg_gain, x.dtype) @ x
        # the full state the numpy policy hands the inversion: x in place, v_x, the rest 0
        y = jnp.zeros(10, x.dtype).at[jnp.asarray(REDUCED_INDEX)].set(x).at[slosh.IVX].set(v_x)
        delta, moment, _ = _SLOSH.invert_inputs(jnp.asarray(self.packed, x.dtype), y, u[0], u[1], INVERSION_ITERATIONS)
        return jnp.clip(jnp.stack([delta, moment]) / jnp.asarray(self.limits, x.dtype), -1.0, 1.0)
