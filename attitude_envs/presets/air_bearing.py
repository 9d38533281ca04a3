"""AirBearing-v0 preset ``air-bearing-85kg``: the three-axis air-bearing attitude simulator
of Ahangarani Farahani, Adami & Arefkhani (GA-tuned state-dependent PID; venue and year are
not in the extracted text, so the preset is named after the platform)."""

from __future__ import annotations

import numpy as np

from attitude_envs.presets import Preset, Sourced, register

RPM = 2.0 * np.pi / 60.0
PAPER = "Ahangarani Farahani et al."
CITATION = (
    "A. Ahangarani Farahani, A. Adami, H. Arefkhani, Laboratory test of a nonlinear attitude-control "
    "algorithm for a satellite simulator with state-dependent gains (GA-tuned PID)"
)

AIR_BEARING_85KG = register(
    Preset(
        name="air-bearing-85kg",
        env="AirBearing-v0",
        description="85 kg three-axis air-bearing platform, three orthogonal wheels, centre-of-mass offset",
        citation=CITATION,
        default=True,
        values={
            "inertia_kg_m2": Sourced(
                np.array([[6.75, 0.89, 0.035], [0.89, 7.46, -0.032], [0.035, -0.032, 12.33]]),
                f"{PAPER}, Table 1 (used as the full inertia tensor)",
            ),
            "wheel_axes": Sourced(np.eye(3), "assumed: three orthogonal wheels, one per body axis"),
            "wheel_inertia_kg_m2": Sourced(
                0.01,
                "assumed: the paper gives no wheel data; 0.01 kg·m² at 6000 rpm stores 6.3 N·m·s, "
                "about 1 rad/s of the platform's 7 kg·m² axes",
            ),
            "max_wheel_speed_rad_s": Sourced(6000.0 * RPM, "assumed: the paper gives no wheel speed limit"),
            "max_wheel_torque_nm": Sourced(0.8, f"{PAPER}, Table 1 (printed 8/0, Persian decimal)"),
            "control_dt_s": Sourced(0.01, "assumed: 100 Hz zero-order hold"),
            "integrator_dt_s": Sourced(0.01, "assumed: one RK4 step per control period"),
            "episode_duration_s": Sourced(20.0, f"{PAPER}, §2: 20 s runs"),
            "Q": Sourced(
                np.diag([4.0, 4.0, 4.0, 1.0, 1.0, 1.0]),
                "assumed: the paper scores IAE; 4|q_e,vec|² ≈ angle² (rad²), rates and torque weighted alike",
            ),
            "R": Sourced(np.eye(3), "assumed: see Q"),
            "cost_input": Sourced("body", "assumed: the cost weights body torque"),
            "target_attitude": Sourced(np.array([0.0, 0.0, 0.0, 1.0]), f"{PAPER}: regulation to zero angles"),
            "initial_rate_max_rad_s": Sourced(np.radians(2.0), "assumed: initial rates uniform in ±2 °/s"),
            "offset_torque_nm": Sourced(
                np.array([0.0014, 1.025e-4, 0.3366]), f"{PAPER}, Table 1: gravity-vector torque m g r_s"
            ),
            "tilt_limit_deg": Sourced(40.0, f"{PAPER}, Table 1: roll and pitch travel of the bearing"),
            "initial_euler_max_deg": Sourced(
                np.array([20.0, 20.0, 45.0]), "assumed: random starts well inside the tilt stops"
            ),
        },
    )
)
