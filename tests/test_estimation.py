"""MEKF attitude/gyro-bias estimator: consistent (NEES), accurate, usable as an observation wrapper."""

import gymnasium as gym
import numpy as np
import pytest
from scipy.stats import chi2

from attitude_envs import quaternion
from attitude_envs.estimation import AttitudeMEKF, EstimatedAttitude
from baselines.lqr import LQRPolicy

RW = "attitude_envs/ReactionWheel-v0"
SENSORS = {
    "gyro": {"noise_std": 5e-4, "bias_walk_std": 1e-5, "initial_bias_std": 2e-3},
    "star_tracker": {"noise_std": 5e-5},
}


def closed_loop(seed, steps, sensors=SENSORS, faults=None):
    """LQR on the *estimated* observation; returns per-step (info, filter NEES)."""
    env = EstimatedAttitude(gym.make(RW, sensors=sensors, faults=faults, episode_duration_s=steps * 0.1))
    policy = LQRPolicy(env)
    obs, info = env.reset(seed=seed)
    rows = [(info, env.filter.nees(info["truth"]["state"]["attitude"], info["truth"]["sensor_bias"]["gyro"]))]
    for _ in range(steps):
        obs, _, _, _, info = env.step(policy.act(obs, info))
        rows.append((info, env.filter.nees(info["truth"]["state"]["attitude"], info["truth"]["sensor_bias"]["gyro"])))
    return rows, obs


def test_nees_is_chi_square_consistent_over_monte_carlo_runs():
    runs, steps = 16, 120
    nees = np.array([[n for _, n in closed_loop(seed, steps)[0]] for seed in range(runs)])
    mean_per_step = nees.mean(axis=0)
    low, high = chi2.ppf([0.025, 0.975], 6 * runs) / runs
    # consistent filter: the run-averaged NEES at each step lies in its 95 % χ² interval
    # about 95 % of the time (measured: 98 % at 20 × 300); an over- or under-confident
    # filter (e.g. the neglected gyro-noise correlation: ANEES 8.3) fails this.
    assert np.mean((mean_per_step >= low) & (mean_per_step <= high)) >= 0.85
    assert 6.0 * 0.85 <= nees.mean() <= 6.0 * 1.15


def test_estimate_beats_the_raw_sensors_and_learns_the_bias():
    rows, obs = closed_loop(seed=3, steps=300)
    late = rows[100:]
    att_err = [
        np.linalg.norm(
            quaternion.to_rotvec(
                quaternion.multiply(quaternion.conjugate(i["truth"]["state"]["attitude"]), i["estimate"]["attitude"])
            )
        )
        for i, _ in late
    ]
    star_err = [
        np.linalg.norm(
            quaternion.to_rotvec(
                quaternion.multiply(quaternion.conjugate(i["truth"]["state"]["attitude"]), i["sensors"]["star_tracker"])
            )
        )
        for i, _ in late
    ]
    rms, star_rms = np.sqrt(np.mean(np.square(att_err))), np.sqrt(np.mean(np.square(star_err)))
    predicted = np.sqrt(np.mean([np.trace(i["estimate"]["covariance"][:3, :3]) for i, _ in late]))
    # gyro noise per step (5e-5 rad) is as large as the star tracker's: the gain is modest
    # (measured 0.77) and the achieved error is what the covariance predicts
    assert rms < 0.85 * star_rms
    assert rms == pytest.approx(predicted, rel=0.2)
    final = rows[-1][0]
    bias_err = final["estimate"]["gyro_bias_rad_s"] - final["truth"]["sensor_bias"]["gyro"]
    sigma = np.sqrt(np.diag(final["estimate"]["covariance"])[3:])
    assert np.all(np.abs(bias_err) < 4 * sigma)
    assert np.all(sigma < 0.1 * SENSORS["gyro"]["initial_bias_std"])  # learned to < 10 % of the prior
    assert np.linalg.norm(final["truth"]["sensor_bias"]["gyro"]) > 1e-3  # the bias was real
    rate_err = final["estimate"]["rate_rad_s"] - final["truth"]["state"]["rate_rad_s"]
    raw_err = final["sensors"]["gyro"] - final["truth"]["state"]["rate_rad_s"]
    assert np.linalg.norm(rate_err) < 0.5 * np.linalg.norm(raw_err)
    # the wrapper's observation is the error state of the estimate
    target = final["measured"]["target_attitude"]
    expected = quaternion.error(final["estimate"]["attitude"], target)[:3]
    assert np.allclose(obs[:3], expected, atol=1e-6)
    # and info["measured"] is the estimate (the flight computer's view)
    assert np.array_equal(final["measured"]["attitude"], final["estimate"]["attitude"])
    assert np.array_equal(final["measured"]["rate_rad_s"], final["estimate"]["rate_rad_s"])
    assert np.array_equal(final["measured"]["wheel_speed_rad_s"], final["sensors"]["tachometer"])


def test_estimator_coasts_through_a_star_tracker_dropout():
    fault = {
        "kind": "dropout",
        "target": "sensor",
        "sensor": "star_tracker",
        "index": "all",
        "onset_s": 5.0,
        "duration_s": 3.0,
    }
    rows, _ = closed_loop(seed=1, steps=120, faults=[fault])
    sig = [np.sqrt(np.trace(i["estimate"]["covariance"][:3, :3])) for i, _ in rows]
    assert sig[79] > 2 * sig[49]  # uncertainty grows while coasting on the gyro
    assert sig[110] < 0.5 * sig[79]  # and collapses once the star tracker is back
    assert all(np.isfinite(n) and n < chi2.ppf(0.9999, 6) for _, n in rows)


def test_wrapper_needs_sensors_and_checks_its_parameters():
    with pytest.raises(ValueError, match="needs sensors on"):
        EstimatedAttitude(gym.make(RW))
    with pytest.raises(ValueError, match=r"filter_params has unknown keys \['gain'\]"):
        EstimatedAttitude(gym.make(RW, sensors=SENSORS), filter_params={"gain": 1})
    with pytest.raises(ValueError, match=r"gyro_noise_std must be in \[0, inf\)"):
        AttitudeMEKF(-1.0, 0.0, 1e-4, 1e-3)
