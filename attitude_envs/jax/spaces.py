"""The one space the JAX plants use: a box, with gymnax's ``Box`` interface."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


class Box:
    """A box ``[low, high]`` of shape ``shape`` (gymnax's ``spaces.Box``: ``sample(key)``,
    ``contains(x)``, ``low``, ``high``, ``shape``, ``dtype``). Unbounded entries are ±inf."""

    def __init__(self, low, high, shape: tuple[int, ...], dtype=jnp.float32) -> None:
        self.shape = tuple(int(s) for s in shape)
        self.dtype = dtype
        self.low = np.broadcast_to(np.asarray(low, dtype=np.float64), self.shape).copy()
        self.high = np.broadcast_to(np.asarray(high, dtype=np.float64), self.shape).copy()

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform draw (a standard normal where unbounded), of ``dtype``."""
        low = jnp.asarray(self.low, dtype=self.dtype)
        high = jnp.asarray(self.high, dtype=self.dtype)
        u = jax.random.uniform(key, self.shape, dtype=self.dtype)
        if np.isfinite(self.low).all() and np.isfinite(self.high).all():  # the same draw, no normal to compile
            return low + u * (high - low)
        bounded = jnp.isfinite(low) & jnp.isfinite(high)
        n = jax.random.normal(jax.random.fold_in(key, 1), self.shape, dtype=self.dtype)
        return jnp.where(bounded, low + u * (jnp.where(bounded, high, 1) - jnp.where(bounded, low, 0)), n)

    def contains(self, x) -> jax.Array:
        x = jnp.asarray(x)
        return jnp.logical_and(jnp.all(x >= self.low), jnp.all(x <= self.high))

    def to_gymnasium(self):
        """The same box as a ``gymnasium.spaces.Box``."""
        from gymnasium import spaces

        return spaces.Box(self.low.astype(np.float32), self.high.astype(np.float32), self.shape, np.float32)

    def __repr__(self) -> str:
        return f"Box(shape={self.shape}, dtype={jnp.dtype(self.dtype).name})"
