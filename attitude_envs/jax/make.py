"""``attitude_envs.jax.make(env_id, **kwargs) -> (env, env_params)``.

The keywords are the numba env's, with the id's registered defaults under them. Each plant
module's ``from_keywords`` validates them with the numba env's own configuration code (its
presets, checks and derived parameters) and builds the JAX plant without a numba env. A
keyword the JAX plant does not model yet raises a ``ValueError`` naming it.
"""

from __future__ import annotations

import importlib
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.envs.base import Layers, build_layers
from attitude_envs.registration import task_defaults
from attitude_envs.sensors import Channel

#: the plant module implementing each env name (``from_keywords(plant, kwargs) -> (env, params)``)
PLANT_MODULES = {
    "ReactionWheel": "attitude_envs.jax.gyrostat",
    "AirBearing": "attitude_envs.jax.gyrostat",
    "Magnetorquer": "attitude_envs.jax.magnetorquer",
    "FuelSlosh": "attitude_envs.jax.fuel_slosh",
    "LinearSystem": "attitude_envs.jax.linear_system",
}
NAMESPACE = "attitude_envs"


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
    """The numba (Gymnasium) env of ``env_id`` with ``kwargs``, unwrapped: the reference a JAX plant
    of the same keywords (:func:`make`) is checked against."""
    import attitude_envs  # noqa: F401  (registers the ids)

    return gym.make(full_id(env_id), disable_env_checker=True, **kwargs).unwrapped


def state_layers(
    plant: str,
    cfg: Any,
    limits: np.ndarray,
    n_states: int,
    flight_sensors: dict | None = None,
    control_dt_s: float | None = None,
) -> Layers:
    """The layers of a plant with one ``state`` sensor channel of ``n_states`` entries:
    ``cfg``'s ``faults``, ``sensors``, ``fault_hint`` and ``conditions`` validated by the numba
    envs' own :func:`~attitude_envs.envs.base.build_layers`. Under flight conditions with
    sensors on and no ``sensors=`` of its own, the channel is the env's flight ``state`` sensor
    ``flight_sensors`` (its ``sensors=`` entry, scaled to the plant); ``control_dt_s`` (s) is
    the decision period. A ``ValueError`` for sensor faults or ``sensors`` without the
    conditions' sensors, which the JAX ``plant`` does not model."""
    cond = cfg.conditions
    sensors = cfg.sensors
    if sensors is None and cond.sensors > 0:
        sensors = {"state": flight_sensors}
    layers = build_layers(
        plant,
        None,
        n_actuators=len(limits),
        actuator_limits=limits,
        channels=[Channel("state", n_states)],
        faults=cfg.faults,
        sensors=sensors,
        fault_hint=cfg.fault_hint,
        conditions=cond,
        control_dt_s=control_dt_s,
    )
    if layers.sensor_layer.fault_configs and cond.sensors == 0:
        raise ValueError(
            f"{plant} JAX plant: sensor faults are modeled only on flight conditions' sensors (conditions with "
            "'sensors' > 0)"
        )
    if layers.sensor_layer.config and cond.sensors == 0:
        raise ValueError(
            f"{plant} JAX plant: keyword 'sensors' is modeled only as flight conditions' sensors (conditions with "
            "'sensors' > 0); without them the state is observed exactly"
        )
    return layers


def make(env_id: str, **kwargs: Any):
    """The JAX plant of ``env_id`` (``"AirBearing-v1"`` or ``"attitude_envs/AirBearing-v1"``)
    and its default ``EnvParams``, configured by the numba env's keywords, flight ``conditions``
    included; a ``ValueError`` names what a twin does not model."""
    full = full_id(env_id)
    plant = full.split("/")[1].rsplit("-v", 1)[0]
    module = importlib.import_module(PLANT_MODULES[plant])
    return module.from_keywords(plant, {**task_defaults(full), **kwargs})
