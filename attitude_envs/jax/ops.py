"""The JAX executor of the plant definitions (:mod:`attitude_envs.plants.ops`): a definition
called with traced arrays builds the twin's equations (helpers stay Python and are traced)."""

from __future__ import annotations

import jax.numpy as jnp

from attitude_envs.plants.ops import Ops

#: traced ``jax.numpy``
JAX = Ops(
    "jax",
    sin=jnp.sin,
    cos=jnp.cos,
    sqrt=jnp.sqrt,
    fabs=jnp.abs,
    where=jnp.where,
    fmin=jnp.minimum,
    fmax=jnp.maximum,
    round=jnp.round,
    sign=jnp.sign,
)
