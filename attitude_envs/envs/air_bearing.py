"""AirBearing-v0: the 85 kg three-axis air-bearing attitude simulator of spec 003.

A configuration of :class:`~attitude_envs.envs.reaction_wheel.ReactionWheelEnv` (same
gyrostat plant, same compiled RK4 step) with three orthogonal wheels, the Table 1 inertia,
the centre-of-mass offset ("gravity-vector") torque and the platform's roll/pitch stops.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.euler import euler_321_rad
from attitude_envs.plants import gyrostat_kernels as kernels
from attitude_envs.plants.gyrostat import GyrostatParams

RPM = 2.0 * np.pi / 60.0

#: Spec 003 parameters; READ = Table 1 of the paper, ASSUMED = the paper gives none.
AIR_BEARING: dict[str, Any] = {
    # READ Table 1, used as the full inertia tensor (spec 003 §5 A3), kg·m²
    "inertia_kg_m2": np.array([[6.75, 0.89, 0.035], [0.89, 7.46, -0.032], [0.035, -0.032, 12.33]]),
    # ASSUMED (A4): three orthogonal wheels, one per body axis
    "wheel_axes": np.eye(3),
    # ASSUMED: the paper gives no wheel data. A 0.8 N·m wheel is a large one; 0.01 kg·m² at
    # 6000 rpm stores 6.3 N·m·s, about 1 rad/s of the platform's 7 kg·m² axes.
    "wheel_inertia_kg_m2": 0.01,
    "max_wheel_speed_rad_s": 6000.0 * RPM,
    "max_wheel_torque_nm": 0.8,  # READ Table 1 (printed 8/0)
    "control_dt_s": 0.01,  # ASSUMED (A5): 100 Hz zero-order hold, RK4 at 0.01 s
    "integrator_dt_s": 0.01,
    "episode_duration_s": 20.0,  # READ §2.8: 20 s runs
    # ASSUMED: the paper's cost is IAE; the shared quadratic cost weighs 4|q_e,vec|² ≈ angle²
    # (rad²), rates (rad²/s²) and body torque (N²·m²) equally.
    "Q": np.diag([4.0, 4.0, 4.0, 1.0, 1.0, 1.0]),
    "R": np.eye(3),
    "cost_input": "body",
    "target_attitude": np.array([0.0, 0.0, 0.0, 1.0]),  # READ/REC A10: regulation to zero
    "initial_rate_max_rad_s": np.radians(2.0),  # REC A9: rates in U[−2, 2] °/s
}

#: READ Table 1: "gravity-vector torque" m g r_s, N·m, body axes (z down: pendulous).
OFFSET_TORQUE_NM = np.array([0.0014, 1.025e-4, 0.3366])
#: READ Table 1: roll and pitch travel of the bearing, deg.
TILT_LIMIT_DEG = 40.0

_OWN_OPTIONS = {"euler_321_deg"}


class AirBearingEnv(ReactionWheelEnv):
    """Three-axis air-bearing platform with three orthogonal reaction wheels (spec 003).

    Plant: the exact gyrostat of :mod:`attitude_envs.plants.gyrostat` plus the torque of the
    centre-of-mass offset about the bearing's centre of rotation, ``p × K(q)`` with
    ``p = m g r_s`` (Table 1) and ``K`` the gravity direction in body axes (eq. 6–9;
    restoring in roll and pitch: stiffness ``p_z = 0.3366 N·m/rad``, periods ≈ 28–30 s).

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
                      collision: the episode ends, ``info["tilt_limit_hit"]``);
                      non-finite state; ``max|ω| > max_rate_rad_s``
    Truncation        simulated time reaches ``episode_duration_s`` (20 s)        s
    ================  ==========================================================  ==========

    Yaw is unlimited. ``info`` is ReactionWheel-v0's plus ``euler_321_deg`` ([φ, θ, ψ] of
    the attitude, deg) and ``tilt_limit_hit``. Parameters: every ReactionWheel-v0 keyword
    (defaults from :data:`AIR_BEARING`; ``disturbance={"kind": "constant", "torque_nm":
    [0.01] * 3}`` is the spec's A11 scenario) plus ``offset_torque_nm`` (``m g r_s``, N·m),
    ``tilt_limit_deg`` and ``initial_euler_max_deg``. Wheel inertia (0.01 kg·m²) and speed
    limit (6000 rpm) are ASSUMED: the paper gives none. ``env.unwrapped.model.params`` carries
    ``offset_torque_nm``; the model's ``linearize()`` is the free body's (it leaves out the
    offset's roll/pitch stiffness ``p_z``, spec 003 eq. 17).
    """

    def __init__(
        self,
        offset_torque_nm=None,
        tilt_limit_deg: float = TILT_LIMIT_DEG,
        initial_euler_max_deg=(20.0, 20.0, 45.0),
        **kwargs: Any,
    ) -> None:
        if "preset" in kwargs:
            raise ValueError("AirBearing-v0 takes no preset (its parameters are spec 003's); pass keywords instead")
        config = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in AIR_BEARING.items()}
        config.update({k: v for k, v in kwargs.items() if v is not None})
        super().__init__(**config)
        offset = OFFSET_TORQUE_NM if offset_torque_nm is None else offset_torque_nm
        p = self.model.params
        params = GyrostatParams(
            p.inertia_kg_m2,
            p.wheel_axes,
            p.wheel_inertia_kg_m2,
            p.max_wheel_torque_nm,
            p.max_wheel_speed_rad_s,
            validation.finite_array("offset_torque_nm", offset, (3,)),
        )
        limit = float(tilt_limit_deg)
        if not 0.0 < limit < 90.0:
            raise ValueError(f"tilt_limit_deg must be in (0, 90), got {tilt_limit_deg!r}")
        self.tilt_limit_deg = limit
        self._tilt_limit_rad = math.radians(limit)  # the compiled step terminates beyond it
        self.model = dataclasses.replace(self.model, params=params)
        self._plant = params
        self._pack_kernel_arguments()
        euler_max = validation.finite_array("initial_euler_max_deg", initial_euler_max_deg, (3,))
        if np.any(euler_max < 0) or np.any(euler_max[:2] >= limit) or euler_max[2] > 180.0:
            raise ValueError(
                f"initial_euler_max_deg must be [roll, pitch] in [0, tilt_limit_deg) and yaw in [0, 180], "
                f"got {euler_max.tolist()}"
            )
        self._euler_max = euler_max
        self._random_start = kwargs.get("initial_attitude") is None

    def _reset_state(self, seed: int | None, options: dict[str, Any] | None) -> None:
        options = {} if options is None else dict(options)
        gym.Env.reset(self, seed=seed)  # seed here: the start attitude is drawn before the parent's draws
        if "euler_321_deg" in options:
            if "attitude" in options:
                raise ValueError("reset options: give either 'euler_321_deg' or 'attitude', not both")
            euler = validation.finite_array("options['euler_321_deg']", options.pop("euler_321_deg"), (3,))
            options["attitude"] = quaternion.from_euler_321_deg(*euler)
        elif "attitude" not in options and self._random_start:
            options["attitude"] = quaternion.from_euler_321_deg(
                *self.np_random.uniform(-self._euler_max, self._euler_max)
            )
        super()._reset_state(None, options)

    def _info(self, applied: np.ndarray, commanded: np.ndarray, cost: float) -> dict:
        info = super()._info(applied, commanded, cost)
        roll, pitch, yaw = euler_321_rad(self._y)
        info["euler_321_deg"] = np.array([math.degrees(roll), math.degrees(pitch), math.degrees(yaw)])
        info["tilt_limit_hit"] = bool(kernels.tilt_exceeded(self._y, self._constants))
        return info
