"""The scenarios with room to win load, build their envs with their faults or mismatch, and
run one short episode; AirBearing-v0's true offset torque can differ from the nominal one."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs.scenarios import list_scenarios, load_scenario, make_scenario_env

# scenario -> (short episode, (kind, index, onset_s) of each actuator fault the env realizes)
SCENARIOS = {
    "two-wheel-failure": ({"episode_duration_s": 3.0}, [("outage", 0, 2.0), ("outage", 1, 2.0)]),
    "tight-torque": ({"episode_duration_s": 2.0}, []),
    "sadigh-2022-faults": (
        {"episode_duration_s": 1.0},
        [("loss_of_effectiveness", 0, 50.0), ("loss_of_effectiveness", 1, 50.0), ("loss_of_effectiveness", 2, 50.0)],
    ),
    "slosh-actuator-faults": (
        {"episode_duration_s": 1.0},
        [("loss_of_effectiveness", 0, 50.0), ("bias", 1, 50.0)],
    ),
    "air-bearing-outage": ({"episode_duration_s": 0.5}, [("outage", 2, 2.0)]),
    "air-bearing-offset-change": ({"episode_duration_s": 0.5}, []),
}


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenario_runs_a_short_episode_with_its_faults(name):
    assert name in list_scenarios()
    short, faults = SCENARIOS[name]
    env = make_scenario_env(load_scenario(name), **short)
    _, info = env.reset(seed=0)
    assert [(f["kind"], f["index"], f["onset_s"]) for f in info["truth"]["faults"]] == faults
    rng = np.random.default_rng(0)
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step(rng.uniform(-0.2, 0.2, env.action_space.shape).astype(np.float32))
        steps += 1
        assert np.isfinite(info["cost"])
        if terminated or truncated:
            break
    assert truncated and not terminated
    assert info["time_s"] == pytest.approx(short["episode_duration_s"])


def test_tight_torque_limits_the_wheels():
    env = make_scenario_env("tight-torque", episode_duration_s=0.5)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.ones(4, dtype=np.float32))
    assert np.allclose(info["truth"]["applied"], 0.01)
    assert env.unwrapped.model.params.max_wheel_torque_nm == 0.01


def test_air_bearing_offset_change_acts_on_the_plant_not_on_the_model():
    changed = make_scenario_env("air-bearing-offset-change", episode_duration_s=1.0)
    nominal = gym.make("attitude_envs/AirBearing-v0", episode_duration_s=1.0)
    base = changed.unwrapped
    assert np.array_equal(base.model.params.offset_torque_nm, nominal.unwrapped.model.params.offset_torque_nm)
    assert np.array_equal(base.true_offset_torque_nm, [0.04, -0.03, 0.25])
    assert np.array_equal(nominal.unwrapped.true_offset_torque_nm, nominal.unwrapped.model.params.offset_torque_nm)
    level = {"euler_321_deg": [0.0, 0.0, 0.0], "rate_rad_s": [0.0, 0.0, 0.0]}
    changed.reset(seed=0, options=level)
    nominal.reset(seed=0, options=level)
    zero = np.zeros(3, dtype=np.float32)
    rate_changed = changed.step(zero)[4]["truth"]["state"]["rate_rad_s"]
    rate_nominal = nominal.step(zero)[4]["truth"]["state"]["rate_rad_s"]
    # at level attitude the nominal offset is almost vertical (tiny torque); the changed one tilts the platform
    inertia = base.model.params.inertia_kg_m2
    expected = np.linalg.solve(inertia, np.cross([0.04, -0.03, 0.25], [0.0, 0.0, 1.0])) * base.control_dt_s
    np.testing.assert_allclose(rate_changed, expected, rtol=0.02)
    assert np.linalg.norm(rate_nominal) < 0.05 * np.linalg.norm(rate_changed)


def test_a_true_offset_without_a_nominal_one_gets_the_offset_kernel_and_the_batched_env_agrees():
    # the nominal model has no offset torque, the true plant has one: the compiled step must include it
    ab = "attitude_envs/AirBearing-v0"
    kwargs = {"offset_torque_nm": [0.0, 0.0, 0.0], "true_offset_torque_nm": [0.0, 0.0, 0.3], "episode_duration_s": 1.0}
    env = gym.make(ab, **kwargs)
    assert not np.any(env.unwrapped.model.params.offset_torque_nm)
    free = gym.make(ab, **{k: v for k, v in kwargs.items() if k != "true_offset_torque_nm"})
    tilted = {"euler_321_deg": [10.0, -5.0, 0.0]}
    env.reset(seed=2, options=tilted)
    free.reset(seed=2, options=tilted)
    action = np.zeros(3, dtype=np.float32)
    rate = env.step(action)[4]["truth"]["state"]["rate_rad_s"]
    assert not np.allclose(rate, free.step(action)[4]["truth"]["state"]["rate_rad_s"])
    vec = gym.make_vec(ab, num_envs=1, vectorization_mode="vector_entry_point", **kwargs)
    vec.reset(seed=2, options=tilted)
    vec.step(action[None])
    np.testing.assert_array_equal(vec.unwrapped.states[0], env.unwrapped.state_row)
    with pytest.raises(ValueError, match=r"true_offset_torque_nm must have shape \(3,\)"):
        gym.make(ab, true_offset_torque_nm=[0.1, 0.2])
