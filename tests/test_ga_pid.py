"""Ahangarani Farahani et al.'s PID baselines, GA tuning, meta-model fit, tune-pid command and reproduction."""

import json
import math

import gymnasium as gym
import numpy as np
import pytest

from agents.ga_tuning import (
    LAB_MANEUVER,
    GAConfig,
    fit_schedule,
    pid_episode,
    sample_maneuvers,
    tune_gains,
)
from attitude_envs import quaternion
from baselines.pid import PAPER_FIXED, GainSchedule, PIDGains, PIDPolicy, load_gains, paper_schedule
from experiments.cli import main as cli_main
from experiments.pid_tuning import evaluator
from experiments.reproductions import REPRODUCTIONS

ENV_ID = "attitude_envs/AirBearing-v0"
SHORT = {"episode_duration_s": 3.0}


def test_schedule_evaluates_eq_24_exactly():
    angle = np.radians([10.0, -10.0, 10.0])
    rate = np.radians([1.0, 1.0, 0.0])
    kp, kd, ki = paper_schedule("deg").at(angle, rate)
    # by hand from eq. 24 with degrees: Kd_θ = 4.22 + 0.4·(−10) − 0.2·1
    assert kd[1] == pytest.approx(4.22 + 0.4 * -10 - 0.2 * 1, abs=1e-12)
    assert kp[0] == pytest.approx(4.07 + 0.023 * 10 + 0.13 * 1, abs=1e-12)
    assert kp[2] == pytest.approx(1.83 - 0.03 * 10 + 0.03 * 0, abs=1e-12)
    assert ki[2] == pytest.approx(0.05 + 0.01 * 10 - 0.037 * 0, abs=1e-12)
    kp, kd, ki = paper_schedule("rad").at(angle, rate)
    assert kd[1] == pytest.approx(4.22 + 0.4 * angle[1] - 0.2 * rate[1], abs=1e-12)
    assert ki[0] == pytest.approx(0.17 + 0.0134 * angle[0] - 0.023 * rate[0], abs=1e-12)
    neg = paper_schedule("rad", kp_yaw_rate_sign=-1.0).at([0, 0, 0], [0, 0, 2.0])[0]
    assert neg[2] == pytest.approx(1.83 - 0.03 * 2.0)


def test_pid_policy_torque_and_integral():
    env = gym.make(ENV_ID).unwrapped
    gains = PIDGains(kp=[0.2, 0.3, 0.4], kd=[1.0, 2.0, 3.0], ki=[0.5, 0.6, 0.7])
    policy = PIDPolicy(env, gains)
    obs, info = env.reset(seed=0, options={"euler_321_deg": [2.0, -3.0, 4.0], "rate_rad_s": [0.0, 0.0, 0.0]})
    policy.reset()
    a0 = policy.act(obs, info)
    e = -np.radians([2.0, -3.0, 4.0])
    np.testing.assert_allclose(a0, -(gains.kp * e) / 0.8, rtol=1e-5)  # body torque T = −u, no integral yet
    a1 = policy.act(obs, info)  # same state again: one period of integral added
    np.testing.assert_allclose(a1, -(gains.kp * e + gains.ki * e * 0.01) / 0.8, rtol=1e-5)
    # rates enter through eq. 14: pure yaw body rate at zero attitude is a pure yaw Euler rate
    obs, info = env.reset(seed=0, options={"euler_321_deg": [0.0, 0.0, 0.0], "rate_rad_s": [0.0, 0.0, 0.1]})
    policy.reset()
    np.testing.assert_allclose(policy.act(obs, info), [0.0, 0.0, 3.0 * 0.1 / 0.8], atol=1e-6)


def test_pid_regulates_lab_test_and_fixed_yaw_matches_the_paper():
    """Table 3 on the lab test: settles; IAE within 5 % of an independent simulation
    (28.6 / 27.7 / 45.2 deg·s) and of the paper's yaw value 47.4."""
    env = gym.make(ENV_ID)
    r = pid_episode(env, PIDPolicy(env, PAPER_FIXED), seed=0, options=LAB_MANEUVER)
    assert not r["terminated"]
    np.testing.assert_allclose(r["iae_deg_s"], [28.6, 27.7, 45.2], rtol=0.05)
    assert r["iae_deg_s"][2] == pytest.approx(47.4, rel=0.05)
    assert np.degrees(np.abs(r["final_angle_rad"])).max() < 2.0
    assert r["peak_motor_torque_nm"] <= 0.8


