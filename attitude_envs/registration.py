"""Gymnasium ids of the suite (``attitude_envs/<Name>-v0``): all five envs, each with its
natively batched vector entry point."""

from __future__ import annotations

import gymnasium as gym

VECTOR_ENTRY_POINTS = {
    "attitude_envs/ReactionWheel-v0": "attitude_envs.envs.reaction_wheel_vector:ReactionWheelVectorEnv",
    "attitude_envs/LinearSystem-v0": "attitude_envs.envs.linear_system_vector:LinearSystemVectorEnv",
    "attitude_envs/AirBearing-v0": "attitude_envs.envs.reaction_wheel_vector:AirBearingVectorEnv",
    "attitude_envs/FuelSlosh-v0": "attitude_envs.envs.fuel_slosh_vector:FuelSloshVectorEnv",
    "attitude_envs/Magnetorquer-v0": "attitude_envs.envs.magnetorquer_vector:MagnetorquerVectorEnv",
}

ENV_IDS = {
    "attitude_envs/ReactionWheel-v0": "attitude_envs.envs.reaction_wheel:ReactionWheelEnv",
    "attitude_envs/LinearSystem-v0": "attitude_envs.envs.linear_system:LinearSystemEnv",
    "attitude_envs/FuelSlosh-v0": "attitude_envs.envs.fuel_slosh:FuelSloshEnv",
    "attitude_envs/AirBearing-v0": "attitude_envs.envs.air_bearing:AirBearingEnv",
    "attitude_envs/Magnetorquer-v0": "attitude_envs.envs.magnetorquer:MagnetorquerEnv",
}


def register_envs() -> None:
    """Register every env id (idempotent)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in gym.registry:
            # Episodes end on simulated time inside the env (truncated), so the time limit
            # does not depend on control_dt_s; no TimeLimit wrapper is added.
            gym.register(
                id=env_id,
                entry_point=entry_point,
                vector_entry_point=VECTOR_ENTRY_POINTS.get(env_id),
                disable_env_checker=False,
            )
