"""Parameter presets of the papers' reaction-wheel spacecraft (defaults of ReactionWheel-v0).

Every value is tagged with its source in the specs (``../shared/spec``); values a paper
does not give are marked ASSUMED with the reason.
"""

from __future__ import annotations

import numpy as np

from attitude_envs.plants.gyrostat import pyramid_axes

RPM = 2.0 * np.pi / 60.0

PRESETS: dict[str, dict] = {
    # Spec 000 (feedback linearization vs LQR): §2.4, §2.6, §3.2.
    "spec-000": {
        "description": "4 kg·m² spacecraft, 4-wheel pyramid (β = 35.26°, θ = 45°), spec 000",
        "inertia_kg_m2": np.diag([4.0, 4.0, 3.0]),  # READ §2.6
        "wheel_axes": pyramid_axes(np.degrees(np.arctan(1.0 / np.sqrt(2.0))), 4, 45.0),  # READ eq. 10
        "wheel_inertia_kg_m2": 5e-4,  # READ §2.6
        # ASSUMED: the paper gives no torque limit (§7 item 8); 0.5 N·m stays above the
        # peak wheel torque of all six published maneuvers, so the table is unaffected.
        "max_wheel_torque_nm": 0.5,
        "max_wheel_speed_rad_s": 5400.0 * RPM,  # READ: rated speed (5000 rpm is the design margin)
        "control_dt_s": 0.1,  # ASSUMED: RL control period; reproductions use 0.01 s
        "integrator_dt_s": 0.1,
        "episode_duration_s": 60.0,  # READ: 60 s simulations
        "Q": np.diag([170.0] * 3 + [13131.0] * 3),  # READ eq. 75 (on q_vec and ω)
        "R": 2500.0 * np.eye(3),  # READ eq. 76 (on body torque)
        "cost_input": "body",
        "initial_angle_deg": 0.0,  # READ: maneuvers start at rest from identity
        "target_angle_deg": 60.0,  # ASSUMED: random rest-to-rest targets within 60°
        "initial_rate_max_rad_s": 0.0,
    },
    # Spec 001 (model-free Q-learning LQR): §2.4, §2.5, §4.
    "spec-001": {
        "description": "1000 kg·m² satellite, 4 wheels tilted 20°, spec 001",
        "inertia_kg_m2": np.diag([1000.0, 1000.0, 800.0]),  # READ eq. 71
        "wheel_axes": pyramid_axes(20.0, 4, 0.0),  # READ eqs. 63, 75
        "wheel_inertia_kg_m2": 0.1,  # READ (units assumed kg·m²)
        "max_wheel_torque_nm": 1.0,  # ASSUMED: paper peak ≈ 0.8 N·m (§5)
        "max_wheel_speed_rad_s": 6000.0 * RPM,  # ASSUMED: not given
        "control_dt_s": 0.01,  # READ Δt
        "integrator_dt_s": 0.01,
        "episode_duration_s": 400.0,  # ASSUMED: LQR settles at ≈ 364 s (§7)
        "Q": np.eye(6),  # READ
        "R": np.eye(3),  # READ (on body torque u_τ)
        "cost_input": "body",
        # READ eq. 74, scalar-first reading normalized (§2.4), stored scalar-last.
        "initial_attitude": np.array([0.3722, -0.4329, 0.6645, 0.4783])
        / np.linalg.norm([0.3722, -0.4329, 0.6645, 0.4783]),
        "initial_rate_rad_s": np.array([0.01, -0.02, 0.01]),  # READ eq. 72
        "target_attitude": np.array([0.0, 0.0, 0.0, 1.0]),
        "initial_angle_deg": 0.0,
        "target_angle_deg": 0.0,
        "initial_rate_max_rad_s": 0.0,
    },
}


def preset(name: str) -> dict:
    """A copy of the named preset's parameters."""
    if name not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {name!r}")
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in PRESETS[name].items()}
