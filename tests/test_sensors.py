"""Sensor models and sensor faults: off by default, exact from onset on, seeded."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs import quaternion

RW = "attitude_envs/ReactionWheel-v0"
LIN = "attitude_envs/LinearSystem-v0"
CMD = np.array([0.4, -0.6, 0.2, 0.8])


def run(steps=12, action=CMD, **kwargs):
    """(time_s, info) after reset and each step; faults onsets at 0.5 s fall on the 5th step."""
    env = gym.make(RW, initial_rate_max_rad_s=0.05, **kwargs).unwrapped
    _, info = env.reset(seed=3)
    rows = [(0.0, info)]
    for _ in range(steps):
        _, _, _, _, info = env.step(action)
        rows.append((info["time_s"], info))
    return rows


def sensor_fault(kind, sensor="gyro", index=1, **kw):
    return dict({"kind": kind, "target": "sensor", "sensor": sensor, "index": index, "onset_s": 0.5}, **kw)


def test_sensors_off_by_default_observe_the_truth_and_leave_the_plant_stream_alone():
    plain = gym.make(RW, initial_rate_max_rad_s=0.05, disturbance={"kind": "random_walk", "std_nm_per_sqrt_s": 1e-3})
    noisy = gym.make(
        RW,
        initial_rate_max_rad_s=0.05,
        disturbance={"kind": "random_walk", "std_nm_per_sqrt_s": 1e-3},
        sensors={"gyro": {"noise_std": 1e-3}, "star_tracker": {"noise_std": 1e-4}},
    )
    o1, i1 = plain.reset(seed=5)
    o2, i2 = noisy.reset(seed=5)
    assert "sensors" not in i1
    assert np.array_equal(o1, plain.unwrapped.error_state().astype(np.float32))
    for _ in range(5):
        o1, _, _, _, i1 = plain.step(CMD)
        o2, _, _, _, i2 = noisy.step(CMD)
    # the plant (incl. its random disturbance) is identical; only the observation is noisy
    assert np.array_equal(i1["truth"]["state"]["attitude"], i2["truth"]["state"]["attitude"])
    assert np.array_equal(o1, plain.unwrapped.error_state().astype(np.float32))
    assert not np.allclose(o1, o2, atol=1e-6)
    assert np.allclose(o1, o2, atol=1e-2)


def test_noise_free_sensor_with_fault_measures_truth_until_onset_then_bias():
    rows = run(faults=[sensor_fault("bias", value=0.01)])
    for t, info in rows:
        gyro = info["sensors"]["gyro"]
        truth = info["truth"]["state"]["rate_rad_s"]
        expected = truth + np.array([0.0, 0.01, 0.0]) * (t >= 0.5 - 1e-9)
        assert np.allclose(gyro, expected, rtol=0, atol=1e-15)
        assert np.array_equal(info["sensors"]["tachometer"], info["truth"]["state"]["wheel_speed_rad_s"])


def test_measured_state_is_the_sensor_readings():
    """info["measured"] (the flight computer's view): star tracker, gyro and tachometers;
    the commanded target as is."""
    rows = run(sensors={"gyro": {"noise_std": 1e-3}, "tachometer": {"noise_std": 0.1}})
    for _, info in rows:
        m, raw, truth = info["measured"], info["sensors"], info["truth"]["state"]
        assert np.array_equal(m["attitude"], raw["star_tracker"])
        assert np.array_equal(m["rate_rad_s"], raw["gyro"]) and not np.array_equal(m["rate_rad_s"], truth["rate_rad_s"])
        assert np.array_equal(m["wheel_speed_rad_s"], raw["tachometer"])
        assert np.array_equal(m["target_attitude"], truth["target_attitude"])


def test_drift_stuck_and_dropout_from_onset():
    drift = run(faults=[sensor_fault("drift", value=0.002)])
    stuck = run(faults=[sensor_fault("stuck", index=2)])
    given = run(faults=[sensor_fault("stuck", sensor="tachometer", index=3, value=7.0)])
    nan = run(faults=[sensor_fault("dropout", index=0, duration_s=0.3)])
    hold = run(faults=[sensor_fault("dropout", index=0, mode="hold")])
    for k, (t, info) in enumerate(drift):
        truth = info["truth"]["state"]["rate_rad_s"]
        after = t >= 0.5 - 1e-9
        assert info["sensors"]["gyro"][1] == pytest.approx(truth[1] + after * 0.002 * (t - 0.5), abs=1e-15)
        held = stuck[5][1]["truth"]["state"]["rate_rad_s"][2]
        s = stuck[k][1]
        assert s["sensors"]["gyro"][2] == (held if after else s["truth"]["state"]["rate_rad_s"][2])
        g = given[k][1]
        assert g["sensors"]["tachometer"][3] == (7.0 if after else g["truth"]["state"]["wheel_speed_rad_s"][3])
        n = nan[k][1]
        assert np.isnan(n["sensors"]["gyro"][0]) == (0.5 - 1e-9 <= t < 0.8 - 1e-9)
        assert np.array_equal(n["sensors"]["gyro"][1:], n["truth"]["state"]["rate_rad_s"][1:])
        h = hold[k][1]
        assert h["sensors"]["gyro"][0] == (
            hold[4][1]["truth"]["state"]["rate_rad_s"][0] if after else h["truth"]["state"]["rate_rad_s"][0]
        )
    assert (
        stuck[5][1]["truth"]["state"]["rate_rad_s"][2] != stuck[10][1]["truth"]["state"]["rate_rad_s"][2]
    )  # the truth moved on


def test_star_tracker_stuck_freezes_the_quaternion_and_nan_dropout_reaches_the_observation():
    rows = run(faults=[sensor_fault("stuck", sensor="star_tracker", index="all")])
    assert np.array_equal(rows[0][1]["sensors"]["star_tracker"], rows[0][1]["truth"]["state"]["attitude"])
    for _, info in rows[5:]:
        assert np.array_equal(info["sensors"]["star_tracker"], rows[5][1]["truth"]["state"]["attitude"])
    env = gym.make(RW, faults=[sensor_fault("dropout", sensor="star_tracker", index="all")])
    env.reset(seed=0)
    obs = [env.step(CMD)[0] for _ in range(6)]
    assert np.all(np.isfinite(obs[3])) and np.all(np.isnan(obs[4][:3])) and np.all(np.isfinite(obs[4][3:]))


def test_star_tracker_noise_is_a_body_rotation_of_the_given_size():
    rows = run(steps=200, action=np.zeros(4), sensors={"star_tracker": {"noise_std": 1e-3}})
    errs = np.array(
        [
            quaternion.to_rotvec(
                quaternion.multiply(quaternion.conjugate(i["truth"]["state"]["attitude"]), i["sensors"]["star_tracker"])
            )
            for _, i in rows
        ]
    )
    # 603 samples of N(0, 1e-6): the sample std is within 10 % with overwhelming probability
    assert np.std(errs) == pytest.approx(1e-3, rel=0.1)
    assert abs(np.mean(errs)) < 5 * 1e-3 / np.sqrt(errs.size)


def test_noise_increase_scales_exactly_the_same_noise_draws():
    cfg = {"gyro": {"noise_std": 1e-3}}
    base = run(sensors=cfg)
    worse = run(sensors=cfg, faults=[sensor_fault("noise_increase", value=5.0)])
    for (t, b), (_, w) in zip(base, worse, strict=True):
        eb = b["sensors"]["gyro"] - b["truth"]["state"]["rate_rad_s"]
        ew = w["sensors"]["gyro"] - w["truth"]["state"]["rate_rad_s"]
        factor = np.array([1.0, 5.0 if t >= 0.5 - 1e-9 else 1.0, 1.0])
        assert np.allclose(ew, factor * eb, rtol=1e-9, atol=1e-15)


def test_gyro_bias_random_walk_statistics_and_seeding():
    cfg = {"gyro": {"bias_walk_std": 1e-4, "initial_bias": [0.01, 0.0, -0.01]}}
    rows = run(steps=400, action=np.zeros(4), sensors=cfg)
    bias = np.array([i["truth"]["sensor_bias"]["gyro"] for _, i in rows])
    assert np.array_equal(bias[0], [0.01, 0.0, -0.01])
    meas_err = np.array([i["sensors"]["gyro"] - i["truth"]["state"]["rate_rad_s"] for _, i in rows])
    assert np.allclose(meas_err, bias, atol=1e-15)  # no white noise configured: error = bias
    steps = np.diff(bias, axis=0).ravel()
    # 1200 increments of N(0, σ² Δt): sample std within 7 % (≈ 3.4 standard errors)
    assert np.std(steps) == pytest.approx(1e-4 * np.sqrt(0.1), rel=0.07)
    again = run(steps=400, action=np.zeros(4), sensors=cfg)
    assert np.array_equal(bias, np.array([i["truth"]["sensor_bias"]["gyro"] for _, i in again]))


def test_random_sensor_faults_follow_the_seed():
    fault = {
        "kind": "bias",
        "target": "sensor",
        "sensor": "gyro",
        "index": "random",
        "value": {"uniform": [0.001, 0.01]},
        "onset_s": {"uniform": [5, 10]},
    }
    env = gym.make(RW, faults=[fault, {"kind": "outage", "index": "random"}]).unwrapped
    draws = {s: env.reset(seed=s)[1]["truth"]["faults"] for s in range(8)}
    assert len({(d[1]["index"], d[1]["value"], d[1]["onset_s"]) for d in draws.values()}) == 8
    assert env.reset(seed=4)[1]["truth"]["faults"] == draws[4]
    plain = gym.make(RW, faults=[{"kind": "outage", "index": "random"}]).unwrapped
    # the sensors draw from a spawned generator: the actuator draws do not change
    assert all(plain.reset(seed=s)[1]["truth"]["faults"][0] == draws[s][0] for s in range(8))


def test_fault_hint_flags_actuator_and_sensor_faults():
    faults = [{"kind": "outage", "index": 2, "onset_s": 0.5}, sensor_fault("bias", value=0.1, onset_s=0.3)]
    plain = gym.make(RW, faults=faults)
    hinted = gym.make(RW, faults=faults, fault_hint=True)
    assert hinted.observation_space.shape == (6 + 4 + 3,)
    assert plain.observation_space.shape == (6,)
    o, _ = hinted.reset(seed=0)
    assert np.array_equal(o[6:], np.zeros(7))
    obs = [hinted.step(CMD)[0] for _ in range(6)]
    assert np.array_equal(obs[2][6:], [0, 0, 0, 0, 1, 0, 0])  # t = 0.3: gyro bias
    assert np.array_equal(obs[4][6:], [0, 0, 1, 0, 1, 0, 0])  # t = 0.5: wheel 2 out


def test_linear_system_state_sensor():
    env = gym.make(
        LIN,
        sensors={"state": {"noise_std": 0.01}},
        faults=[{"kind": "bias", "target": "sensor", "sensor": "state", "index": 3, "value": 1.0, "onset_s": 0.05}],
        fault_hint=True,
    )
    obs, info = env.reset(seed=0)
    assert obs.shape == (6 + 3 + 1,)
    for _ in range(8):
        obs, _, _, _, info = env.step(np.zeros(3))
        err = obs[:6] - info["truth"]["state"]
        assert np.array_equal(info["measured"], info["sensors"]["state"])  # the measurement in obs
        assert np.array_equal(info["measured"].astype(np.float32), obs[:6])
        late = info["truth"]["faults"][0]["active"]
        assert abs(err[3] - (1.0 if late else 0.0)) < 0.05
        assert np.all(np.abs(np.delete(err, 3)) < 0.05)
        assert obs[-1] == float(late)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"sensors": {"sun_sensor": {}}}, r"sensors must be one of \['gyro', 'star_tracker', 'tachometer'\]"),
        ({"sensors": {"gyro": {"noise": 1}}}, r"sensors\['gyro'\] has unknown keys \['noise'\]"),
        ({"sensors": {"gyro": {"noise_std": -1}}}, r"sensors\['gyro'\].noise_std must be in \[0, inf\)"),
        ({"sensors": {"gyro": {"initial_bias": [1, 2]}}}, r"initial_bias must be a number or have 3 entries"),
        ({"faults": [sensor_fault("melt")]}, r"faults\[0\].kind must be one of \['bias', 'drift'"),
        ({"faults": [sensor_fault("bias", value=1, index=3)]}, r"faults\[0\].index must be an integer in \[0, 2\]"),
        ({"faults": [sensor_fault("bias", sensor="tachometer", index=4, value=1)]}, r"in \[0, 3\]"),
        ({"faults": [sensor_fault("bias")]}, r"faults\[0\].value is required"),
        ({"faults": [sensor_fault("dropout", mode="zero")]}, r"faults\[0\].mode must be one of \['hold', 'nan'\]"),
        ({"faults": [sensor_fault("dropout", sensor="star_tracker")]}, r"faults\[0\].index must be 'all'"),
        ({"faults": [sensor_fault("noise_increase", value=2.0)]}, r"needs sensors\['gyro'\].noise_std > 0"),
        (
            {"sensors": {"gyro": {"noise_std": 1}}, "faults": [sensor_fault("noise_increase", value=0.5)]},
            r"faults\[0\].value must be in \[1.0, inf\]",
        ),
        ({"faults": [sensor_fault("bias", value=1, onset_s=-2)]}, r"faults\[0\].onset_s must be in \[0.0, inf\]"),
        ({"faults": [sensor_fault("stuck", colour=1)]}, r"unknown keys \['colour'\]"),
    ],
)
def test_bad_sensor_configs_name_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(RW, **kwargs)


def test_bad_sensor_fault_per_episode_is_rejected_at_reset():
    env = gym.make(RW)
    with pytest.raises(ValueError, match=r"faults\[0\].sensor must be one of"):
        env.reset(seed=0, options={"faults": [{"kind": "bias", "target": "sensor", "sensor": "sun", "value": 1}]})


def test_envs_with_sensors_and_hints_pass_the_gymnasium_checker():
    from gymnasium.utils.env_checker import check_env

    sensors = {"gyro": {"noise_std": 1e-3}, "star_tracker": {"noise_std": 1e-4}, "tachometer": {"noise_std": 0.1}}
    check_env(gym.make(RW, sensors=sensors, fault_hint=True, faults=[{"kind": "outage", "index": 1}]).unwrapped)
    check_env(gym.make(LIN, sensors={"state": {"noise_std": 0.01}}, fault_hint=True).unwrapped)


def test_star_tracker_bias_is_a_body_rotation_about_its_axis():
    rows = run(faults=[sensor_fault("bias", sensor="star_tracker", index=2, value=0.01)])
    for t, info in rows:
        q, m = info["truth"]["state"]["attitude"], info["sensors"]["star_tracker"]
        err = quaternion.to_rotvec(quaternion.multiply(quaternion.conjugate(q), m))
        assert np.allclose(err, [0, 0, 0.01 if t >= 0.5 - 1e-9 else 0.0], atol=1e-12)


def test_fuel_slosh_state_sensor_and_fault_hint():
    from gymnasium.utils.env_checker import check_env

    fault = {"kind": "bias", "target": "sensor", "sensor": "state", "index": 1, "value": 0.01, "onset_s": 0.2}
    env = gym.make("attitude_envs/FuelSlosh-v0", sensors={"state": {"noise_std": 0.0}}, faults=[fault], fault_hint=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (8 + 3,)
    for _ in range(4):
        obs, _, _, _, info = env.step(np.zeros(2))
        truth = np.append(info["truth"]["x"], info["truth"]["state"]["v_x_m_s"])
        active = info["time_s"] >= 0.2 - 1e-9
        assert np.allclose(obs[:8], truth + np.eye(8)[1] * (0.01 if active else 0.0), atol=1e-6)
        assert obs[-1] == float(active)
    check_env(gym.make("attitude_envs/FuelSlosh-v0", sensors={"state": {"noise_std": 1e-3}}, fault_hint=True).unwrapped)


def test_magnetorquer_sensors_reach_the_observation():
    from gymnasium.utils.env_checker import check_env

    mag = "attitude_envs/Magnetorquer-v0"
    kwargs = {"episode_duration_s": 5.0, "observe_field": True}
    fault = {"kind": "bias", "target": "sensor", "sensor": "magnetometer", "index": 2, "value": 1e-6, "onset_s": 0.3}
    truth_env = gym.make(mag, **kwargs)
    sensed = gym.make(mag, **kwargs, sensors={"gyro": {"noise_std": 0.0}}, faults=[fault], fault_hint=True)
    o_truth, _ = truth_env.reset(seed=4)
    o_meas, _ = sensed.reset(seed=4)
    assert np.allclose(o_meas[:10], o_truth, atol=1e-6) and o_meas.shape == (10 + 8,)
    for _ in range(5):
        o_truth = truth_env.step(np.zeros(4))[0]
        o_meas, _, _, _, info = sensed.step(np.zeros(4))
        active = info["time_s"] >= 0.3 - 1e-9
        shift = 1e-6 / 5e-5 if active else 0.0  # FIELD_SCALE_T normalizes the field observation
        assert np.allclose(o_meas[:7], o_truth[:7], atol=1e-6)  # noise-free gyro and star tracker
        assert o_meas[9] - o_truth[9] == pytest.approx(shift, abs=1e-5)
        assert o_meas[-1] == float(active)  # magnetometer is the last sensor flag
    check_env(gym.make(mag, **kwargs, sensors={"magnetometer": {"noise_std": 1e-8}}, fault_hint=True).unwrapped)
