"""Flight conditions: the keyword, the actuator chain's physics, slower sensors, and the
gyrostat envs under them (the lab stays the lab)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.integrate import solve_ivp

import attitude_envs  # noqa: F401
from attitude_envs.actuator_dynamics import ActuatorChain, ActuatorModel
from attitude_envs.conditions import FLIGHT_CONDITIONS, Conditions
from attitude_envs.envs.reaction_wheel import misaligned_axes
from attitude_envs.presets import flight
from attitude_envs.sensors import Channel, SensorSuite

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"


# ---------------------------------------------------------------- the keyword
@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (None, Conditions()),
        ("lab", Conditions()),
        ("flight", FLIGHT_CONDITIONS),
        ({"delay_steps": 2}, Conditions(delay_steps=2)),
        ({"delay_steps": True}, Conditions(delay_steps=1)),
        ({"sensors": 3}, Conditions(sensors=3.0)),
        ({"base": "flight", "delay_steps": 0}, Conditions(1.0, True, 0, 1.0)),
        ({"parameters": False, "base": "flight"}, Conditions(1.0, True, 1, 0.0)),
    ],
)
def test_conditions_resolve(value, expected):
    c = Conditions.from_config(value)
    assert c == expected
    assert Conditions.from_config(c.as_dict()) == c


def test_conditions_names():
    assert Conditions().name == "lab" and Conditions().is_lab
    assert FLIGHT_CONDITIONS.name == "flight"
    assert Conditions(delay_steps=1).name == "custom"


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ("space", "conditions must be 'lab', 'flight'"),
        ({"delay": 1}, "delay"),
        ({"delay_steps": -1}, "conditions['delay_steps']"),
        ({"delay_steps": 11}, "[0, 10]"),
        ({"delay_steps": 1.5}, "conditions['delay_steps']"),
        ({"sensors": -2}, "conditions['sensors']"),
        ({"parameters": "1"}, "conditions['parameters']"),
        ({"actuators": 1}, "conditions['actuators']"),
        ({"base": "orbit"}, "conditions['base']"),
        (3, "conditions must be"),
    ],
)
def test_conditions_bad_input_names_the_key(value, fragment):
    with pytest.raises(ValueError, match=None) as err:
        Conditions.from_config(value)
    assert fragment in str(err.value)


def test_env_rejects_bad_conditions_by_name():
    with pytest.raises(ValueError, match=r"conditions\['delay_steps'\]"):
        gym.make(RW, conditions={"delay_steps": -1})
    with pytest.raises(ValueError, match=r"conditions\['parameters'\] must be in \[0, 10\]"):
        gym.make(RW, conditions={"parameters": 11})


# ---------------------------------------------------------------- the actuator chain
def _chain(delay=0, dt=0.1, **entries):
    model = ActuatorModel.build(np.array([1.0, 2.0]), **entries) if entries else None
    chain = ActuatorChain(model, delay, dt)
    chain.reset(2)
    return chain


def _no_faults(c):
    return c


def test_delay_line_acts_late_with_zeros_first():
    chain = _chain(delay=2)
    cmds = [np.array([0.1 * k, -0.1 * k]) for k in range(1, 6)]
    out = [chain.deliver(c, _no_faults) for c in cmds]
    np.testing.assert_array_equal(out[0], 0.0)
    np.testing.assert_array_equal(out[1], 0.0)
    for k in range(2, 5):
        np.testing.assert_array_equal(out[k], cmds[k - 2])


def test_lag_period_mean_is_the_exact_response_mean():
    """The held output is the period mean of the first-order lag's exact response, and the
    lag's state follows it across periods (checked against scipy's integration)."""
    tau, dt = 0.03, 0.1
    chain = _chain(dt=dt, lag_s=tau)
    cmds = [np.array([0.5, -1.0]), np.array([-0.2, 0.4]), np.array([0.9, 0.0])]
    y = np.zeros(2)
    for c in cmds:
        mean = chain.deliver(c, _no_faults)
        sol = solve_ivp(
            lambda t, z, c=c: np.concatenate([(c - z[:2]) / tau, z[:2]]),
            (0.0, dt),
            np.concatenate([y, np.zeros(2)]),
            rtol=1e-11,
            atol=1e-13,
        )
        y = sol.y[:2, -1]
        np.testing.assert_allclose(mean, sol.y[2:, -1] / dt, rtol=1e-8, atol=1e-12)


def test_resolution_rate_limit_gain_duty_and_friction():
    chain = _chain(resolution=[0.1, 0.0], rate_limit=[math.inf, 1.0], duty=[0.8, 1.0], coulomb=[0.0, 0.01])
    chain.reset(2, gain=np.array([1.1, 0.9]))
    out = chain.deliver(np.array([0.123, 2.0]), _no_faults, speeds=np.array([0.0, 5.0]))
    # (the model's entries are absolute: N·m, N·m/s) 0.123 → 0.1 (resolution 0.1) × gain 1.1 ×
    # duty 0.8; 2.0 → 0.1 (rate 1.0/s over 0.1 s) × 0.9 − Coulomb 0.01 at a positive speed
    np.testing.assert_allclose(out, [0.1 * 1.1 * 0.8, 0.1 * 0.9 - 0.01])
    out = chain.deliver(np.array([0.123, 2.0]), _no_faults, speeds=np.array([0.0, -5.0]))
    np.testing.assert_allclose(out[1], 0.2 * 0.9 + 0.01)


def test_actuator_model_rejects_bad_entries():
    with pytest.raises(ValueError, match="actuator duty"):
        ActuatorModel.build(np.ones(2), duty=1.5)
    with pytest.raises(ValueError, match="actuator lag_s"):
        ActuatorModel.build(np.ones(2), lag_s=[-1.0, 0.0])
    with pytest.raises(ValueError, match="unknown entries"):
        ActuatorModel.build(np.ones(2), backlash=0.1)


# ---------------------------------------------------------------- slower sensors
def test_sensor_period_holds_samples_between_updates():
    suite = SensorSuite({"star": {"noise_std": 1.0, "period_s": 0.5}}, [Channel("star", 2)])
    suite.reset(np.random.default_rng(0))
    readings = [suite.measure({"star": np.zeros(2)}, 0.1 * k) for k in range(11)]
    values = [r["star"][0] for r in readings]
    assert values[0] == values[4] and values[5] == values[9] and values[10] != values[9]
    assert values[0] != values[5]


# ---------------------------------------------------------------- the envs
def _episode(env_id, seed=1, steps=30, **kwargs):
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    rows = [(obs, 0.0, info)]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(np.full(env.action_space.shape, 0.2, np.float32))
        rows.append((obs, reward, info))
        if terminated or truncated:
            break
    return env, rows


@pytest.mark.parametrize("env_id", [RW, AB])
def test_lab_keyword_is_the_env_without_it(env_id):
    _, plain = _episode(env_id)
    _, lab = _episode(env_id, conditions="lab")
    for (o1, r1, _), (o2, r2, _) in zip(plain, lab, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2


@pytest.mark.parametrize("env_id", [RW, AB])
def test_flight_starts_where_the_lab_starts(env_id):
    _, lab = _episode(env_id, steps=0)
    _, fl = _episode(env_id, steps=0, conditions="flight")
    for key in ("attitude", "rate_rad_s", "target_attitude"):
        np.testing.assert_array_equal(lab[0][2]["truth"]["state"][key], fl[0][2]["truth"]["state"][key])
    assert "drawn_parameters" in fl[0][2]["truth"] and "drawn_parameters" not in lab[0][2]["truth"]


@pytest.mark.parametrize("env_id", [RW, AB])
def test_flight_env_passes_the_checker(env_id):
    check_env(gym.make(env_id, conditions="flight").unwrapped)


def test_parameter_draws_are_within_the_tolerances_and_differ_by_seed():
    table = flight.table("ReactionWheel-v0")
    env = gym.make(RW, conditions={"parameters": 1})
    nominal = env.unwrapped.model.params
    draws = []
    for seed in range(5):
        env.reset(seed=seed)
        d = env.unwrapped.drawn_parameters()
        draws.append(d)
        moments = np.linalg.eigvalsh(d["inertia_kg_m2"])
        # the sum of moments moves by at most the moment tolerance
        assert abs(moments.sum() / np.trace(nominal.inertia_kg_m2) - 1.0) <= table.plant_value("inertia_moment")
        tilt = np.degrees(np.arccos(np.clip(np.sum(d["wheel_axes"] * nominal.wheel_axes, axis=0), -1, 1)))
        assert np.all(tilt <= table.plant_value("wheel_misalignment_deg") + 1e-9)
        assert np.all(np.abs(d["actuator_gain"] - 1.0) <= table.gain_tolerance_of(4))
        np.testing.assert_array_equal(env.unwrapped.kernel_matrices[:9].reshape(3, 3), d["inertia_kg_m2"])
    assert not np.array_equal(draws[0]["inertia_kg_m2"], draws[1]["inertia_kg_m2"])
    env.reset(seed=3)
    np.testing.assert_array_equal(env.unwrapped.drawn_parameters()["wheel_axes"], draws[3]["wheel_axes"])


def test_misaligned_axes_tilt_within_the_angle():
    axes = np.eye(3)
    out = misaligned_axes(axes, 0.5, np.random.default_rng(0))
    np.testing.assert_allclose(np.linalg.norm(out, axis=0), 1.0)
    tilt = np.degrees(np.arccos(np.clip(np.sum(out * axes, axis=0), -1.0, 1.0)))
    assert np.all(tilt <= 0.5 + 1e-12) and np.all(tilt > 0)


def test_delay_makes_the_first_step_deliver_nothing():
    _, rows = _episode(RW, steps=2, conditions={"delay_steps": 1})
    np.testing.assert_array_equal(rows[1][2]["truth"]["applied"], 0.0)
    np.testing.assert_allclose(rows[2][2]["truth"]["applied"], rows[1][2]["commanded"])


def test_flight_sensors_observe_a_slow_star_tracker():
    _, rows = _episode(RW, steps=8, conditions={"sensors": True})
    star = [r[2]["sensors"]["star_tracker"] for r in rows]
    # 1.7 Hz under 10 Hz control: the first sample repeats until t ≥ 0.588 s
    for k in range(1, 6):
        np.testing.assert_array_equal(star[k], star[0])
    assert not np.array_equal(star[6], star[0])


def test_sensor_noise_scale_scales_the_noise():
    base = flight.table("ReactionWheel-v0").sensor_config(1.0)
    big = flight.table("ReactionWheel-v0").sensor_config(10.0)
    assert big["gyro"]["noise_std"] == pytest.approx(10 * base["gyro"]["noise_std"])
    assert big["star_tracker"]["period_s"] == base["star_tracker"]["period_s"]


def test_every_flight_value_has_a_source():
    for family in ("ReactionWheel-v0", "AirBearing-v0"):
        rows = flight.table(family).sources()
        assert rows
        for name, value, source in rows:
            assert source.strip(), name
            assert np.all(np.isfinite(np.asarray(value, dtype=float))), name


def test_batched_env_refuses_flight_conditions():
    with pytest.raises(ValueError, match="lab conditions only"):
        gym.make_vec(RW, num_envs=2, vectorization_mode="vector_entry_point", conditions={"delay_steps": 1})
