"""The JAX executor of the plant definitions (:mod:`attitude_envs.plants.ops`): a definition
called with traced arrays builds the twin's equations (helpers stay Python and are traced)."""

from __future__ import annotations

import jax.numpy as jnp

from attitude_envs.plants.ops import library_ops

#: traced ``jax.numpy``
JAX = library_ops("jax", jnp)
