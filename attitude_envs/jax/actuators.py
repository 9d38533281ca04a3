"""The flight conditions' delay and actuator dynamics (:mod:`attitude_envs.actuator_dynamics`)
as arrays, for the JAX plants.

:meth:`attitude_envs.actuator_dynamics.ActuatorChain.deliver` in JAX: the delay line, then the
stages written once in :func:`attitude_envs.actuator_dynamics.define_chain` (the command
resolution, the rate limit; after the plant's faults the first-order lag as the period mean
of its exact response, the gain times the duty cycle and the wheel friction), traced with
``jax.numpy`` (``np.round`` and ``jnp.round`` both round half to even; the lag's weights ``φ``
and ``e^{−Δt/τ}`` and the rate limiter's step ``rate_limit · Δt`` are the numpy chain's
:func:`~attitude_envs.actuator_dynamics.numbers_of`, bit for bit).

What fixes the compiled program is an :class:`~attitude_envs.actuator_dynamics.ActuatorLayout`
(static: the delay's length and which stages are on); the numbers are an
:class:`ActuatorParams` pytree and the runtime state (the delay line, the rate limiter's last
output and the lag's state) an :class:`ActuatorState`, carried in the env state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from attitude_envs.actuator_dynamics import ActuatorLayout, ActuatorModel, define_chain, layout_of, numbers_of
from attitude_envs.jax.ops import JAX

#: folded into a plant's reset key for its flight draws (the true plant, the actuator gains),
#: so a flight episode's start, target and faults are the lab episode's of the same key (as
#: the numba envs spawn their flight generator without advancing their own)
FLIGHT_STREAM = 0x464C54


_CHAIN = define_chain(JAX)


@struct.dataclass
class ActuatorParams:
    """The numbers of an actuator chain, one entry per actuator: ``limits`` (own units),
    ``resolution`` (0: none), ``rate_step`` (``rate_limit · Δt``; inf: none), ``lag_on``,
    ``mean_weight`` (φ), ``decay`` (``e^{−Δt/τ}``), ``duty``, ``coulomb``, ``viscous``."""

    limits: jax.Array
    resolution: jax.Array
    rate_step: jax.Array
    lag_on: jax.Array
    mean_weight: jax.Array
    decay: jax.Array
    duty: jax.Array
    coulomb: jax.Array
    viscous: jax.Array


@struct.dataclass
class ActuatorState:
    """The chain's runtime state: ``queue`` (``delay_steps`` × N, oldest first: the commands
    still to act), ``last`` (the rate limiter's last output) and ``lagged`` (the lag's state)."""

    queue: jax.Array
    last: jax.Array
    lagged: jax.Array


def chain_layout(layers: Any) -> ActuatorLayout:
    """The static layout of the actuator chain of a numba env's ``layers``
    (:func:`~attitude_envs.envs.base.build_layers`): its model (None: no actuator dynamics),
    the conditions' delay, and scale-factor gains where they are drawn."""
    chain = layers.actuator_chain
    model = None if chain is None else chain.model
    return layout_of(model, layers.conditions.delay_steps, bool(layers.gain_tolerance.any()))


def chain_params(layers: Any, n: int, dt_s: float, dtype) -> ActuatorParams:
    """The arrays of the actuator chain of ``layers`` (``n`` actuators, control period ``dt_s``)."""
    chain = layers.actuator_chain
    return params_of(None if chain is None else chain.model, n, dt_s, dtype)


def params_of(model: ActuatorModel | None, n: int, dt_s: float, dtype) -> ActuatorParams:
    """The arrays of ``model`` (``n`` actuators; None: neutral entries) at the control period
    ``dt_s``: :func:`attitude_envs.actuator_dynamics.numbers_of`, the numpy chain's numbers bit
    for bit."""
    numbers = vars(numbers_of(model, n, dt_s))  # booleans (lag_on) as they are, numbers in ``dtype``
    return ActuatorParams(
        **{k: jnp.asarray(v) if v.dtype == bool else jnp.asarray(v, dtype=dtype) for k, v in numbers.items()}
    )


def initial_state(layout: ActuatorLayout, n: int, dtype) -> ActuatorState:
    """An episode's start: an empty delay line (zero commands), outputs at rest."""
    return ActuatorState(
        queue=jnp.zeros((layout.delay_steps, n), dtype=dtype),
        last=jnp.zeros(n, dtype=dtype),
        lagged=jnp.zeros(n, dtype=dtype),
    )


def command(
    layout: ActuatorLayout, p: ActuatorParams, state: ActuatorState, commanded: jax.Array
) -> tuple[jax.Array, ActuatorState]:
    """Stages 1–3 (:meth:`ActuatorChain.command`): the command the actuators act on this
    period (delayed, then :func:`~attitude_envs.actuator_dynamics.define_chain`'s ``command``)
    and the next state."""
    c, queue = commanded, state.queue
    if layout.delay_steps:
        queue = jnp.concatenate([queue, c[None]], axis=0)
        c, queue = queue[0], queue[1:]
    c, last = _CHAIN.command(layout, p, state.last, c)
    return c, state.replace(queue=queue, last=last)


def output(
    layout: ActuatorLayout,
    p: ActuatorParams,
    state: ActuatorState,
    faulted: jax.Array,
    gain: jax.Array | None,
    speeds: jax.Array,
) -> tuple[jax.Array, ActuatorState]:
    """Stages 5–7 (:meth:`ActuatorChain.output`, then the env's gain without a model): the
    output held over the period, from the faulted command, this episode's ``gain`` (None:
    ones) and the wheel speeds at the period's start; and the next state."""
    y, lagged = _CHAIN.output(layout, p, state.lagged, faulted, gain, speeds)
    return y, state.replace(lagged=lagged)


def deliver(
    layout: ActuatorLayout,
    p: ActuatorParams,
    state: ActuatorState,
    commanded: jax.Array,
    fault: Callable[[jax.Array], tuple[jax.Array, Any]],
    gain: jax.Array | None,
    speeds: jax.Array,
) -> tuple[jax.Array, Any, ActuatorState]:
    """:meth:`ActuatorChain.deliver`: the command's stages 1–3 (:func:`command`), the env's
    actuator faults ``fault(c) -> (faulted, fault state)`` (stage 4), then stages 5–7
    (:func:`output`, ``gain`` and wheel ``speeds`` as there). Returns the delivered command,
    the faults' next state and the chain's."""
    c, state = command(layout, p, state, commanded)
    faulted, fault_state = fault(c)
    delivered, state = output(layout, p, state, faulted, gain, speeds)
    return delivered, fault_state, state


__all__ = [
    "FLIGHT_STREAM",
    "ActuatorLayout",
    "ActuatorParams",
    "ActuatorState",
    "chain_layout",
    "chain_params",
    "command",
    "deliver",
    "initial_state",
    "layout_of",
    "output",
]
