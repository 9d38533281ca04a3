"""Bad input raises a ValueError that names the parameter."""

import gymnasium as gym
import numpy as np
import pytest

RW = "attitude_envs/ReactionWheel-v0"


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"inertia_kg_m2": [[4, 0.5, 0], [0, 4, 0], [0, 0, 3]]}, "inertia_kg_m2 must be symmetric"),
        ({"inertia_kg_m2": np.diag([4.0, -1.0, 3.0])}, "inertia_kg_m2 must be positive definite"),
        ({"inertia_kg_m2": np.diag([1.0, 1.0, 3.0])}, "inertia_kg_m2 violates the triangle inequality"),
        ({"inertia_kg_m2": np.eye(2)}, r"inertia_kg_m2 must have shape \(3, 3\)"),
        ({"wheel_axes": np.zeros((3, 0))}, "wheel_axes must be a 3xN matrix with N >= 1"),
        ({"wheel_axes": [[1, 1, 0], [0, 0, 1], [0, 0, 0.0]]}, "wheel_axes must have rank 3"),
        ({"wheel_axes": 2 * np.eye(3)}, "wheel_axes columns must be unit vectors"),
        ({"max_wheel_torque_nm": -0.1}, r"max_wheel_torque_nm must be in \(0, inf\)"),
        ({"max_wheel_speed_rad_s": -1.0}, r"max_wheel_speed_rad_s must be in \(0, inf\]"),
        ({"wheel_inertia_kg_m2": 0.0}, "wheel_inertia_kg_m2 must be in"),
        ({"wheel_inertia_kg_m2": 3.0}, "wheel_inertia_kg_m2 is too large"),
        ({"control_dt_s": 0.1, "integrator_dt_s": 0.03}, "integer multiple of integrator_dt_s"),
        ({"control_dt_s": 0.0}, "control_dt_s must be in"),
        ({"target_attitude": [0, 0, 0, 2.0]}, "target_attitude must be a unit quaternion"),
        ({"initial_attitude": [0, 0, np.nan, 1.0]}, "initial_attitude must be finite"),
        ({"target_angle_deg": 200.0}, r"target_angle_deg must be in \[0, 180\]"),
        ({"Q": -np.eye(6)}, "Q must be positive semi-definite"),
        ({"R": np.zeros(3)}, "R must be positive definite"),
        ({"cost_input": "torque"}, "cost_input must be one of"),
        ({"preset": "spec-999"}, "preset must be one of"),
        ({"inertia_uncertainty": {"kind": "random", "moment_scale": 1.5}}, r"moment_scale must be in \[0, 1\)"),
        ({"inertia_uncertainty": {"kind": "gaussian"}}, "inertia_uncertainty.kind must be one of"),
        ({"disturbance": {"kind": "constant", "torque_nm": [1, 2]}}, r"disturbance.torque_nm must have shape \(3,\)"),
        ({"disturbance": {"kind": "sinusoidal", "period_s": -5}}, "disturbance.period_s must be in"),
        ({"disturbance": {"kind": "constant", "torq": [0, 0, 0]}}, "unknown keys"),
    ],
)
def test_reaction_wheel_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(RW, **kwargs)


def test_unknown_render_mode_is_rejected():
    from attitude_envs.envs import ReactionWheelEnv

    with pytest.raises(ValueError, match="render_mode must be one of"):
        ReactionWheelEnv(render_mode="ansi")


@pytest.mark.parametrize(
    "action,match",
    [
        (np.zeros(3), r"action must have shape \(4,\)"),
        (np.array([0.0, np.nan, 0.0, 0.0]), "action must be finite"),
        (np.array([0.0, np.inf, 0.0, 0.0]), "action must be finite"),
        ("full", "action must be numeric"),
    ],
)
def test_step_rejects_bad_actions(action, match):
    env = gym.make(RW).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_reset_rejects_non_unit_quaternions():
    env = gym.make(RW).unwrapped
    with pytest.raises(ValueError, match=r"options\['attitude'\] must be a unit quaternion"):
        env.reset(options={"attitude": [0.5, 0, 0, 0.5]})
    with pytest.raises(ValueError, match=r"options\['wheel_speed_rad_s'\] must have shape \(4,\)"):
        env.reset(options={"wheel_speed_rad_s": [0.0, 0.0]})


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"preset": None}, "A is required"),
        ({"preset": None, "A": [[1, 0]], "B": [[1]]}, "A must be a square"),
        ({"preset": None, "A": np.eye(2), "B": np.ones((3, 1))}, "B must be an n x m matrix"),
        ({"action_scale": -1.0}, "action_scale must be > 0"),
        ({"x0_std": -1.0}, "x0_std must be >= 0"),
        ({"process_noise_std": -0.1}, "process_noise_std must be in"),
        ({"episode_steps": 0}, "episode_steps must be >= 1"),
        ({"Q": -np.eye(6)}, "Q must be positive semi-definite"),
    ],
)
def test_linear_system_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("attitude_envs/LinearSystem-v0", **kwargs)
