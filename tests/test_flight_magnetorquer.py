"""Magnetorquer-v0 under flight conditions: the cited table, the flight env's API, starts
equal to the lab's, the drawn true inertia, the command delay, the torquers' duty cycle and
the wheel friction's sign, and the batched env's refusal."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs.presets import flight

MT = "attitude_envs/Magnetorquer-v0"
SHORT = {"episode_duration_s": 20.0}
ACTION = np.array([0.5, -0.3, 0.2, 0.4], dtype=np.float32)


def _make(conditions, **kwargs):
    return gym.make(MT, **SHORT, conditions=conditions, **kwargs).unwrapped


def test_flight_env_passes_the_env_checker_with_warnings_as_errors():
    env = _make("flight", observe_field=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)


@pytest.mark.parametrize("task", ["tracking", "regulation"])
def test_flight_episode_starts_where_the_lab_episode_of_the_same_seed_starts(task):
    for seed in (0, 3):
        _, lab = _make("lab", task=task).reset(seed=seed)
        _, fl = _make("flight", task=task).reset(seed=seed)
        for key, value in lab["truth"]["state"].items():
            np.testing.assert_array_equal(fl["truth"]["state"][key], value, err_msg=key)
        np.testing.assert_array_equal(fl["orbit"]["argument_of_latitude_rad"], lab["orbit"]["argument_of_latitude_rad"])


def test_parameters_draw_a_true_inertia_within_the_tolerance_and_per_seed():
    table = flight.table("Magnetorquer-v0")
    tol = table.plant_value("inertia_moment")
    env = _make({"parameters": 1}, time_varying_inertia=None)
    nominal = env.model.params.inertia_kg_m2
    nominal_moments = np.linalg.eigvalsh(nominal)
    drawn = []
    for seed in (0, 1, 2):
        _, info = env.reset(seed=seed)
        inertia = env.drawn_parameters()["inertia_kg_m2"]
        np.testing.assert_array_equal(info["truth"]["drawn_parameters"]["inertia_kg_m2"], inertia)
        moments = np.linalg.eigvalsh(inertia)
        assert np.all(np.abs(moments / nominal_moments - 1.0) <= tol + 1e-12)
        assert not np.allclose(inertia, nominal)
        np.testing.assert_array_equal(env.true_inertia_at(0.0), inertia)  # the plant integrates it
        drawn.append(inertia)
    assert not np.allclose(drawn[0], drawn[1]) and not np.allclose(drawn[1], drawn[2])
    env.reset(seed=1)
    np.testing.assert_array_equal(env.drawn_parameters()["inertia_kg_m2"], drawn[1])  # reproducible
    assert "inertia_kg_m2" not in _make("lab").drawn_parameters()


def test_a_one_period_delay_makes_the_first_step_deliver_zero_then_the_first_command():
    env = _make({"delay_steps": 1})
    env.reset(seed=0)
    _, _, _, _, info = env.step(ACTION)
    np.testing.assert_array_equal(info["truth"]["applied"], np.zeros(4))
    first = np.asarray(info["commanded"]).copy()
    _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    np.testing.assert_allclose(info["truth"]["applied"], first, rtol=1e-12)


def test_the_torquers_duty_cycle_and_the_drivers_resolution_scale_the_delivered_dipole():
    env = _make({"actuators": True})
    env.reset(seed=0)
    _, _, _, _, info = env.step(ACTION)
    commanded = np.asarray(info["commanded"])
    limit = env.model.params.max_dipole_am2
    lsb = limit / 255.0
    quantized = np.round(commanded[:3] / lsb) * lsb
    np.testing.assert_allclose(info["truth"]["applied"][:3], 0.8 * quantized, rtol=1e-12)
    assert np.all(np.abs(info["truth"]["applied"][:3] - 0.8 * commanded[:3]) <= 0.8 * lsb / 2 + 1e-15)
    # the wheel is always on: its torque only lags (0.02 s) and is quantized
    assert 0.0 < info["truth"]["applied"][3] < commanded[3]


def test_wheel_friction_opposes_the_wheel_spin_so_it_adds_to_the_body_torque():
    env = _make({"actuators": True})
    env.reset(seed=0, options={"wheel_speed_rad_s": [100.0]})
    _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    wheel_torque_on_body = info["truth"]["applied"][3]
    assert wheel_torque_on_body > 0.0  # the wheel (+Ω) is braked: −T_w on the wheel is negative
    np.testing.assert_array_equal(info["truth"]["applied"][:3], np.zeros(3))  # coils have no friction


def test_lab_delivers_the_command_exactly():
    env = _make("lab")
    env.reset(seed=0)
    _, _, _, _, info = env.step(ACTION)
    np.testing.assert_array_equal(info["truth"]["applied"][:3], info["commanded"][:3])
    assert env.conditions.is_lab and env.drawn_parameters() == {}


def test_every_flight_table_value_of_magnetorquer_has_a_source():
    table = flight.table("Magnetorquer-v0")
    rows = table.sources()
    names = {name for name, _, _ in rows}
    assert {"sensors.gyro.noise_std", "sensors.star_tracker.period_s", "sensors.magnetometer.noise_std"} <= names
    assert {"actuators.duty", "actuators.resolution", "delay_steps", "gain_tolerance", "plant.inertia_moment"} <= names
    for name, value, source in rows:
        assert isinstance(source, str) and source.strip(), name
        assert np.all(np.isfinite(np.asarray(value, dtype=float))), name
    assert table.actuators["duty"].value == (0.8, 0.8, 0.8, 1.0)
    # the flight sensors are the env's when flight is on
    env = _make("flight")
    assert env.sensor_layer.enabled
    assert env.sensor_layer.parameters("magnetometer")["noise_std"] == pytest.approx(10e-9)


def test_batched_env_refuses_flight_conditions():
    with pytest.raises(ValueError, match="conditions=.*batched env"):
        gym.make_vec(MT, num_envs=2, vectorization_mode="vector_entry_point", conditions={"delay_steps": 1})
