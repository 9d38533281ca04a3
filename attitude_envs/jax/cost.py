"""The termination charge of :meth:`attitude_envs.envs.base.AttitudeEnv.batch_termination_cost`
in JAX (the running cost is each plant's own: it integrates it as its numba kernel does)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from attitude_envs.envs.base import TERMINATION_COSTS

#: the code of each ``termination_cost`` mode in ``EnvParams.termination_mode``
TERMINATION_CODES = {mode: code for code, mode in enumerate(TERMINATION_COSTS)}


def termination_charge(mode: jax.Array, x: jax.Array, Q: jax.Array, horizon, elapsed) -> jax.Array:
    """``xᵀQx`` held over the rest of the horizon (``"hold"``), the whole horizon
    (``"episode"``), or 0 (``"none"``); ``horizon`` and ``elapsed`` in the plant's time
    unit (s, or steps for a discrete-time plant)."""
    held = jnp.where(
        mode == TERMINATION_CODES["episode"],
        horizon,
        jnp.where(mode == TERMINATION_CODES["hold"], jnp.maximum(horizon - elapsed, 0.0), 0.0),
    )
    return (x @ Q @ x) * held


def mode_code(mode: str) -> int:
    """The code of a validated ``termination_cost`` mode."""
    return TERMINATION_CODES[mode]
