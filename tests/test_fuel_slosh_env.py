"""FuelSlosh-v0: Gymnasium API, cost wiring, options and bad input."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs import presets  # (importing attitude_envs registers the ids)
from attitude_envs.envs.fuel_slosh import PAPER_INITIAL_STATE, FuelSloshEnv
from attitude_envs.integrators import rk4_step
from attitude_envs.plants import slosh


@pytest.mark.parametrize("observe_slosh", [True, False])
def test_check_env(observe_slosh):
    env = gym.make("attitude_envs/FuelSlosh-v0", observe_slosh=observe_slosh)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == ((8,) if observe_slosh else (4,))


def test_paper_initial_state_and_observation():
    env = FuelSloshEnv()
    obs, info = env.reset(seed=0)
    np.testing.assert_allclose(
        obs, [100, math.radians(2), 0, math.radians(30), 0, math.radians(-30), 0, 3000], rtol=1e-6
    )
    assert info["truth"]["state"]["v_x_m_s"] == 3000.0


def test_step_matches_plant_integration_and_cost_is_integrated():
    """One step with a held (δ, M) equals RK4 of the plant; the cost equals a fine
    quadrature of xᵀQx + u_cᵀRu_c with u_c = [a_z, Ω̇] realized by the plant."""
    env = FuelSloshEnv(control_dt_s=0.1, integrator_dt_s=0.01)
    env.reset(seed=0)
    y0 = env.state
    action = np.array([0.5, -0.25], dtype=np.float32)
    _, reward, _, _, info = env.step(action)
    delta, moment = 0.5 * math.radians(30.0), -0.25 * 2000.0
    np.testing.assert_allclose(info["truth"]["applied"], [delta, moment])
    y = y0.copy()
    for _ in range(10):
        y = rk4_step(lambda t, s: slosh.derivative(env.model.params, s, delta, moment), 0.0, y, 0.01)
    np.testing.assert_allclose(env.state, y, rtol=1e-12, atol=1e-12)

    y, cost, h, az_int = y0.copy(), 0.0, 1e-4, 0.0
    f = lambda t, s: slosh.derivative(env.model.params, s, delta, moment)  # noqa: E731
    for k in range(1000):
        dy = f(0, y)
        _, a_z, dom = slosh.tank_accelerations(y, dy)
        stage = env.model.cost.stage(y[[6, 2, 7, 3, 8, 4, 9]], np.array([a_z, dom]))
        cost += stage * h * (0.5 if k == 0 else 1.0)
        az_int += a_z * h * (0.5 if k == 0 else 1.0)
        y = rk4_step(f, 0.0, y, h)
    dy = f(0, y)
    _, a_z, dom = slosh.tank_accelerations(y, dy)
    cost += 0.5 * h * env.model.cost.stage(y[[6, 2, 7, 3, 8, 4, 9]], np.array([a_z, dom]))
    assert info["cost"] == pytest.approx(cost, rel=1e-6)
    assert reward == -info["cost"]
    az_int += 0.5 * h * a_z
    assert info["truth"]["new_inputs"][0] == pytest.approx(az_int / 0.1, rel=1e-6)  # step-mean a_z


def test_reset_options_and_randomization():
    env = FuelSloshEnv(randomize_initial_state=True)
    o1, _ = env.reset(seed=1)
    o2, _ = env.reset(seed=1)
    o3, _ = env.reset(seed=2)
    np.testing.assert_array_equal(o1, o2)
    assert not np.array_equal(o1, o3)
    assert abs(o1[0]) <= 100 and abs(o1[3]) <= math.radians(30)
    state = PAPER_INITIAL_STATE.copy()
    state[1] = -5.0
    obs, _ = env.reset(options={"state": state})
    assert obs[0] == -5.0


def test_truncates_on_time_and_terminates_on_tumbling():
    env = FuelSloshEnv(episode_duration_s=1.0)
    env.reset(seed=0)
    for k in range(10):
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        assert not terminated
        assert truncated == (k == 9)
    env = FuelSloshEnv()
    env.reset(seed=0)
    terminated = False
    for _ in range(100):
        _, _, terminated, _, _ = env.step(np.array([0.0, 1.0], np.float32))
        if terminated:
            break
    assert terminated  # full moment spins the craft past max_pitch_rate_rad_s


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"fill_preset": "full"}, "fill_preset"),
        ({"preset": "full"}, "navabi-fill-i"),
        ({"preset": None}, "preset=None needs"),
        ({"params": {"mass_kg": 1.0}}, "params must be a SloshParams"),
        ({"initial_state": [3000, float("nan"), 0, 0, 0, 0, 0, 0]}, "initial_state"),
        ({"initial_state": [3000, 100]}, "initial_state"),
        ({"max_gimbal_deg": 120}, "max_gimbal_deg"),
        ({"max_moment_nm": -1}, "max_moment_nm"),
        ({"control_dt_s": 0.1, "integrator_dt_s": 0.03}, "control_dt_s"),
        ({"Q": -np.eye(7)}, "Q"),
    ],
)
def test_bad_arguments_raise(kwargs, name):
    with pytest.raises(ValueError, match=name), warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fill_preset
        FuelSloshEnv(**kwargs)


def test_bad_reset_options_raise():
    env = FuelSloshEnv()
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": [np.inf] * 8})
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(options={"attitude": [0, 0, 0, 1]})
    env.reset()
    with pytest.raises(ValueError, match="action"):
        env.step(np.array([np.nan, 0.0]))


def test_presets_are_the_papers_length_mappings_with_sources():
    names = [p.name for p in presets.for_env("FuelSlosh-v0")]
    assert names == ["navabi-fill-i", "navabi-fill-ii", "navabi-fill-iii", "navabi-fill-iv"]
    for mapping in slosh.FILL_PRESETS:
        p = presets.get("FuelSlosh-v0", mapping)  # the old names are aliases
        assert p.name == f"navabi-fill-{mapping}" and p.default == (mapping == "i")
        assert p.params()["params"] == slosh.SloshParams.from_fill_preset(mapping)
        assert all(p.source(k).startswith(("Navabi & Davoodi", "assumed")) for k in p.values)
    assert presets.get("FuelSlosh-v0", "i").source("initial_state").startswith("Navabi & Davoodi, Table 4")
    np.testing.assert_array_equal(presets.get("FuelSlosh-v0").params()["initial_state"], PAPER_INITIAL_STATE)


def test_preset_selects_the_plant_and_keywords_override_single_values():
    env = FuelSloshEnv(preset="navabi-fill-iii", max_moment_nm=500.0)
    assert env.model.params == slosh.SloshParams.from_fill_preset("iii")
    assert env.model.max_moment_nm == 500.0 and env.model.max_gimbal_rad == pytest.approx(math.radians(30.0))
    assert FuelSloshEnv(preset="ii").model.params == slosh.SloshParams.from_fill_preset("ii")
    assert FuelSloshEnv().preset == "navabi-fill-i"


def test_fill_preset_still_works_with_a_deprecation_warning():
    with pytest.warns(DeprecationWarning, match="preset='navabi-fill-iv'"):
        env = FuelSloshEnv(fill_preset="iv")
    assert env.model.params == slosh.SloshParams.from_fill_preset("iv")
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="not both"):
        FuelSloshEnv(preset="navabi-fill-ii", fill_preset="iv")


def test_info_contract_truth_measured_and_public_entries():
    env = FuelSloshEnv()
    _, info = env.reset(seed=0)
    truth = info["truth"]
    assert set(truth) == {"state", "full_state", "x", "applied", "new_inputs", "faults"}
    assert info["measured"] is not truth["state"] and set(info["measured"]) == set(truth["state"])
    _, _, _, _, info = env.step(np.array([0.1, -0.2], np.float32))
    assert {"cost", "time_s", "commanded", "truth", "measured"} <= set(info) and "new_inputs" not in info
    np.testing.assert_array_equal(info["truth"]["x"], info["truth"]["full_state"][[6, 2, 7, 3, 8, 4, 9]])
    for key, value in info["truth"]["state"].items():  # sensors off: measured is the truth
        np.testing.assert_array_equal(info["measured"][key], value)
    assert "sensors" not in info and "sensor_bias" not in info["truth"]


@pytest.mark.parametrize("observe_slosh", [True, False])
def test_measured_holds_what_the_state_sensor_measures(observe_slosh):
    env = FuelSloshEnv(observe_slosh=observe_slosh, sensors={"state": {"noise_std": 1e-3}})
    obs, info = env.reset(seed=0)
    for _ in range(2):
        m = info["measured"]
        keys = {"theta_rad", "v_x_m_s", "v_z_m_s", "pitch_rate_rad_s"}
        if observe_slosh:
            keys |= {"slosh_angle_rad", "slosh_rate_rad_s"}
        assert set(m) == keys  # position_m is never measured
        assert np.array_equal(info["sensors"]["state"].astype(np.float32), obs)
        assert m["v_z_m_s"] == info["sensors"]["state"][0] and m["v_x_m_s"] == info["sensors"]["state"][-1]
        assert m["theta_rad"] != info["truth"]["state"]["theta_rad"]  # noisy
        assert "state" in info["truth"]["sensor_bias"]
        obs, _, _, _, info = env.step(np.zeros(2, np.float32))


def test_public_members_for_the_batched_env():
    env = FuelSloshEnv(observe_slosh=False)
    assert np.array_equal(env.observation_index, [slosh.IVZ, slosh.ITH, slosh.IOM, slosh.IVX])
    assert np.array_equal(env.actuator_limits, [math.radians(30.0), 2000.0])
    for a in (env.observation_index, env.actuator_limits, env.kernel_constants):
        assert not a.flags.writeable
    assert env.fault_layer.n == 2 and not env.sensor_layer.enabled
