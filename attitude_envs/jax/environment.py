"""The base of the JAX-native plants: gymnax 1.0's ``Environment`` API, mirrored.

gymnax 1.0.1 pins ``gymnasium<1.4`` and this suite pins gymnasium 1.4, so the API is
reproduced here rather than inherited (same method names, signatures, return values and
autoreset semantics as ``gymnax.environments.environment.Environment``):

* ``env.reset(key, params) -> (obs, state)``
* ``env.step(key, state, action, params) -> (obs, state, reward, terminated, truncated, info)``;
  when the step ends the episode (``terminated`` at a limit, ``truncated`` at the time limit)
  the returned ``obs`` and ``state`` are those of a fresh episode drawn with the step's key,
  and ``info["final_observation"]`` holds the last observation of the episode that ended;
  ``info["terminated"]``, ``info["truncated"]`` repeat the flags.
* ``env.action_space(params)``, ``env.observation_space(params)``,
  ``env.default_params``, ``env.name``, ``env.num_actions``. The spaces are
  :class:`attitude_envs.jax.spaces.Box`, a ``gymnax.environments.spaces.Box`` where gymnax is
  installed, so gymnax's ``GymnaxToGymWrapper``, ``GymnaxToVectorGymWrapper`` and
  ``LogWrapper`` take these envs unmodified.

One difference from gymnax 1.0.1, on purpose: ``truncated`` is the time limit of an episode
that did *not* end at a limit (``truncated = time limit and not terminated``), as in the
numba envs, where gymnax sets ``truncated = state.time >= max_steps_in_episode`` whatever
``terminated`` says. The two differ only on a step that crosses a limit on an episode's last
decision: gymnax would report both flags; here only ``terminated``. A trainer that
bootstraps ``γ·V(final_observation)`` where ``truncated`` (the fused PPO trainer, SB3's
time-limit handling) must not bootstrap past a limit crossing, and ``done = terminated or
truncated`` is the same under either rule. :class:`~attitude_envs.jax.wrappers.DoneStep` adapts
the envs to the 5-tuple ``step`` of PureJaxRL-style trainers (rejax).

An action that is not finite (NaN or inf) cannot raise inside a compiled program: the step
that takes it ends the episode (``terminated``; the reward it returns is NaN, and
``info["invalid_action"]`` is set), and the autoreset starts a fresh episode, so no NaN state
carries over. An action of the wrong shape, or another plant's ``EnvParams``, raises a
``ValueError`` when the step is traced (:meth:`Environment.check_step_arguments`).

``info["final_observation"]`` is the plant's last observation as ``step_env`` computed it. On a
step that crosses a limit it may lie beyond ``observation_space`` (the numba env returns that
observation clipped to its box; no policy acts on it, and only ``truncated`` steps, which
cross no limit, read it for a bootstrap); every ``obs`` that ``step`` and ``reset`` return
lies in the space.

A plant subclasses :class:`Environment` and implements ``step_env`` and ``reset_env``. What
fixes array shapes or the compiled program's branches (wheel count, sub-steps, observation
layout) is an attribute of the env object, static under ``jax.jit``; every number that may
vary between plants, faults or tasks lives in the ``EnvParams`` pytree, so ``jax.vmap`` over
params randomizes plants and faults in one compiled program.

Every env reports ``info["cost"]``, the running cost J accrued over the step (the reward is
``-cost``, termination charge included), and ``info["time_s"]``, the time at the step's end.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache, partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct


@struct.dataclass
class EnvState:
    """The state every plant's carries: ``time``, the decisions taken in the episode."""

    time: jax.Array


@struct.dataclass
class EnvParams:
    """The parameters every plant's carries: ``max_steps_in_episode`` (decisions)."""

    max_steps_in_episode: int = 1


