"""Bad input raises a ValueError that names the parameter."""

import math
import re

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs

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
        ({"episode_steps": 0}, "episode_steps must be an integer >= 1"),
        ({"episode_steps": 10.5}, "episode_steps must be an integer >= 1"),
        ({"Q": -np.eye(6)}, "Q must be positive semi-definite"),
    ],
)
def test_linear_system_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("attitude_envs/LinearSystem-v0", **kwargs)


# ---------------------------------------------------------------- constructor arguments
# Every numeric keyword of every env with a value outside its accepted range. Strings are
# refused too, numeric ones included: as Gymnasium's envs, no coercion (YAML's 1e-3 is a string).
_WHEEL_ENV = {
    "wheel_inertia_kg_m2": 0.0,
    "max_wheel_torque_nm": -1.0,
    "max_wheel_speed_rad_s": -1.0,
    "control_dt_s": 0.0,
    "integrator_dt_s": -0.01,
    "episode_duration_s": 0.0,
    "wheel_momentum_weight": -1.0,
    "target_angle_deg": 181.0,
    "initial_angle_deg": -1.0,
    "initial_rate_max_rad_s": -0.1,
    "tilt_limit_deg": 90.0,
    "max_rate_rad_s": 0.0,
}
OUT_OF_RANGE = {
    "attitude_envs/ReactionWheel-v0": _WHEEL_ENV,
    "attitude_envs/AirBearing-v0": _WHEEL_ENV,
    "attitude_envs/LinearSystem-v0": {
        "process_noise_std": -0.1,
        "episode_steps": 0,
        "divergence_threshold": 0.0,
        "dt_s": 0.0,
        "control_dt_s": 0.0,
    },
    "attitude_envs/FuelSlosh-v0": {
        "max_gimbal_deg": 91.0,
        "max_moment_nm": 0.0,
        "control_dt_s": 0.0,
        "integrator_dt_s": 0.0,
        "episode_duration_s": -1.0,
        "max_slosh_angle_deg": 0.0,
        "max_pitch_rate_rad_s": 0.0,
        "max_pitch_angle_deg": 0.0,
        "design_v_x_m_s": math.inf,
    },
    "attitude_envs/Magnetorquer-v0": {
        "initial_angle_deg": 181.0,
        "initial_rate_max_rad_s": -1.0,
        "wheel_inertia_kg_m2": 0.0,
        "max_dipole_am2": 0.0,
        "max_wheel_torque_nm": 0.0,
        "max_wheel_momentum_nms": 0.0,
        "dipole_strength_t_m3": 0.0,
        "disturbance_scale": -1.0,
        "control_dt_s": 0.0,
        "integrator_dt_s": 0.0,
        "episode_duration_s": 0.0,
        "max_rate_rad_s": 0.0,
    },
}
# array keywords (and the keywords they need alongside)
ARRAYS = {
    "attitude_envs/ReactionWheel-v0": [
        "inertia_kg_m2",
        "wheel_axes",
        "Q",
        "R",
        "target_attitude",
        "initial_attitude",
        "initial_rate_rad_s",
        "offset_torque_nm",
        "true_offset_torque_nm",
    ],
    "attitude_envs/AirBearing-v0": ["initial_euler_max_deg", "inertia_kg_m2", "offset_torque_nm"],
    "attitude_envs/LinearSystem-v0": ["A", "B", "Q", "R", "x0_mean", "x0_std", "action_scale"],
    "attitude_envs/FuelSlosh-v0": ["Q", "R", "initial_state"],
    "attitude_envs/Magnetorquer-v0": ["inertia_kg_m2", "target_euler_deg", "Q", "R"],
}
_NEEDS = {
    ("attitude_envs/LinearSystem-v0", "A"): {"B": [[1.0]]},
    ("attitude_envs/LinearSystem-v0", "B"): {"A": [[1.0]]},
}


def test_every_env_has_its_numeric_keywords_listed():
    assert set(OUT_OF_RANGE) == set(ARRAYS) == set(attitude_envs.ENV_IDS)


def _numeric_cases():
    for env_id, table in OUT_OF_RANGE.items():
        for name, bad in table.items():
            for value in ("0.1", "fast", bad):
                yield pytest.param(env_id, name, value, id=f"{env_id.split('/')[1]}-{name}-{value!r}")


@pytest.mark.parametrize(("env_id", "name", "value"), list(_numeric_cases()))
def test_numeric_keyword_of_wrong_type_or_range_is_named(env_id, name, value):
    with pytest.raises(ValueError) as exc:
        gym.make(env_id, **{name: value})
    message = str(exc.value)
    assert message.startswith(f"{name} must be "), message  # the parameter, first
    assert repr(value) in message and "\n" not in message  # the value given, one line
    if isinstance(value, str):  # the accepted type and range
        assert re.search(r"must be (a number in [\[(].*, .*[)\]]|an integer >= \d)", message), message
        if value == "0.1":
            assert f"pass {name}=0.1, a number, not a string" in message
    else:
        assert re.search(r"must be (in [\[(].*, .*[)\]]|an integer >= \d)", message), message


def _array_cases():
    for env_id, names in ARRAYS.items():
        for name in names:
            yield pytest.param(env_id, name, id=f"{env_id.split('/')[1]}-{name}")


@pytest.mark.parametrize(("env_id", "name"), list(_array_cases()))
def test_array_keyword_given_as_a_string_is_named(env_id, name):
    kwargs = {**_NEEDS.get((env_id, name), {}), name: "1"}
    with pytest.raises(ValueError, match=rf"^{name} must be numeric \(numbers, not strings\), got '1'$"):
        gym.make(env_id, **kwargs)


def test_yaml_exponent_strings_get_a_hint():
    with pytest.raises(ValueError, match=r"YAML reads 1e-3 as a string: write 1.0e-3"):
        gym.make("attitude_envs/FuelSlosh-v0", integrator_dt_s="1e-3")


def test_numbers_of_numpy_types_are_accepted():
    env = gym.make("attitude_envs/LinearSystem-v0", dt_s=np.float32(0.5), episode_steps=np.int64(7)).unwrapped
    assert env.model.dt_s == 0.5 and env.episode_steps == 7 and type(env.episode_steps) is int
    assert gym.make("attitude_envs/LinearSystem-v0", episode_steps=7.0).unwrapped.episode_steps == 7


@pytest.mark.parametrize("env_id", sorted(attitude_envs.ENV_IDS))
def test_unknown_keyword_is_named_with_the_accepted_ones(env_id):
    with pytest.raises(ValueError) as exc:
        gym.make(env_id, control_dt="fast")
    message = str(exc.value)
    assert "\n" not in message and f"'{env_id}'" in message and "no keyword argument 'control_dt'" in message
    assert "(accepted: [" in message and "'fault_hint'" in message
