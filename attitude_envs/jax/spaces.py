"""The one space the JAX plants use: a box, with gymnax's ``Box`` interface.

gymnax's ``GymnaxToGymWrapper`` and ``GymnaxToVectorGymWrapper`` convert only gymnax's own
space types (``gymnax_space_to_gym_space``: "Conversion of Box not supported" for any
other). Once gymnax's spaces module is imported (importing ``gymnax`` or its wrappers does),
every :class:`Box` built is an instance of a subclass of both :class:`Box` and
``gymnax.environments.spaces.Box``, so those wrappers take the JAX plants unmodified (the
plants build their spaces at each ``observation_space(params)`` call). gymnax is neither
imported here (its import takes seconds: it loads all its envs, seaborn included) nor a
dependency (its 1.0.1 pins ``gymnasium<1.4``; the JAX guide shows how to install it beside
gymnasium 1.4).
"""

from __future__ import annotations

import functools
import sys

import jax
import jax.numpy as jnp
import numpy as np

#: the module whose ``Box`` a :class:`Box` also is, once imported
GYMNAX_SPACES_MODULE = "gymnax.environments.spaces"


@functools.cache
def _with_gymnax_base(gymnax_box: type) -> type:
    """:class:`Box` that is also a ``gymnax_box`` (our methods first), made once."""
    return type("Box", (Box, gymnax_box), {"__module__": __name__, "__qualname__": "Box", "__slots__": ()})


class Box:
    """A box ``[low, high]`` of shape ``shape`` (gymnax's ``spaces.Box``: ``sample(key)``,
    ``contains(x)``, ``low``, ``high``, ``shape``, ``dtype``). Unbounded entries are ±inf.

    ``low`` and ``high`` are numpy arrays of ``dtype`` (the observation's own precision: the
    float32 bounds of the numba env's ``gymnasium.spaces.Box``, or float64 under
    ``jax_enable_x64``), so :meth:`to_gymnasium` and gymnax's conversion build a Gymnasium box
    without a precision warning.

    ``Box(...)`` returns a ``gymnax.environments.spaces.Box`` as well where gymnax's spaces
    module has been imported (see the module docstring); ``is_gymnax_space(box)`` says which."""

    def __new__(cls, *args, **kwargs):
        gymnax_spaces = sys.modules.get(GYMNAX_SPACES_MODULE)
        if cls is Box and gymnax_spaces is not None:
            cls = _with_gymnax_base(gymnax_spaces.Box)
        return super().__new__(cls)

    def __reduce__(self):  # the plain class by name: the gymnax subclass is made at run time
        return (Box, (self.low, self.high, self.shape, self.dtype))

    def __init__(self, low, high, shape: tuple[int, ...], dtype=jnp.float32) -> None:
        self.shape = tuple(int(s) for s in shape)
        self.dtype = dtype
        np_dtype = np.dtype(dtype)
        self.low = np.broadcast_to(np.asarray(low, dtype=np_dtype), self.shape).copy()
        self.high = np.broadcast_to(np.asarray(high, dtype=np_dtype), self.shape).copy()

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
        """Whether every entry of ``x`` lies in ``[low, high]`` (a boolean scalar)."""
        x = jnp.asarray(x)
        return jnp.logical_and(jnp.all(x >= self.low), jnp.all(x <= self.high))

    def to_gymnasium(self):
        """The same box as a ``gymnasium.spaces.Box`` (float32, as the numba envs')."""
        from gymnasium import spaces

        return spaces.Box(self.low.astype(np.float32), self.high.astype(np.float32), self.shape, np.float32)

    def __repr__(self) -> str:
        return f"Box(shape={self.shape}, dtype={jnp.dtype(self.dtype).name})"


def is_gymnax_space(space: object) -> bool:
    """Whether ``space`` is a ``gymnax.environments.spaces.Space`` (False while gymnax's
    spaces module is not imported)."""
    gymnax_spaces = sys.modules.get(GYMNAX_SPACES_MODULE)
    return gymnax_spaces is not None and isinstance(space, gymnax_spaces.Space)