class Environment:
    """gymnax 1.0's environment API (see the module docstring). A plant sets
    ``_default_params`` at construction; :attr:`default_params` returns it."""

    _default_params: Any = None

    @property
    def default_params(self) -> Any:
        """The params of the plant's keywords (:func:`attitude_envs.jax.make`)."""
        if self._default_params is None:
            raise NotImplementedError(f"{type(self).__name__} sets no default params")
        return self._default_params

    @partial(jax.jit, static_argnames=("self",))
    def step(self, key: jax.Array, state: Any, action: jax.Array, params: Any = None):
        """One decision with autoreset (gymnax 1.0's ``step``): ``(obs, state, reward,
        terminated, truncated, info)``. ``truncated`` is the time limit and not ``terminated``
        (gymnax 1.0.1 sets it at the time limit whatever ``terminated`` says; see the module
        docstring); when either is set, ``obs`` and ``state`` start the next episode, drawn with
        this step's key, and ``info["final_observation"]`` is the ended episode's last."""
        if params is None:
            params = self.default_params
        self.check_step_arguments(action, params)
        key_step, key_reset = jax.random.split(key)
        obs_st, state_st, reward, terminated, info = self.step_env(key_step, state, action, params)
        # a non-finite action cannot raise under jit: it ends the episode, flagged (the reward stays NaN)
        invalid = jnp.logical_not(jnp.all(jnp.isfinite(action)))
        terminated = jnp.logical_or(terminated, invalid)
        truncated = jnp.logical_and(self.is_truncated(state_st, params), jnp.logical_not(terminated))
        done = jnp.logical_or(terminated, truncated)
        obs_re, state_re = self.reset_env(key_reset, params)
        state = jax.tree.map(lambda x, y: jax.lax.select(done, x, y), state_re, state_st)
        obs = jax.lax.select(done, obs_re, obs_st)
        info = {
            **info,
            "terminated": terminated,
            "truncated": truncated,
            "final_observation": obs_st,
            "invalid_action": invalid,
        }
        return obs, state, reward, terminated, truncated, info

    def check_step_arguments(self, action: Any, params: Any) -> None:
        """``ValueError`` unless ``params`` is this env's ``EnvParams`` class and ``action`` has
        the action space's shape ``(n,)``: one decision, not a batch (``jax.vmap`` the step
        for a batch). Shapes and types are static under ``jax.jit``, so this raises when the
        step is traced, not in the compiled program. The gyrostats' ReactionWheel and
        AirBearing share one ``EnvParams`` class, so their params are not told apart here."""
        try:
            expected = type(self.default_params)
        except ValueError:  # a plant built without default params: nothing to compare with
            expected = None
        if expected is not None and not isinstance(params, expected):
            raise ValueError(
                f"params must be {self.name}'s {expected.__module__}.{expected.__qualname__} (from "
                f"attitude_envs.jax.make or env.default_params), got {type(params).__module__}."
                f"{type(params).__qualname__}"
            )
        n = tuple(self.action_space(params).shape)
        shape = tuple(jnp.shape(action))
        if shape != n:
            raise ValueError(
                f"action must have shape {n} (one decision of {self.name}, each in [-1, 1]; jax.vmap the step "
                f"for a batch), got shape {shape}"
            )

    @partial(jax.jit, static_argnames=("self",))
    def reset(self, key: jax.Array, params: Any = None):
        """A fresh episode drawn with ``key`` (gymnax 1.0's ``reset``)."""
        if params is None:
            params = self.default_params
        return self.reset_env(key, params)

    def step_env(self, key: jax.Array, state: Any, action: jax.Array, params: Any):
        """The plant's step without autoreset: ``(obs, state, reward, terminated, info)``."""
        raise NotImplementedError

    def reset_env(self, key: jax.Array, params: Any):
        """The plant's episode draw: ``(obs, state)``."""
        raise NotImplementedError

    def is_truncated(self, state: Any, params: Any) -> jax.Array:
        """The time limit: ``state.time >= params.max_steps_in_episode``."""
        return state.time >= params.max_steps_in_episode

    @property
    def name(self) -> str:
        return type(self).__name__

    @property
    def num_actions(self) -> int:
        return int(self.action_space(self.default_params).shape[0])

    def action_space(self, params: Any = None):
        raise NotImplementedError

    def observation_space(self, params: Any = None):
        raise NotImplementedError


def episode_decisions(episode_duration_s: float, control_dt_s: float) -> int:
    """The decisions after which the numba envs truncate (both in s): the least ``n ≥ 1`` with
    ``n · control_dt_s ≥ episode_duration_s − 10⁻⁹ · control_dt_s`` in float64, their
    time-limit test."""
    threshold = episode_duration_s - 1e-9 * control_dt_s
    n = max(1, math.ceil(threshold / control_dt_s))
    while n > 1 and (n - 1) * control_dt_s >= threshold:
        n -= 1
    while n * control_dt_s < threshold:
        n += 1
    return n


def drawn_arrays(flight: Any, drawn: dict, shapes: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    """The entries ``shapes`` names of a numba flight episode's ``drawn`` parameters
    (``env.unwrapped.drawn_parameters()``) as float arrays of those shapes, for a twin's
    ``with_drawn_parameters``; a ``ValueError`` for lab params (``flight`` None), a missing
    entry or a wrong shape."""
    if flight is None:
        raise ValueError("with_drawn_parameters takes the params of a flight env (conditions with parameter draws)")
    missing = [k for k in shapes if k not in drawn]
    if missing:
        raise ValueError(
            f"drawn parameters lack {missing} (got {sorted(drawn)}): pass env.unwrapped.drawn_parameters()"
        )
    out = {k: np.asarray(drawn[k], dtype=float) for k in shapes}
    for k, shape in shapes.items():
        if out[k].shape != tuple(shape):
            raise ValueError(f"drawn {k} must have shape {tuple(shape)}, got {out[k].shape}")
    return out


def check_state_from(sensors: bool, chain: Any, steps: int) -> None:
    """A ``ValueError`` unless a numba env's episode can become a twin's state: no sensors
    (the numba sensor layer's samples are not public) and, with a delay or actuator dynamics
    (``chain``, an :class:`~attitude_envs.jax.actuators.ActuatorLayout` or None), no step
    taken yet (the chain's state is not public either); ``steps``: the steps it has taken."""
    if sensors:
        raise ValueError(
            "state_from does not take an env with sensors: the numba sensor layer's samples are not public "
            "(reset the JAX env instead)"
        )
    if chain is not None and steps and (chain.delay_steps or chain.model):
        raise ValueError(
            "state_from takes a flight env with a delay or actuator dynamics only right after its reset "
            f"(time=0, the actuator chain at rest), got {steps} steps taken"
        )


def preset_defaults(config: Callable[[], Any], params_of: Callable[[Any], Any]) -> Callable[[str], Any]:
    """``field(group)``: a params field whose default is ``group`` of ``params_of(config())``,
    the default preset's params. ``config`` (called once, cached) is the numba env's validated
    configuration; the arrays are made when a params object is, in the dtype then in force."""
    config = cache(config)

    def field(group: str) -> Any:
        return struct.field(default_factory=lambda: getattr(params_of(config()), group))

    return field
