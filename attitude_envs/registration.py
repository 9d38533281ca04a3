"""Gymnasium ids of the suite: the five plants as ``attitude_envs/<Name>-v0`` (the papers'
problems: their periods, episodes and defaults) and ``attitude_envs/<Name>-v1`` (the same plants
posed as learning tasks: :data:`LEARNING_TASKS`), each with its natively batched vector entry point.

A ``-v1`` id is its ``-v0`` env with other defaults (Gymnasium's versioning: a change of
defaults that changes an env's reward, dynamics or episodes is a new version; ``-v0`` keeps
every paper reproduction and saved model working). Keyword arguments given to ``make`` override
the task's defaults, as for any registered ``kwargs``.
"""

from __future__ import annotations

from typing import Any

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

#: The learning task of each plant: ``-v1`` id → (its ``-v0`` id, the defaults it changes).
#: Fewer, longer decisions: a learner's advantage estimate needs each decision to move the
#: state, and the decision period and the discount's horizon ``Δt/(1 − γ)`` change together
#: (the shipped recipes: experiments/sb3/hyperparams); the physics step and the cost
#: integral are the ``-v0`` ones, so J is the same quantity at either period. A limit
#: crossing is charged ``T·xᵀQx`` (``termination_cost="episode"``, see
#: :meth:`attitude_envs.envs.base.AttitudeEnv.batch_termination_cost`). The magnetorquer's
#: observation carries the geomagnetic field (its only torque is m × b). LinearSystem-v1 is
#: Heravi & Novinzadeh 2017's 400 s regulation of the linearized satellite.
LEARNING_TASKS: dict[str, tuple[str, dict[str, Any]]] = {
    "attitude_envs/ReactionWheel-v1": ("attitude_envs/ReactionWheel-v0", {"termination_cost": "episode"}),
    "attitude_envs/AirBearing-v1": (
        "attitude_envs/AirBearing-v0",
        {"control_dt_s": 0.5, "termination_cost": "episode"},
    ),
    "attitude_envs/FuelSlosh-v1": (
        "attitude_envs/FuelSlosh-v0",
        {
            "control_dt_s": 0.25,
            "episode_duration_s": 100.0,
            "randomize_initial_state": True,
            "termination_cost": "episode",
        },
    ),
    "attitude_envs/Magnetorquer-v1": (
        "attitude_envs/Magnetorquer-v0",
        {
            "control_dt_s": 10.0,
            "integrator_dt_s": 0.5,
            "episode_duration_s": 300.0,
            "observe_field": True,
            "termination_cost": "episode",
        },
    ),
    "attitude_envs/LinearSystem-v1": (
        "attitude_envs/LinearSystem-v0",
        {"preset": "heravi-2017", "episode_steps": 40000, "control_dt_s": 5.0, "termination_cost": "episode"},
    ),
}


#: the warning Gymnasium gives on ``make`` of a ``-v0`` id of this suite once its ``-v1`` exists
#: ("… is out of date. You should consider upgrading to version `v1`"). The ``-v0`` ids are the
#: papers' problems, kept on purpose; Gymnasium's registry has no per-spec switch for this
#: warning, so importing the suite adds a warnings filter that matches only this namespace's
#: ``-v0`` ids (:func:`quiet_version_warnings`); any other env's warning is left alone.
OUT_OF_DATE = r".*The environment attitude_envs/[A-Za-z0-9_]+-v0 is out of date\. You should consider upgrading"


def quiet_version_warnings() -> None:
    """Silence Gymnasium's out-of-date warning for this suite's ``-v0`` ids (and only theirs)
    in this process. Called on registration (importing ``attitude_envs``); idempotent. A test
    runner that resets the warning filters (pytest) shows the warning again."""
    import warnings

    warnings.filterwarnings("ignore", message=OUT_OF_DATE, category=DeprecationWarning)


def base_version(env_id: str) -> str:
    """The ``-v0`` id of ``env_id`` (itself for a ``-v0`` or a foreign id)."""
    return LEARNING_TASKS[env_id][0] if env_id in LEARNING_TASKS else env_id


def task_defaults(env_id: str) -> dict[str, Any]:
    """The defaults ``env_id`` sets over its ``-v0`` env (empty for a ``-v0`` id)."""
    return dict(LEARNING_TASKS[env_id][1]) if env_id in LEARNING_TASKS else {}


#: Tasks beyond the five plants' regulation, registered beside them: the same plant and
#: cost with constraints (:mod:`attitude_envs.constraints`); no batched entry point yet.
CONSTRAINED_ENV_IDS = {
    "attitude_envs/ConstrainedSlew-v0": "attitude_envs.envs.constrained_slew:ConstrainedSlewEnv",
}


def register_envs() -> None:
    """Register every env id (idempotent) and silence Gymnasium's out-of-date warning for the
    ``-v0`` ids (:data:`OUT_OF_DATE`)."""
    quiet_version_warnings()
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
    for env_id, (v0, defaults) in LEARNING_TASKS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=ENV_IDS[v0],
                vector_entry_point=VECTOR_ENTRY_POINTS.get(v0),
                disable_env_checker=False,
                kwargs=dict(defaults),
            )
    for env_id, entry_point in CONSTRAINED_ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, disable_env_checker=False)
