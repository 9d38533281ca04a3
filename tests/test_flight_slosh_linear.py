"""Flight conditions of FuelSlosh and LinearSystem: the checker, lab-equal starts, the drawn
plant within its tolerances, the delay, the gimbal slew limit, the unmeasured slosh states,
the batched envs' refusal, per-axis sensor noise and the tables' sources."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs.envs.fuel_slosh import FuelSloshEnv
from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.presets import flight
from attitude_envs.sensors import Channel, SensorSuite

FS, FS1 = "attitude_envs/FuelSlosh-v0", "attitude_envs/FuelSlosh-v1"
LS, LS1 = "attitude_envs/LinearSystem-v0", "attitude_envs/LinearSystem-v1"


def make(env_id: str, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the -v0 ids' note about their -v1
        return gym.make(env_id, **kwargs)


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [(FS, {}), (FS1, {"observe_slosh": False, "fault_hint": True}), (LS, {}), (LS1, {"fault_hint": True})],
)
def test_flight_envs_pass_the_checker(env_id, kwargs):
    check_env(make(env_id, conditions="flight", **kwargs).unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", [FS, FS1, LS, LS1])
def test_same_seed_starts_as_the_lab(env_id):
    """Flight draws come from a spawned generator: the true start equals the lab's."""
    lab, fl = make(env_id).unwrapped, make(env_id, conditions="flight").unwrapped
    for seed in (0, 7):
        lab.reset(seed=seed)
        fl.reset(seed=seed)
        assert np.array_equal(lab.state, fl.state)
        assert lab.np_random.bit_generator.state == fl.np_random.bit_generator.state


def test_slosh_plant_drawn_within_tolerance_and_per_seed():
    env = FuelSloshEnv(conditions="flight")
    nominal = env.model.params
    table = flight.table("FuelSlosh-v0")
    tol_m, tol_l = table.plant_value("slosh_mass"), table.plant_value("pendulum_length")
    draws = []
    for seed in range(6):
        env.reset(seed=seed)
        d = env.drawn_parameters()
        assert np.all(np.abs(d["slosh_mass_kg"] / np.array(nominal.slosh_mass_kg) - 1) <= tol_m)
        assert np.all(np.abs(d["length_m"] / np.array(nominal.length_m) - 1) <= tol_l)
        assert np.all(np.abs(d["actuator_gain"] - 1) <= table.gain_tolerance.value)
        # the fixed propellant takes the slosh mass change: the total mass is the nominal one
        total = d["fuel_mass_kg"] + d["slosh_mass_kg"].sum()
        assert total == pytest.approx(nominal.fuel_mass_kg + sum(nominal.slosh_mass_kg), rel=1e-12)
        draws.append(d["slosh_mass_kg"])
    assert len({tuple(m) for m in draws}) == len(draws)  # a new plant per episode
    env.reset(seed=3)
    again = env.drawn_parameters()
    env.reset(seed=3)
    assert np.array_equal(env.drawn_parameters()["length_m"], again["length_m"])
    # the controllers' model stays nominal; the compiled step runs the drawn plant
    assert env.model.params == nominal
    assert not np.array_equal(env.kernel_constants, FuelSloshEnv().kernel_constants)
    with pytest.raises(ValueError, match="must stay below 90 %"):
        FuelSloshEnv(conditions={"parameters": 7})


def test_linear_gain_drawn_within_tolerance_and_acts_on_b():
    env = LinearSystemEnv(conditions={"parameters": True})
    x0 = np.array([0.1, -0.2, 0.3, 0.01, 0.02, -0.01])
    env.reset(seed=4, options={"state": x0})
    gain = env.drawn_parameters()["actuator_gain"]
    assert gain.shape == (3,) and np.all(np.abs(gain - 1) <= 0.05) and not np.all(gain == 1)
    a = np.array([0.5, -1.0, 0.25])
    env.step(a)
    u = env.action_scale * a * gain
    assert np.allclose(env.state, env.model.A @ x0 + env.model.B @ u, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("env_id", "n_actions"), [(FS, 2), (LS, 3), (LS1, 3)])
def test_delay_delivers_zero_first(env_id, n_actions):
    env = make(env_id, conditions={"delay_steps": True}).unwrapped
    env.reset(seed=1)
    action = np.full(n_actions, 0.8, dtype=np.float32)
    first = env.step(action)[4]["truth"]["applied"]
    second = env.step(action)[4]["truth"]["applied"]
    assert np.all(first == 0.0)
    assert np.allclose(second, 0.8 * env.actuator_limits if env_id == FS else 0.8 * env.action_scale)