def test_ga_is_deterministic_with_a_seed():
    cfg = GAConfig(population=4, generations=2, seed=3)
    with evaluator(ENV_ID, SHORT) as ev:
        m = [{"seed": 0, "options": LAB_MANEUVER}]
        a = tune_gains(ev, m, cfg)
        b = tune_gains(ev, m, cfg)
        c = tune_gains(ev, m, GAConfig(population=4, generations=2, seed=4))
    np.testing.assert_array_equal(a.gains.as_vector(), b.gains.as_vector())
    assert a.history == b.history
    assert not np.array_equal(a.gains.as_vector(), c.gains.as_vector())
    lo = np.array([0.0, 0.0, 0.0] * 3)
    hi = np.array([10.0, 20.0, 1.0] * 3)
    assert np.all(a.gains.as_vector() >= lo) and np.all(a.gains.as_vector() <= hi)


def test_ga_improves_on_its_initial_population():
    with evaluator(ENV_ID, SHORT) as ev:
        r = tune_gains(ev, [{"seed": 0, "options": LAB_MANEUVER}], GAConfig(population=8, generations=6, seed=0))
        again = tune_gains(ev, [{"seed": 0, "options": LAB_MANEUVER}], GAConfig(population=8, generations=6, seed=0))
        # the reported objective is the best gains' real objective
        env = ev.env
        direct = pid_episode(env, PIDPolicy(env, r.gains), 0, LAB_MANEUVER)["iae_charged_deg_s"].sum()
    assert len(r.history) == 7
    assert r.history[-1] < r.history[0]
    assert all(b <= a for a, b in zip(r.history, r.history[1:], strict=False))
    assert r.objective == pytest.approx(direct, rel=1e-12)
    assert again.objective == r.objective


def test_parallel_evaluation_matches_serial():
    genes = np.array([PAPER_FIXED.as_vector(), PAPER_FIXED.as_vector() * 0.5])
    m = [{"seed": 0, "options": LAB_MANEUVER}]
    with evaluator(ENV_ID, SHORT, workers=1) as ev:
        serial = ev.evaluate(genes, m, "cost")
    with evaluator(ENV_ID, SHORT, workers=2) as ev:
        parallel = ev.evaluate(genes, m, "cost")
    np.testing.assert_allclose(parallel, serial, rtol=1e-12)
    assert serial[0] != serial[1]


def test_meta_model_fit_recovers_a_linear_schedule():
    rng = np.random.default_rng(0)
    truth = rng.uniform(-1, 1, (3, 3, 3))
    angles = rng.uniform(-0.3, 0.3, (12, 3))
    rates = rng.uniform(-0.05, 0.05, (12, 3))
    genes = np.array(
        [np.column_stack(GainSchedule(truth).at(a, r)).ravel() for a, r in zip(angles, rates, strict=True)]
    )
    schedule, rms, rank = fit_schedule(genes, angles, rates, "rad")
    np.testing.assert_allclose(schedule.coefficients, truth, atol=1e-9)
    assert rms.max() < 1e-9 and list(rank) == [3, 3, 3]
    deg, _, _ = fit_schedule(genes, angles, rates, "deg")
    np.testing.assert_allclose(deg.at(angles[0], rates[0]), schedule.at(angles[0], rates[0]), atol=1e-9)


def test_same_pipeline_tunes_reaction_wheel_v0(tmp_path):
    out = tmp_path / "rw.json"
    kwargs = json.dumps({"episode_duration_s": 4.0, "control_dt_s": 0.1})
    argv = [
        "--env",
        "attitude_envs/ReactionWheel-v0",
        "--env-kwargs",
        kwargs,
        "--maneuvers",
        "1",
        "--objective",
        "cost",
    ]
    assert (
        cli_main(["tune-pid", *argv, "--population", "3", "--generations", "1", "--jobs", "1", "--out", str(out)]) == 0
    )
    doc = json.loads(out.read_text())
    gains = load_gains(out)
    assert isinstance(gains, PIDGains) and doc["env"] == "attitude_envs/ReactionWheel-v0"
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=4.0, control_dt_s=0.1)
    r = pid_episode(env, PIDPolicy.from_file(env, out), **{"seed": 0, "options": doc["maneuvers"][0]["options"]})
    assert r["J"] == pytest.approx(doc["best_objective"], rel=1e-9)


