"""``attitude_envs.jax.make(env_id, **kwargs) -> (env, env_params)``.

The keywords are the numba env's: ``make`` builds the numba env with them (so the same
validation, presets and derived parameters serve both) and reads the JAX plant's static
layout and ``EnvParams`` from it. A keyword the JAX plant does not model yet raises a
``ValueError`` naming it.
"""

from __future__ import annotations

import importlib
from typing import Any

import gymnasium as gym

#: the plant module implementing each env name (``from_env(numba_env) -> (env, params)``)
PLANT_MODULES = {
    "ReactionWheel": "attitude_envs.jax.gyrostat",
    "AirBearing": "attitude_envs.jax.gyrostat",
    "Magnetorquer": "attitude_envs.jax.magnetorquer",
    "FuelSlosh": "attitude_envs.jax.fuel_slosh",
    "LinearSystem": "attitude_envs.jax.linear_system",
}
NAMESPACE = "attitude_envs"
#: the plants whose JAX twin models flight conditions (:mod:`attitude_envs.conditions`): the
#: delay, the actuator dynamics, the per-episode parameter draws and the flight sensors
FLIGHT_PLANTS = ("ReactionWheel", "AirBearing")


def full_id(env_id: str) -> str:
    """``env_id`` with the suite's namespace; ``ValueError`` naming the ids for another (or for
    anything not a string)."""
    if not isinstance(env_id, str):
        raise ValueError(
            f"env_id must be a string, one of the suite's ids ({sorted(PLANT_MODULES)}, -v0 or -v1, e.g. "
            f"'AirBearing-v1'), got {env_id!r} ({type(env_id).__name__})"
        )
    full = env_id if "/" in env_id else f"{NAMESPACE}/{env_id}"
    namespace, _, name = full.partition("/")
    plant = name.rsplit("-v", 1)[0]
    if namespace != NAMESPACE or plant not in PLANT_MODULES:
        raise ValueError(f"env_id must be one of the suite's ids ({sorted(PLANT_MODULES)}, -v0 or -v1), got {env_id!r}")
    gym.spec(full)  # gymnasium's error for an unknown version
    return full


def numba_env(env_id: str, **kwargs: Any):
    """The numba (Gymnasium) env the JAX plant of ``env_id`` is built from, unwrapped."""
    import attitude_envs  # noqa: F401  (registers the ids)

    return gym.make(full_id(env_id), disable_env_checker=True, **kwargs).unwrapped


def make(env_id: str, **kwargs: Any):
    """The JAX plant of ``env_id`` (``"AirBearing-v1"`` or ``"attitude_envs/AirBearing-v1"``)
    and its default ``EnvParams``, configured by the numba env's keywords. Flight ``conditions`` only for the gyrostats
    (:data:`FLIGHT_PLANTS`); a ``ValueError`` names the rest."""
    env = numba_env(env_id, **kwargs)
    plant = full_id(env_id).split("/")[1].rsplit("-v", 1)[0]
    if not env.conditions.is_lab:
        if plant not in FLIGHT_PLANTS:
            raise ValueError(
                f"conditions={env.conditions.name!r} ({env.conditions.as_dict()}): the JAX {plant} models the lab "
                "conditions only so far; use the numba env (gymnasium.make) for flight conditions"
            )
    module = importlib.import_module(PLANT_MODULES[plant])
    return module.from_env(env)