def test_gimbal_slew_rate_limit_holds_on_bang_bang():
    env = FuelSloshEnv(conditions="flight")
    env.reset(seed=2)
    limit = math.radians(10.0) * env.control_dt_s * np.max(env.drawn_parameters()["actuator_gain"])
    previous = 0.0
    for k in range(30):
        applied = env.step(np.array([(-1.0) ** (k // 3), 0.0], dtype=np.float32))[4]["truth"]["applied"]
        assert abs(applied[0] - previous) <= limit * (1 + 1e-12)
        previous = applied[0]
    # the moment is not rate-limited
    env.reset(seed=2)
    env.step(np.array([0.0, 1.0], dtype=np.float32))
    applied = env.step(np.array([0.0, 1.0], dtype=np.float32))[4]["truth"]["applied"]
    assert applied[1] == pytest.approx(env.model.max_moment_nm * env.drawn_parameters()["actuator_gain"][1])


def test_flight_sensors_do_not_measure_the_slosh():
    env = FuelSloshEnv(conditions="flight")
    obs, info = env.reset(seed=5)
    true = env.state[env.observation_index]
    assert np.all(obs[3:7] == 0.0) and not np.allclose(true[3:7], 0.0)
    assert np.all(obs[[0, 1, 2, 7]] != true[[0, 1, 2, 7]].astype(np.float32))  # measured, noisy
    assert np.abs(obs[1] - true[1]) < 1e-3  # θ within 1 mrad
    assert "slosh_angle_rad" not in info["measured"] and "theta_rad" in info["measured"]
    assert env.measured_entries.tolist() == [True, True, True, False, False, False, False, True]
    assert FuelSloshEnv().measured_entries.all() and LinearSystemEnv(conditions="flight").measured_entries.all()
    # an explicit sensors= replaces the flight sensors: then the slosh is measured
    env = FuelSloshEnv(conditions="flight", sensors={"state": {"noise_std": 0.0}})
    obs, info = env.reset(seed=5)
    assert np.array_equal(obs[3:7], env.state[env.observation_index][3:7].astype(np.float32))
    assert "slosh_angle_rad" in info["measured"]
    # observe_slosh=False: the four rigid-body entries, all measured
    env = FuelSloshEnv(conditions="flight", observe_slosh=False)
    obs, info = env.reset(seed=5)
    assert obs.shape == (4,) and np.all(obs != 0.0) and env.measured_entries.all()


def test_linear_flight_noise_is_a_fraction_of_the_state_scale():
    env = LinearSystemEnv(conditions={"sensors": True})
    std = env.sensor_layer.parameters("state")["noise_std"]
    assert np.allclose(std, 0.01 * env.state_scale)
    assert np.allclose(env.state_scale[3:], [0.01, 0.02, 0.01])  # the preset's fixed start
    env2 = LinearSystemEnv(A=np.eye(2), B=np.eye(2), x0_mean=[0.0, 3.0], x0_std=0.0, conditions="flight")
    assert np.array_equal(env2.state_scale, [3.0, 3.0])  # a zero entry takes the largest scale


@pytest.mark.parametrize("env_id", [FS, LS])
@pytest.mark.parametrize("conditions", ["flight", {"delay_steps": 1}, {"base": "flight", "sensors": 0}])
def test_batched_envs_refuse_flight(env_id, conditions):
    with pytest.raises(ValueError, match="runs the lab conditions only.*SyncVectorEnv"):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", conditions=conditions)
    gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", conditions="lab").close()


def test_per_axis_sensor_noise():
    suite = SensorSuite(
        {"state": {"noise_std": [0.0, 1.0, 0.0], "bias_walk_std": 0.0, "initial_bias_std": (0.0, 0.0, 2.0)}},
        [Channel("state", 3)],
    )
    params = suite.parameters("state")
    assert isinstance(params["bias_walk_std"], float) and params["noise_std"].shape == (3,)
    suite.reset(np.random.default_rng(0))
    assert suite.bias["state"][0] == 0.0 and suite.bias["state"][2] != 0.0
    m = suite.measure({"state": np.zeros(3)}, 0.1)["state"]
    assert m[0] == 0.0 and m[1] != 0.0
    with pytest.raises(ValueError, match=r"noise_std must be a number >= 0 or 3 of them"):
        SensorSuite({"state": {"noise_std": [1.0, 2.0]}}, [Channel("state", 3)])
    with pytest.raises(ValueError, match=r"noise_std must be a number >= 0 or 3 of them"):
        SensorSuite({"state": {"noise_std": [1.0, -2.0, 0.0]}}, [Channel("state", 3)])


@pytest.mark.parametrize("env_id", ["FuelSlosh-v0", "LinearSystem-v0"])
def test_every_table_value_has_a_source(env_id):
    rows = flight.table(env_id).sources()
    assert rows
    for name, value, source in rows:
        assert isinstance(source, str) and len(source.strip()) > 10, name
        assert value is not None, name
    slosh_noise = dict((r[0], r) for r in flight.table("FuelSlosh-v0").sources())["sensors.state.noise_std"]
    assert "not measured" in slosh_noise[2] and "as quoted by" in slosh_noise[2]
