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
from attitude_envs.evaluation.success import FINAL_ERROR_DEG


class AirBearingEnv(ReactionWheelEnv):
    """Three-axis air-bearing attitude simulator with three orthogonal reaction wheels.

    **Description.** The 85 kg laboratory platform of Ahangarani Farahani, Adami &
    Arefkhani, on which they tested a PID with state-dependent, GA-tuned gains. The plant is
    ReactionWheel-v0's exact gyrostat (the same compiled RK4 step) plus the torque of the
    centre-of-mass offset about the bearing's centre of rotation, ``p × K(q)`` with
    ``p = m g r_s`` (the paper's Table 1) and ``K`` the gravity direction in body axes (the
    paper's eqs. 6–9): restoring in roll and pitch (stiffness ``p_z = 0.3366 N·m/rad``,
    periods ≈ 28–30 s), none in yaw. With idle wheels the total energy including the
    gravity potential is conserved. Roll and pitch are limited by the bearing's mechanical
    stops at ±40°; yaw is unlimited. The paper gives no wheel data: the wheel inertia
    (0.01 kg·m²) and speed limit (6000 rpm) are assumed.

    **Action space.** ``Box(-1, 1, (3,), float32)``, clipped: the x, y and z wheels' motor
    torques ``u = 0.8 a`` N·m; the body torque is ``T_c = −u``. With ``action_frame="body"``
    the action is the body-torque demand ``T_c = 0.8 a`` N·m instead.

    **Observation space.** ``Box(float32)`` of ``x = [q_e,vec (3), ω (3, rad/s)]``,
    ``q_e = q_T* ⊗ q`` (w ≥ 0), target identity; the options of ReactionWheel-v0
    (``observe_wheel_speeds``, ``fault_hint``, sensors) apply unchanged, and so do its bounds:
    the step that crosses a limit observes its measurement clipped to the bounds
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`; ``info["truth"]`` holds
    the true state).

    **Reward.** ``−∫ (xᵀQx + T_cᵀR T_c) dt`` over the step with ``Q = diag(4·I3, I3)``,
    ``R = I3`` (assumed: the paper scores the integral of absolute error, IAE;
    ``4|q_e,vec|²`` is about the squared error angle in rad²).

    **Starting state.** 3-2-1 Euler angles uniform in ±``initial_euler_max_deg``
    (20°, 20°, 45°), body rate uniform in ±2 °/s per axis, wheels at rest, target identity.
    ``reset(options={"euler_321_deg": [φ, θ, ψ]})`` pins the start angles (degrees);
    ``"attitude"``, ``"rate_rad_s"``, ``"wheel_speed_rad_s"`` and ``"faults"`` work as
    in ReactionWheel-v0.

    **Episode end.** Terminated when roll or pitch passes ±``tilt_limit_deg`` (40°): the
    platform hits its mechanical stop (not modelled as a collision: the episode ends and
    ``info["truth"]["tilt_limit_hit"]`` is set); also on a non-finite state or
    ``max|ω| > max_rate_rad_s``. Truncated when the simulated time reaches
    ``episode_duration_s`` (20 s, the paper's runs). A terminated step is charged the
    terminal error state's running cost over the rest of the run, as in ReactionWheel-v0
    (``termination_cost``).

    **Arguments.** Every ReactionWheel-v0 keyword, with the preset's values as defaults,
    plus ``initial_euler_max_deg``:

    =========================  ========  ==================  =====  ==================================================
    name                       type      default             unit   description
    =========================  ========  ==================  =====  ==================================================
    ``preset``                 str       "air-bearing-85kg"  —      parameter set (see Presets)
    ``initial_euler_max_deg``  3 floats  (20, 20, 45)        deg    random start: 3-2-1 Euler angles uniform in ±
                                                                    these; roll and pitch below ``tilt_limit_deg``,
                                                                    yaw up to 180
    ``inertia_kg_m2``          3×3       Table 1             kg·m²  the platform's full inertia tensor
    ``wheel_axes``             3×3       identity            —      three orthogonal wheels, one per body axis
    ``wheel_inertia_kg_m2``    float     0.01                kg·m²  wheel spin inertia (assumed: the paper gives none)
    ``max_wheel_torque_nm``    float     0.8                 N·m    motor torque limit (Table 1)
    ``max_wheel_speed_rad_s``  float     6000 rpm            rad/s  wheel speed limit (assumed)
    ``offset_torque_nm``       3 floats  Table 1             N·m    p = m g r_s = [0.0014, 1.025e-4, 0.3366]: the
                                                                    centre-of-mass offset torque p × K(q)
    ``tilt_limit_deg``         float     40                  deg    roll/pitch stop: the episode ends beyond it
                                                                    (required)
    ``control_dt_s``           float     0.01                s      100 Hz control (assumed)
    ``integrator_dt_s``        float     0.01                s      one RK4 step per control period
    ``episode_duration_s``     float     20                  s      the paper's 20 s runs
    ``Q``, ``R``               6×6, 3×3  diag(4·I3, I3), I3  —      cost weights (assumed: the paper scores IAE)
    ``disturbance``            dict      None                N·m    ``{"kind": "constant", "torque_nm": [0.01] * 3}``
                                                                    is the paper's constant-disturbance run
    (every other)                                                   ReactionWheel-v0's keywords and defaults
                                                                    (:mod:`attitude_envs.envs.reaction_wheel`):
                                                                    ``faults``, ``sensors``, ``fault_hint``,
                                                                    ``action_frame``, ``true_offset_torque_nm``,
                                                                    ``render_mode``, ...
    =========================  ========  ==================  =====  ==================================================


    **Presets.** ``"air-bearing-85kg"`` (default): the paper's Table 1 platform. Every
    value not printed in the paper is marked "assumed" with its reason.

    **Faults and sensors.** As ReactionWheel-v0: actuator i is the wheel on body axis i;
    sensor channels ``gyro``, ``star_tracker`` and ``tachometer``
    (:mod:`attitude_envs.sensors`); faults through :mod:`attitude_envs.faults`.

    **Info.** ReactionWheel-v0's (:mod:`attitude_envs.info`) plus
    ``info["truth"]["euler_321_deg"]`` ([φ, θ, ψ] of the true attitude, deg) and
    ``info["truth"]["tilt_limit_hit"]``.

    **Model.** ``env.unwrapped.model.params`` carries ``offset_torque_nm``; the model's
    ``linearize()`` is the free body's (it leaves out the offset's roll/pitch stiffness
    ``p_z``, the paper's eq. 17).

    **Success** (as ReactionWheel-v0, :mod:`attitude_envs.evaluation.success`):
    ``success_metric`` is ``FINAL_ERROR_DEG``, the final attitude error angle (deg, default
    threshold 2°).

    **Version history.** v1 (``attitude_envs/AirBearing-v1``, 2026-11-27): the learning task — decisions every 0.5 s over the same 0.01 s RK4 physics (40 per 20 s episode) and a limit crossing charged ``T·xᵀQx`` (``termination_cost="episode"``); the plant, the episodes and J are v0's. v0: a limit crossing charged the terminal running cost over the rest of the episode (``termination_cost``, 2026-11); the paper's platform as ReactionWheel-v0's gyrostat with the
    offset torque and tilt stop in the compiled step; a natively batched env; the preset
    through :mod:`attitude_envs.presets`; infos split into ``truth`` and ``measured``.
    """

    env_name = "AirBearing-v0"
    default_preset = "air-bearing-85kg"
    success_metric = FINAL_ERROR_DEG

    def __init__(self, preset: str | None = None, initial_euler_max_deg=None, **kwargs: Any) -> None:
        super().__init__(preset, **kwargs)
        self.initial_euler_max_deg = euler_max(self.env_name, self.preset, self.tilt_limit_deg, initial_euler_max_deg)
        self._random_start = self._initial_fixed is None

    def reset_episode(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """:meth:`ReactionWheelEnv.reset_episode` with the start attitude drawn in 3-2-1 Euler
        angles (or given as ``options["euler_321_deg"]``)."""
        options = validation.mapping("reset options", options)
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


def euler_max(env_name: str, preset: str | None, tilt_limit_deg: float | None, initial_euler_max_deg) -> np.ndarray:
    """The validated ``initial_euler_max_deg`` (deg, 3; None: ``preset``'s, else zeros) of an
    air bearing with the roll/pitch stop ``tilt_limit_deg`` (required); the env and the JAX
    plant (:mod:`attitude_envs.jax.gyrostat`) both take it from here."""
    if tilt_limit_deg is None:
        raise ValueError("AirBearing-v0 needs tilt_limit_deg (the bearing's roll/pitch stop)")
    if initial_euler_max_deg is None:
        preset_value = presets.get(env_name, preset).values.get("initial_euler_max_deg")
        initial_euler_max_deg = np.zeros(3) if preset_value is None else preset_value.value
    value = validation.finite_array("initial_euler_max_deg", initial_euler_max_deg, (3,))
    if np.any(value < 0) or np.any(value[:2] >= tilt_limit_deg) or value[2] > 180.0:
        raise ValueError(
            f"initial_euler_max_deg must be [roll, pitch] in [0, tilt_limit_deg) and yaw in [0, 180], "
            f"got {value.tolist()}"
        )
    return value
