"""AirBearing-v0: the 85 kg three-axis air-bearing attitude simulator of Ahangarani
Farahani, Adami & Arefkhani (GA-tuned state-dependent PID).

ReactionWheel-v0's gyrostat with the ``air-bearing-85kg`` preset
(:mod:`attitude_envs.presets.air_bearing`): three orthogonal wheels, the paper's Table 1
inertia, the centre-of-mass offset ("gravity-vector") torque and the platform's roll/pitch
stops, all regular keywords of :class:`~attitude_envs.envs.reaction_wheel.ReactionWheelEnv`.
This class adds only the random start in Euler angles and the Euler angles in ``info``.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs import presets, quaternion, validation
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.euler import euler_321_rad


class AirBearingEnv(ReactionWheelEnv):
    """Three-axis air-bearing platform with three orthogonal reaction wheels.

    Plant: the exact gyrostat of :mod:`attitude_envs.plants.gyrostat` plus the torque of the
    centre-of-mass offset about the bearing's centre of rotation, ``p × K(q)`` with
    ``p = m g r_s`` (the paper's Table 1) and ``K`` the gravity direction in body axes (the
    paper's eqs. 6–9; restoring in roll and pitch: stiffness ``p_z = 0.3366 N·m/rad``,
    periods ≈ 28–30 s).

    ================  ==========================================================  ==========
    Quantity          Meaning                                                     Units
    ================  ==========================================================  ==========
    State (truth)     q (scalar last), ω body rate, Ω wheel speeds rel. body     -, rad/s
    Observation       float32 ``x = [q_e,vec (3), ω (3)]``, q_e = q_T*⊗q, w ≥ 0   -, rad/s
    Action            3 normalized wheel motor torques in [-1, 1] (x, y, z        -
                      wheels); ``u = 0.8 a`` N·m; body torque ``T_c = −u``        N·m
    Reward            −∫ (xᵀQx + T_cᵀR T_c) dt, Q = diag(4·I3, I3), R = I3        (cost)
    Start state       3-2-1 Euler angles uniform in ±``initial_euler_max_deg``    deg
                      (20, 20, 45), ω uniform in ±2 °/s, wheels at rest, target
                      identity; ``reset(options={"euler_321_deg": [φ, θ, ψ]})``
                      or ``"attitude"``, ``"rate_rad_s"``, ...
    Termination       roll or pitch beyond ±``tilt_limit_deg`` (40°): the         deg
                      platform hits its mechanical stop (not modelled as a
                      collision: the episode ends, ``truth["tilt_limit_hit"]``);
                      non-finite state; ``max|ω| > max_rate_rad_s``
    Truncation        simulated time reaches ``episode_duration_s`` (20 s)        s
    ================  ==========================================================  ==========

    Yaw is unlimited. ``info`` is ReactionWheel-v0's plus ``truth["euler_321_deg"]``
    ([φ, θ, ψ] of the true attitude, deg). Parameters: every ReactionWheel-v0 keyword (the
    preset ``"air-bearing-85kg"`` sets the paper's values, including ``offset_torque_nm``
    and ``tilt_limit_deg``; ``disturbance={"kind": "constant", "torque_nm": [0.01] * 3}``
    is the paper's constant-disturbance run) plus ``initial_euler_max_deg`` (roll and pitch
    below ``tilt_limit_deg``, yaw up to 180). Wheel inertia (0.01 kg·m²) and speed limit
    (6000 rpm) are assumed: the paper gives none. ``env.unwrapped.model.params`` carries
    ``offset_torque_nm``; the model's ``linearize()`` is the free body's (it leaves out the
    offset's roll/pitch stiffness ``p_z``, the paper's eq. 17).
    """

    env_name = "AirBearing-v0"
    default_preset = "air-bearing-85kg"

    def __init__(self, preset: str | None = None, initial_euler_max_deg=None, **kwargs: Any) -> None:
        super().__init__(preset, **kwargs)
        if self.tilt_limit_deg is None:
            raise ValueError("AirBearing-v0 needs tilt_limit_deg (the bearing's roll/pitch stop)")
        if initial_euler_max_deg is None:
            preset_value = presets.get(self.env_name, self.preset).values.get("initial_euler_max_deg")
            initial_euler_max_deg = np.zeros(3) if preset_value is None else preset_value.value
        euler_max = validation.finite_array("initial_euler_max_deg", initial_euler_max_deg, (3,))
        if np.any(euler_max < 0) or np.any(euler_max[:2] >= self.tilt_limit_deg) or euler_max[2] > 180.0:
            raise ValueError(
                f"initial_euler_max_deg must be [roll, pitch] in [0, tilt_limit_deg) and yaw in [0, 180], "
                f"got {euler_max.tolist()}"
            )
        self.initial_euler_max_deg = euler_max
        self._random_start = self._initial_fixed is None

    def reset_episode(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """:meth:`ReactionWheelEnv.reset_episode` with the start attitude drawn in 3-2-1 Euler
        angles (or given as ``options["euler_321_deg"]``)."""
        options = {} if options is None else dict(options)
        gym.Env.reset(self, seed=seed)  # seed here: the start attitude is drawn before the parent's draws
        if "euler_321_deg" in options:
            if "attitude" in options:
                raise ValueError("reset options: give either 'euler_321_deg' or 'attitude', not both")
            euler = validation.finite_array("options['euler_321_deg']", options.pop("euler_321_deg"), (3,))
            options["attitude"] = quaternion.from_euler_321_deg(*euler)
        elif "attitude" not in options and self._random_start:
            options["attitude"] = quaternion.from_euler_321_deg(
                *self.np_random.uniform(-self.initial_euler_max_deg, self.initial_euler_max_deg)
            )
        super().reset_episode(None, options)

    def _info(self, applied: np.ndarray, commanded: np.ndarray, cost: float) -> dict:
        info = super()._info(applied, commanded, cost)
        roll, pitch, yaw = euler_321_rad(self._y)
        info["truth"]["euler_321_deg"] = np.array([math.degrees(roll), math.degrees(pitch), math.degrees(yaw)])
        return info
