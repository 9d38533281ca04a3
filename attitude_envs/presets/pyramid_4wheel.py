"""ReactionWheel-v0 preset ``pyramid-4wheel``: a 4 kg·m² spacecraft with a pyramid of four
reaction wheels, from the feedback-linearization paper (Modares Mechanical Engineering;
the extracted text lost its title and authors, so the preset is named after the spacecraft).
"""

from __future__ import annotations

import numpy as np

from attitude_envs.plants.gyrostat import pyramid_axes
from attitude_envs.presets import Preset, Sourced, register

RPM = 2.0 * np.pi / 60.0
PAPER = "quaternion feedback linearization vs. LQR (Modares Mech. Eng.)"

PYRAMID_4WHEEL = register(
    Preset(
        name="pyramid-4wheel",
        env="ReactionWheel-v0",
        description="4 kg·m² spacecraft, 4-wheel pyramid (β = 35.26°, θ = 45°): rest-to-rest maneuvers",
        citation=f"Spacecraft attitude control by {PAPER}",
        aliases=("spec-000",),
        default=True,
        values={
            "inertia_kg_m2": Sourced(np.diag([4.0, 4.0, 3.0]), f"{PAPER}, §2 (simulation parameters)"),
            "wheel_axes": Sourced(
                pyramid_axes(np.degrees(np.arctan(1.0 / np.sqrt(2.0))), 4, 45.0), f"{PAPER}, eq. 10 (pyramid)"
            ),
            "wheel_inertia_kg_m2": Sourced(5e-4, f"{PAPER}, §2 (simulation parameters)"),
            "max_wheel_torque_nm": Sourced(
                0.5,
                "assumed: the paper gives no torque limit; 0.5 N·m is above the peak wheel torque "
                "of all six published maneuvers, so their results are unaffected",
            ),
            "max_wheel_speed_rad_s": Sourced(5400.0 * RPM, f"{PAPER}: rated wheel speed 5400 rpm"),
            "control_dt_s": Sourced(0.1, "assumed: 10 Hz control for learning; the reproduction uses 0.01 s"),
            "integrator_dt_s": Sourced(0.1, "assumed: one RK4 step per control period"),
            "episode_duration_s": Sourced(60.0, f"{PAPER}: 60 s simulations"),
            "Q": Sourced(np.diag([170.0] * 3 + [13131.0] * 3), f"{PAPER}, eq. 75 (weights on q_vec and ω)"),
            "R": Sourced(2500.0 * np.eye(3), f"{PAPER}, eq. 76 (weight on body torque)"),
            "cost_input": Sourced("body", f"{PAPER}, eq. 76: the weight is on body torque"),
            "initial_angle_deg": Sourced(0.0, f"{PAPER}: maneuvers start at rest from identity"),
            "target_angle_deg": Sourced(60.0, "assumed: random rest-to-rest targets within 60°"),
            "initial_rate_max_rad_s": Sourced(0.0, f"{PAPER}: maneuvers start at rest"),
        },
    )
)
