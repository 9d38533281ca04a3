"""The estimators the analytic controllers act through under flight sensors: the MEKF on the
gyrostats and the Magnetorquer, the Kalman filters on LinearSystem and FuelSlosh, and the
estimator-in-the-loop policy wrapper."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs import quaternion
from attitude_envs.estimation import GyrostatMEKF, LinearKF, MagnetorquerMEKF, SampleGate, SloshKF, estimator_for
from attitude_envs.evaluation.rollout import rollout
from baselines.estimated import Estimated, lqr_mekf, slosh_lqr_kf
from baselines.linear_lqr import LinearLQRPolicy
from baselines.lqr import LQRPolicy

RW = "attitude_envs/ReactionWheel-v0"


def _angle(q_true, q):
    return float(np.linalg.norm(quaternion.to_rotvec(quaternion.multiply(quaternion.conjugate(q_true), q))))


def _run(env, estimator, policy, seed, steps):
    """Closed loop through ``estimator``; per step the env's info and the policy's view."""
    obs, info = env.reset(seed=seed)
    obs_e, view = estimator.reset(obs, info)
    rows = [(info, view)]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy.act(obs_e, view))
        obs_e, view = estimator.update(obs, info)
        rows.append((info, view))
        if terminated or truncated:
            break
    return rows


def test_mekf_beats_the_slow_star_tracker_under_flight_sensors():
    env = gym.make(RW, conditions={"sensors": True}, episode_duration_s=20.0)
    est = GyrostatMEKF(env)
    assert env.unwrapped.sensor_layer.parameters("star_tracker")["period_s"] > 0.1  # slower than the loop
    rows = _run(env, est, LQRPolicy(env), seed=2, steps=200)
    late = rows[50:]
    est_err = np.mean([_angle(i["truth"]["state"]["attitude"], v["estimate"]["attitude"]) for i, v in late])
    raw_err = np.mean([_angle(i["truth"]["state"]["attitude"], i["sensors"]["star_tracker"]) for i, _ in late])
    assert est_err < 0.5 * raw_err
    # one update per new star-tracker sample (period 1/1.7 s: every 6th 0.1 s step), none between
    distinct = sum(
        not np.array_equal(a["sensors"]["star_tracker"], b["sensors"]["star_tracker"])
        for (a, _), (b, _) in zip(rows[:-1], rows[1:], strict=True)
    )
    assert est.updates == distinct
    assert 200 // 6 - 1 <= distinct <= 200 // 6 + 1


def test_mekf_learns_the_gyro_bias_with_a_slow_star_tracker():
    sensors = {
        "gyro": {"noise_std": 5e-4, "bias_walk_std": 1e-6, "initial_bias_std": 3e-3},
        "star_tracker": {"noise_std": 5e-5, "period_s": 0.5},
    }
    env = gym.make(RW, sensors=sensors, episode_duration_s=30.0)
    rows = _run(env, GyrostatMEKF(env), LQRPolicy(env), seed=1, steps=300)
    first_info, first_view = rows[0]
    last_info, last_view = rows[-1]
    err0 = np.linalg.norm(first_view["estimate"]["gyro_bias_rad_s"] - first_info["truth"]["sensor_bias"]["gyro"])
    err1 = np.linalg.norm(last_view["estimate"]["gyro_bias_rad_s"] - last_info["truth"]["sensor_bias"]["gyro"])
    assert err1 < 0.2 * err0


@pytest.mark.parametrize("env_id", ["attitude_envs/AirBearing-v0", RW])
def test_noise_free_sensors_give_the_env_observation_back(env_id):
    tiny = {"noise_std": 1e-12}
    env = gym.make(env_id, sensors={"gyro": tiny, "star_tracker": tiny}, episode_duration_s=2.0)
    est = estimator_for(env, "mekf")
    obs, info = env.reset(seed=0)
    obs_e, _ = est.reset(obs, info)
    np.testing.assert_allclose(obs_e, obs, atol=1e-6)
    for _ in range(10):
        obs, _, _, _, info = env.step(env.action_space.sample() * 0.2)
        obs_e, view = est.update(obs, info)
        np.testing.assert_allclose(obs_e, obs, atol=1e-6)
    assert view is not info and info["measured"]["attitude"] is not view["measured"]["attitude"]


def test_magnetorquer_mekf_follows_the_orbital_frame_and_uses_the_magnetometer():
    sensors = {
        "gyro": {"noise_std": 1e-4, "initial_bias_std": 1e-3},
        "star_tracker": {"noise_std": 1e-4, "period_s": 1.0},
        "magnetometer": {"noise_std": 1e-8},
    }
    env = gym.make("attitude_envs/Magnetorquer-v0", sensors=sensors, episode_duration_s=12.0)
    est = MagnetorquerMEKF(env)
    assert est.magnetometer_std == pytest.approx(1e-8)
    zero = np.zeros(4, dtype=np.float32)
    obs, info = env.reset(seed=0)
    est.reset(obs, info)
    est_err, raw_err = [], []
    for _ in range(120):
        obs, _, _, _, info = env.step(zero)
        _, view = est.update(obs, info)
        q_true = info["truth"]["state"]["attitude"]
        est_err.append(_angle(q_true, view["measured"]["attitude"]))
        raw_err.append(_angle(q_true, info["sensors"]["star_tracker"]))
        w_bo = info["truth"]["state"]["rate_rad_s"]
    assert np.mean(est_err[40:]) < np.mean(raw_err[40:])
    # ω_bo = ω_bi − A(q) ω_oi: the estimate's orbital-frame rate is the truth's within the gyro noise
    assert np.linalg.norm(view["measured"]["rate_rad_s"] - w_bo) < 1e-3


def test_linear_kf_reduces_the_state_error():
    env = gym.make("attitude_envs/LinearSystem-v0", sensors={"state": {"noise_std": 0.05}})
    est = LinearKF(env)
    rows = _run(env, est, LinearLQRPolicy(env), seed=0, steps=300)
    late = rows[50:]
    kf = np.mean([np.linalg.norm(v["measured"] - i["truth"]["state"]) for i, v in late])
    raw = np.mean([np.linalg.norm(i["measured"] - i["truth"]["state"]) for i, _ in late])
    assert kf < 0.5 * raw


def test_slosh_kf_filters_the_pitch_and_keeps_unmeasured_slosh_as_reported():
    env = gym.make("attitude_envs/FuelSlosh-v0", conditions={"sensors": True}, episode_duration_s=60.0)
    est = SloshKF(env)
    policy = slosh_lqr_kf(env)
    rows = _run(env, est, policy.policy, seed=0, steps=600)
    late = rows[100:]
    kf = np.sqrt(np.mean([(v["estimate"]["state"][1] - i["truth"]["x"][1]) ** 2 for i, v in late]))
    raw = np.sqrt(np.mean([(i["sensors"]["state"][1] - i["truth"]["x"][1]) ** 2 for i, _ in late]))
    assert kf < raw  # θ
    measured = "slosh_angle_rad" in rows[0][0]["measured"]
    assert ("slosh_angle_rad" in rows[-1][1]["measured"]) == measured
    assert np.all(np.isfinite(rows[-1][1]["estimate"]["input_disturbance"]))


def test_sample_gate_counts_changes_only():
    gate = SampleGate()
    gate.reset(np.array([1.0, 2.0]))
    assert [gate.is_new(np.array(v)) for v in ([1.0, 2.0], [1.0, 2.5], [1.0, 2.5], [np.nan, 0.0])] == [
        False,
        True,
        False,
        False,
    ]


def test_estimated_policy_runs_a_flight_episode_and_names_its_row():
    env = gym.make(RW, conditions="flight", episode_duration_s=10.0)
    policy = lqr_mekf(env)
    assert policy.name == "lqr+mekf"
    result = rollout(env, policy, seed=0)
    assert result["steps"] == 100 and not result["terminated"] and np.isfinite(result["J"])
    assert policy.last_info["measured"]["attitude"] is not None
    wrapped = Estimated(LQRPolicy(env), GyrostatMEKF(env), name="custom")
    assert wrapped.name == "custom"


def test_estimators_refuse_envs_without_sensors_or_of_another_plant():
    with pytest.raises(ValueError, match="sensors on"):
        GyrostatMEKF(gym.make(RW))
    with pytest.raises(ValueError, match="does not apply"):
        estimator_for(gym.make(RW, conditions={"sensors": True}), "kf")


def test_magnetometer_holds_the_attitude_through_a_star_tracker_dropout():
    sensors = {
        "gyro": {"noise_std": 1e-3, "initial_bias_std": 1e-2},
        "star_tracker": {"noise_std": 1e-4},
        "magnetometer": {"noise_std": 1e-9},
    }
    dropout = [{"kind": "dropout", "target": "sensor", "sensor": "star_tracker", "index": "all", "onset_s": 1.0}]
    errors = {}
    for use in (True, False):
        env = gym.make("attitude_envs/Magnetorquer-v0", sensors=sensors, faults=dropout, episode_duration_s=12.0)
        est = MagnetorquerMEKF(env, use_magnetometer=use)
        obs, info = env.reset(seed=3)
        est.reset(obs, info)
        for _ in range(100):
            obs, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
            _, view = est.update(obs, info)
        q_true = info["truth"]["state"]["attitude"]
        err = quaternion.to_rotvec(quaternion.multiply(quaternion.conjugate(q_true), view["measured"]["attitude"]))
        b = info["truth"]["magnetic_field_body_t"] / np.linalg.norm(info["truth"]["magnetic_field_body_t"])
        errors[use] = np.linalg.norm(err - (err @ b) * b)  # the field fixes the two axes across it
    assert errors[True] < 0.2 * errors[False]


def test_a_per_step_sensor_held_by_a_dropout_is_not_fused_again():
    """LinearSystem-v0's state sensor samples at every step; held by a dropout it repeats its
    last sample, and the KF coasts on the model (its estimate tracks the moving state) instead
    of re-fusing the stale reading (the estimate would stick to it)."""
    held = [{"kind": "dropout", "target": "sensor", "sensor": "state", "index": "all", "mode": "hold", "onset_s": 1.0}]
    env = gym.make("attitude_envs/LinearSystem-v0", episode_steps=300, conditions={"sensors": True}, faults=held)
    kf = LinearKF(env)
    obs, info = env.reset(seed=0)
    kf.reset(obs, info)
    policy = LinearLQRPolicy(env)
    for _ in range(300):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        _, view = kf.update(obs, info)
    truth = np.asarray(info["truth"]["state"], dtype=float)
    stale = np.linalg.norm(np.asarray(info["sensors"]["state"]) - truth)
    assert np.linalg.norm(view["estimate"]["state"] - truth) < 0.05 * stale, (view["estimate"]["state"], truth)
