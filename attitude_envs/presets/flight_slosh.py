"""The cited flight values of FuelSlosh (:mod:`attitude_envs.presets.flight`).

Where a number was read in a text that quotes a datasheet rather than in the datasheet
itself, the source says "as quoted by"; "assumed:" marks a value no source gave, with the
reasoning. Units are SI; sensor noise is per sample at the control period.

**The state sensor.** FuelSlosh's one sensor channel ``state`` measures the observation
vector ``[v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2, v_x]``. In flight an IMU (with the attitude of a
star-tracker-aided solution) measures the rigid-body entries only: nothing senses the
slosh pendulums. Their entries are **not measured**: the env reports them as 0 (their
noise here is 0 and :class:`~attitude_envs.envs.fuel_slosh.FuelSloshEnv` overwrites them),
so an estimator must reconstruct ψ_i, ψ̇_i from the rigid-body response. The values are
one per entry of that vector (:data:`STATE_ORDER`); the env takes the entries of its
observation (:func:`state_sensor_config`), since ``FlightTable.sensor_config`` holds one
number per channel.
"""

from __future__ import annotations

import math

import numpy as np

from attitude_envs.presets import Sourced
from attitude_envs.presets.flight import ARCSEC, make_table, register
from attitude_envs.presets.flight_gyrostat import _DELAY, _GYRO_STIM300, _HE5AS, _STIM300

#: the entries of the ``state`` sensor's values, in the order of FuelSlosh's observation
STATE_ORDER = ("v_z", "theta", "Omega", "psi1", "dpsi1", "psi2", "dpsi2", "v_x")
#: which of them the flight sensors measure (the slosh pendulum states are not measured)
MEASURED = (True, True, True, False, False, False, False, True)

_NOT_MEASURED = "not measured: no flight sensor senses the slosh pendulums (the env reports 0)"
_VELOCITY_NOISE = (
    "assumed: 0.01 m/s per sample, the velocity of an inertial navigation solution from tactical "
    "MEMS accelerometers (STIM300 class); no accelerometer value was read"
)
_VELOCITY_WALK = (
    "assumed: 1.2e-3 m/s/√s, a velocity random walk of about 0.07 m/s/√h (STIM300-class accelerometer, "
    "from memory of its datasheet, not read)"
)
_VELOCITY_BIAS = "assumed: 0.05 m/s navigation velocity error at the start of the burn"


def _per_entry(values: dict[str, tuple[float, str]]) -> Sourced:
    """One :class:`Sourced` of a value per :data:`STATE_ORDER` entry, its source naming each."""
    numbers = tuple(float(values[k][0]) for k in STATE_ORDER)
    groups: dict[str, list[str]] = {}
    for k in STATE_ORDER:
        groups.setdefault(values[k][1], []).append(k)
    return Sourced(numbers, "; ".join(f"{', '.join(keys)}: {src}" for src, keys in groups.items()))


_GYRO_NOISE = _GYRO_STIM300["noise_std"]
_GYRO_WALK = _GYRO_STIM300["bias_walk_std"]
_GYRO_BIAS = _GYRO_STIM300["initial_bias_std"]
_SLOSH = (0.0, _NOT_MEASURED)