def test_tune_pid_schedule_mode_writes_loadable_schedule(tmp_path):
    out = tmp_path / "s.json"
    argv = ["--env-kwargs", json.dumps(SHORT), "--mode", "schedule", "--maneuvers", "3", "--units", "deg"]
    argv += ["--regressor", "final"]
    assert (
        cli_main(["tune-pid", *argv, "--population", "3", "--generations", "1", "--jobs", "1", "--out", str(out)]) == 0
    )
    schedule = load_gains(out)
    assert isinstance(schedule, GainSchedule) and schedule.units == "deg"
    doc = json.loads(out.read_text())
    assert np.array(doc["data_bank"]["genes"]).shape == (3, 9)
    assert doc["regressor"] == "final"
    # the literal option regresses on the states at the end of each optimal run, not the start
    starts = np.array([quaternion.to_euler_321_deg(m["options"]["attitude"]) for m in doc["maneuvers"]])
    finals = np.degrees(np.array(doc["data_bank"]["angles_rad"]))
    assert np.abs(finals).max() < np.abs(starts).max()
    assert not np.allclose(finals, starts, atol=0.5)


def test_sample_maneuvers_replay_the_env_start():
    env = gym.make(ENV_ID).unwrapped
    m = sample_maneuvers(env, 2, seed=5)
    _, info = env.reset(seed=5)
    np.testing.assert_allclose(m[0]["options"]["attitude"], info["truth"]["state"]["attitude"])
    assert quaternion.error_angle_rad(np.array(m[1]["options"]["attitude"]), info["truth"]["state"]["attitude"]) > 0


@pytest.mark.parametrize(
    "kwargs",
    [
        {"kp_bounds": (2.0, 1.0)},
        {"kd_bounds": (-1.0, 1.0)},
        {"population": 1},
        {"generations": 0},
        {"mutation_probability": 1.5},
        {"elitism": 20},
    ],
)
def test_bad_ga_config(kwargs):
    with pytest.raises(ValueError):
        GAConfig(**kwargs)


def test_bad_inputs():
    with pytest.raises(ValueError, match="units"):
        GainSchedule(np.zeros((3, 3, 3)), "furlongs")
    with pytest.raises(ValueError, match="units"):
        paper_schedule("grad")
    with pytest.raises(ValueError, match="at least 3"):
        fit_schedule(np.zeros((2, 9)), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="objective"):
        with evaluator(ENV_ID, SHORT) as ev:
            tune_gains(ev, [{"options": LAB_MANEUVER}], GAConfig(population=2, generations=1), objective="ise")
    with pytest.raises(ValueError, match="workers"):
        with evaluator(ENV_ID, SHORT, workers=0):
            pass
    with pytest.raises(ValueError, match="gains"):
        PIDPolicy(gym.make(ENV_ID), {"kp": 1})
    with pytest.raises(ValueError, match="kp"):
        PIDGains(kp=[1.0, math.nan, 1.0], kd=[0, 0, 0], ki=[0, 0, 0])


def test_reproduction_quick(tmp_path):
    assert "ga-pid" in REPRODUCTIONS
    from experiments.reproductions.ga_pid import reproduce

    rows = reproduce(tmp_path, quick=True)
    doc = json.loads((tmp_path / "ga-pid.json").read_text())
    assert doc["paper"] == "ga-pid" and len(doc["rows"]) == len(rows)
    claimed = [r for r in rows if r.tolerance is not None]
    assert len(claimed) == 1 and claimed[0].within  # fixed-PID yaw IAE vs Table 4
    assert (tmp_path / "ga-pid-gains-fixed.json").exists()
    load_gains(tmp_path / "ga-pid-gains-schedule.json")


def test_tune_pid_bad_input_returns_2(tmp_path, capsys):
    out = tmp_path / "x.json"
    assert cli_main(["tune-pid", "--kp-bounds", "2", "1", "--jobs", "1", "--out", str(out)]) == 2
    assert "kp_bounds" in capsys.readouterr().err
    assert cli_main(["tune-pid", "--env-kwargs", "[1]", "--out", str(out)]) == 2
    assert not out.exists()
