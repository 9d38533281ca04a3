"""``attitude_envs.jax.make(env_id, **kwargs) -> (env, env_params)``.

The keywords are the numba env's, with the id's registered defaults under them. A plant
module with ``from_keywords`` validates them with the numba env's own configuration code
(its presets, checks and derived parameters) and builds the JAX plant without a numba env;
for the others ``make`` builds the numba env and reads the JAX plant's static layout and
``EnvParams`` from it (``from_env``). A keyword the JAX plant does not model yet raises a
``ValueError`` naming it.
"""

from __future__ import annotations

import importlib
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.conditions import Conditions
from attitude_envs.envs.base import build_layers
from attitude_envs.faults import ActuatorFaults
from attitude_envs.registration import task_defaults
from attitude_envs.sensors import Channel

#: the plant module implementing each env name (``from_keywords(plant, kwargs)`` or
#: ``from_env(numba_env)``, each ``-> (env, params)``)
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


def lab_only(plant: str, conditions: Conditions) -> None:
    """A ``ValueError`` unless ``conditions`` are the lab's: the JAX ``plant`` models no other."""
    if not conditions.is_lab:
        raise ValueError(
            f"conditions={conditions.name!r} ({conditions.as_dict()}): the JAX {plant} models the lab "
            "conditions only so far; use the numba env (gymnasium.make) for flight conditions"
        )


def lab_layers(plant: str, cfg: Any, limits: np.ndarray, n_states: int) -> ActuatorFaults:
    """The actuator fault layer of a lab plant with one ``state`` sensor channel of
    ``n_states`` entries: ``cfg``'s ``faults``, ``sensors`` and ``fault_hint`` validated by the
    numba envs' own :func:`~attitude_envs.envs.base.build_layers`; a ``ValueError`` for flight
    conditions, ``sensors`` or sensor faults, which the JAX ``plant`` does not model."""
    layers = build_layers(
        plant,
        None,
        n_actuators=len(limits),
        actuator_limits=limits,
        channels=[Channel("state", n_states)],
        faults=cfg.faults,
        sensors=cfg.sensors,
        fault_hint=cfg.fault_hint,
    )
    lab_only(plant, cfg.conditions)
    if layers.sensor_layer.config:
        raise ValueError(f"{plant} JAX plant: keyword 'sensors' is not modeled (the state is observed exactly)")
    if layers.sensor_layer.fault_configs:
        raise ValueError(f"{plant} JAX plant: 'faults' with target 'sensor' are not modeled (actuator faults only)")
    return layers.fault_layer


def make(env_id: str, **kwargs: Any):
    """The JAX plant of ``env_id`` (``"AirBearing-v1"`` or ``"attitude_envs/AirBearing-v1"``)
    and its default ``EnvParams``, configured by the numba env's keywords. Flight ``conditions`` only for the gyrostats
    (:data:`FLIGHT_PLANTS`); a ``ValueError`` names the rest."""
    full = full_id(env_id)
    plant = full.split("/")[1].rsplit("-v", 1)[0]
    module = importlib.import_module(PLANT_MODULES[plant])
    if hasattr(module, "from_keywords"):
        return module.from_keywords(plant, {**task_defaults(full), **kwargs})
    env = numba_env(env_id, **kwargs)
    if plant not in FLIGHT_PLANTS:
        lab_only(plant, env.conditions)
    return module.from_env(env)