_STATE_SENSOR = {
    "noise_std": _per_entry(
        {
            "v_z": (0.01, _VELOCITY_NOISE),
            "theta": (
                16.0 * ARCSEC,
                f"assumed: 16″, the about-boresight noise of the {_HE5AS}, for the attitude of a "
                "star-tracker-aided IMU solution sampled every control period",
            ),
            "Omega": (_GYRO_NOISE.value, f"{_GYRO_NOISE.source} (a 0.1 s average: FuelSlosh-v0's period)"),
            "psi1": _SLOSH,
            "dpsi1": _SLOSH,
            "psi2": _SLOSH,
            "dpsi2": _SLOSH,
            "v_x": (0.01, _VELOCITY_NOISE),
        }
    ),
    "bias_walk_std": _per_entry(
        {
            "v_z": (1.2e-3, _VELOCITY_WALK),
            "theta": (0.0, "assumed: none, the star tracker's attitude is absolute"),
            "Omega": (_GYRO_WALK.value, f"{_STIM300} gyro; {_GYRO_WALK.source}"),
            "psi1": _SLOSH,
            "dpsi1": _SLOSH,
            "psi2": _SLOSH,
            "dpsi2": _SLOSH,
            "v_x": (1.2e-3, _VELOCITY_WALK),
        }
    ),
    "initial_bias_std": _per_entry(
        {
            "v_z": (0.05, _VELOCITY_BIAS),
            "theta": (0.0, "assumed: none, the star tracker's attitude is absolute"),
            "Omega": (_GYRO_BIAS.value, f"{_STIM300} gyro; {_GYRO_BIAS.source}"),
            "psi1": _SLOSH,
            "dpsi1": _SLOSH,
            "psi2": _SLOSH,
            "dpsi2": _SLOSH,
            "v_x": (0.05, _VELOCITY_BIAS),
        }
    ),
}

_GIMBAL_RATE_DEG_S = 10.0
_GIMBAL_LIMIT_DEG = 30.0  # FuelSlosh's default max_gimbal_deg

_SLOSH_REFS = (
    "NASA SP-106 (Abramson, ed., 1966), The Dynamic Behavior of Liquids in Moving Containers, and Dodge 2000, "
    "The New 'Dynamic Behavior of Liquids in Moving Containers' (SwRI), describe the equivalent pendulum model "
    "(the percentage is our choice)"
)

register(
    "FuelSlosh",
    make_table(
        "FuelSlosh",
        sensors={"state": _STATE_SENSOR},
        actuators={
            # actuator 0: the gimbal angle (rad); actuator 1: the pitch moment (N·m)
            "rate_limit": Sourced(
                (_GIMBAL_RATE_DEG_S / _GIMBAL_LIMIT_DEG, math.inf),
                f"assumed: gimbal slew rate {_GIMBAL_RATE_DEG_S:g} °/s (generic thrust-vector-control actuators "
                f"slew 5–20 °/s; liquid apogee engines are usually fixed, so the gimbal itself is a model "
                f"choice), per second as a fraction of the default {_GIMBAL_LIMIT_DEG:g}° limit (it scales "
                "with max_gimbal_deg); the pitch moment: none",
            ),
            "lag_s": Sourced(
                (0.05, 0.0),
                "assumed: gimbal actuator first-order lag 0.05 s (an electromechanical TVC loop of about "
                "3 Hz bandwidth); the pitch moment: none (thruster valves open in a few ms, far below the "
                "control period)",
            ),
        },
        delay_steps=_DELAY,
        gain_tolerance=Sourced(
            0.05,
            "assumed: ±5 % scale factor of the gimbal angle (position sensing and linkage) and of the "
            "pitch moment (thrust level of the moment actuators)",
        ),
        plant={
            "slosh_mass": Sourced(0.15, f"assumed: ±15 % on each pendulum's slosh mass; {_SLOSH_REFS}"),
            "pendulum_length": Sourced(0.15, f"assumed: ±15 % on each pendulum's length; {_SLOSH_REFS}"),
        },
    ),
)


def state_sensor_config(observation_entries, noise_scale: float = 1.0) -> dict:
    """The ``sensors=`` entry of the ``state`` channel for an observation of the
    :data:`STATE_ORDER` entries at ``observation_entries`` (positions in that order): one
    value per observed entry, the noise, bias walk and bias spread times ``noise_scale``."""
    idx = np.asarray(observation_entries, dtype=int)
    return {key: np.asarray(sourced.value, dtype=float)[idx] * noise_scale for key, sourced in _STATE_SENSOR.items()}
