"""JAX-native plants in gymnax 1.0's API (the optional ``jax`` extra).

``env, params = attitude_envs.jax.make("AirBearing-v1")``, then ``env.reset(key, params)``
and ``env.step(key, state, action, params)`` as in gymnax; ``jax.vmap`` and ``jax.jit`` over
keys, states and params. Each plant steps as its numba env does (a test checks them against
each other with ``jax_enable_x64``). Only this subpackage imports jax.
"""

try:
    import flax  # noqa: F401
    import jax  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised without the extra
    raise ImportError(
        "attitude_envs.jax needs the optional packages jax and flax: pip install 'attitude-envs[jax]'"
    ) from exc

from attitude_envs.jax.environment import Environment
from attitude_envs.jax.make import make
from attitude_envs.jax.spaces import Box
from attitude_envs.jax.wrappers import DoneStep

__all__ = ["Box", "DoneStep", "Environment", "make"]
