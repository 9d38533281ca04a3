"""Presets ``heravi-2017``: the 1000 kg·m² satellite with four wheels tilted 20° of
Heravi & Novinzadeh (2017), for ReactionWheel-v0 (the nonlinear plant); the
Euler-discretized linear model of the same paper is LinearSystem-v0's preset."""

from __future__ import annotations

import numpy as np

from attitude_envs.plants.gyrostat import pyramid_axes
from attitude_envs.presets import Preset, Sourced, register

RPM = 2.0 * np.pi / 60.0
PAPER = "Heravi & Novinzadeh 2017"
CITATION = (
    "F. Taji Heravi, A. Basohbat Novinzadeh, Design of satellite attitude control using a model-free "
    "optimal control method, Journal of Space Science and Technology 10(3), 2017"
)
# Eq. 74, read scalar-first and normalized; stored scalar-last.
_Q0 = np.array([0.3722, -0.4329, 0.6645, 0.4783]) / np.linalg.norm([0.3722, -0.4329, 0.6645, 0.4783])

HERAVI_2017 = register(
    Preset(
        name="heravi-2017",
        env="ReactionWheel-v0",
        description="1000 kg·m² satellite, 4 wheels tilted 20°: regulation from the paper's initial state",
        citation=CITATION,
        aliases=("spec-001",),
        values={
            "inertia_kg_m2": Sourced(np.diag([1000.0, 1000.0, 800.0]), f"{PAPER}, eq. 71"),
            "wheel_axes": Sourced(pyramid_axes(20.0, 4, 0.0), f"{PAPER}, eqs. 63 and 75"),
            "wheel_inertia_kg_m2": Sourced(0.1, f"{PAPER} (units assumed kg·m²)"),
            "max_wheel_torque_nm": Sourced(1.0, "assumed: the paper's peak wheel torque is about 0.8 N·m"),
            "max_wheel_speed_rad_s": Sourced(6000.0 * RPM, "assumed: the paper gives no speed limit"),
            "control_dt_s": Sourced(0.01, f"{PAPER}: Δt = 0.01 s"),
            "integrator_dt_s": Sourced(0.01, f"{PAPER}: Δt = 0.01 s"),
            "episode_duration_s": Sourced(400.0, "assumed: the paper's LQR settles at about 364 s"),
            "Q": Sourced(np.eye(6), f"{PAPER}: Q = I"),
            "R": Sourced(np.eye(3), f"{PAPER}: R = I on body torque"),
            "cost_input": Sourced("body", f"{PAPER}: the input is the body torque"),
            "initial_attitude": Sourced(_Q0, f"{PAPER}, eq. 74 (scalar-first, normalized)"),
            "initial_rate_rad_s": Sourced(np.array([0.01, -0.02, 0.01]), f"{PAPER}, eq. 72"),
            "target_attitude": Sourced(np.array([0.0, 0.0, 0.0, 1.0]), f"{PAPER}: regulation to identity"),
            "initial_angle_deg": Sourced(0.0, f"{PAPER}: fixed initial state"),
            "target_angle_deg": Sourced(0.0, f"{PAPER}: fixed target"),
            "initial_rate_max_rad_s": Sourced(0.0, f"{PAPER}: fixed initial rate"),
        },
    )
)


# ---------------------------------------------------------------------- LinearSystem-v0
def _euler_linear_model() -> dict[str, np.ndarray]:
    """The paper's linearized quaternion/rate model (eq. 59: ẋ = [[0, ½I₃], [0, 0]] x +
    [[0], [J⁻¹]] u, x = [q₁, q₂, q₃, ω₁, ω₂, ω₃], J of eq. 71) discretized by forward Euler
    (eqs. 61–62: A_d = I + AΔt, B_d = BΔt, Δt = 0.01 s), and the initial state: the vector
    part of eq. 74's quaternion read scalar-first and normalized, the rates of eq. 72."""
    dt = 0.01
    inertia = np.array([1000.0, 1000.0, 800.0])
    A = np.eye(6)
    A[:3, 3:] = 0.5 * dt * np.eye(3)
    B = np.zeros((6, 3))
    B[3:, :] = dt * np.diag(1.0 / inertia)
    q0 = np.array([0.4783, 0.3722, -0.4329, 0.6645])
    q0 = q0 / np.linalg.norm(q0)
    x0 = np.concatenate([q0[1:], [0.01, -0.02, 0.01]])
    return {"A": A, "B": B, "x0": x0}


_LINEAR = _euler_linear_model()

HERAVI_2017_LINEAR = register(
    Preset(
        name="heravi-2017",
        env="LinearSystem-v0",
        description="the 1000 kg·m² satellite's linearized quaternion/rate model, forward-Euler discretized "
        "(Δt = 0.01 s), from the paper's initial state",
        citation=CITATION,
        aliases=("spec-001",),
        default=True,
        values={
            "A": Sourced(_LINEAR["A"], f"{PAPER}, eq. 59 discretized by forward Euler (eqs. 61–62), Δt = 0.01 s"),
            "B": Sourced(_LINEAR["B"], f"{PAPER}, eq. 59 with J = diag(1000, 1000, 800) kg·m² (eq. 71), eqs. 61–62"),
            "Q": Sourced(np.eye(6), f"{PAPER}: Q = I₆"),
            "R": Sourced(np.eye(3), f"{PAPER}: R = I₃ on the body torque"),
            "x0_mean": Sourced(
                _LINEAR["x0"], f"{PAPER}, eqs. 72 and 74 (quaternion read scalar-first, normalized; vector part)"
            ),
            "x0_std": Sourced(0.0, f"{PAPER}: one fixed initial state"),
            "action_scale": Sourced(
                2.0, "assumed: ±2 N·m body torque per axis; the paper's LQR needs about 1.1 N·m from its initial state"
            ),
            "dt_s": Sourced(0.01, f"{PAPER}: Δt = 0.01 s"),
        },
    )
)
