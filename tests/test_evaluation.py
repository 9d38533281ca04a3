"""Metrics on a hand-made trace, dt-independence, the evaluator grid, CSV/JSON and the SB3 adapter."""

import csv
import json

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401
from attitude_envs import quaternion
from attitude_envs.evaluation import EpisodeTrace, Scenario, episode_metrics, evaluate, record_episode
from attitude_envs.evaluation.runner import write_csv, write_json
from baselines.base import ZeroPolicy
from baselines.feedback_linearization import FeedbackLinearizationPolicy
from baselines.quaternion_lqr import QuaternionLQRPolicy
from experiments.plots import plot_episodes, plot_error_overlay, plot_metric_bars
from experiments.training.policy import SB3Policy

RPM = 60 / (2 * np.pi)


def synthetic_trace() -> EpisodeTrace:
    """Rotation about x: 10° → 0 at t = 5 s, overshoot to −2° at 6 s, back to 0 at 8 s."""
    t = np.arange(0, 10.0 + 1e-9, 0.5)
    angle = np.interp(t, [0, 5, 6, 8, 10], [10, 0, -2, 0, 0])
    att = np.array([quaternion.from_axis_angle([1, 0, 0], np.radians(a)) for a in angle])
    k = len(t) - 1
    wheel = np.zeros((k + 1, 4))
    wheel[:, 0] = 100.0 * t
    applied = np.zeros((k, 4))
    applied[:, 0] = 0.01
    action = applied / 0.5
    action[:5, 1] = 1.5  # 5 of 20 steps ask beyond the torque limit
    return EpisodeTrace(
        time_s=t,
        attitude=att,
        target_attitude=np.tile([0, 0, 0, 1.0], (k + 1, 1)),
        rate_rad_s=np.zeros((k + 1, 3)),
        wheel_speed_rad_s=wheel,
        error_angle_deg=np.abs(angle),
        action=action,
        commanded_nm=np.clip(action, -1, 1) * 0.5,
        applied_nm=applied,  # wheel 2 delivers nothing of its commanded 0.5 N·m (speed limit)
        cost=np.full(k, 0.25),
        terminated=False,
        max_wheel_torque_nm=0.5,
    )


def test_metrics_of_a_hand_made_trace():
    m = episode_metrics(synthetic_trace(), wheel_speed_limit_rad_s=500.0)
    assert m["J"] == pytest.approx(5.0)
    assert m["eulerint_deg_s"] == pytest.approx(25 + 1 + 2)  # ∫|α| dt, not time-weighted
    assert m["overshoot_deg"] == pytest.approx(2.0, abs=1e-9)
    assert m["overshoot_pct"] == pytest.approx(20.0, abs=1e-7)
    assert m["settling_time_s"] == pytest.approx(8.0)  # 2 % of 10° = 0.2°: 0.5° at 7.5 s
    assert m["settling_time_abs_s"] == pytest.approx(7.0)  # 1° band: 1.5° at 6.5 s
    assert m["steady_state_error_deg"] == pytest.approx(0.0)
    assert m["power_integral_j"] == pytest.approx(50.0)  # ∫ 100 t · 0.01 dt over 10 s
    assert m["power_sum_w"] == pytest.approx(95.0)  # Σ_k 100 t_k · 0.01, t_k = 0 … 9.5
    assert m["effort_integral_nm_s"] == pytest.approx(0.1)
    assert m["effort_sum_nm"] == pytest.approx(0.2)
    assert m["energy_integral_nm2_s"] == pytest.approx(1e-3)
    assert m["peak_wheel_speed_rpm"] == pytest.approx(1000 * RPM)
    assert m["wheel_speed_violation"] is True
    assert m["saturation_fraction"] == pytest.approx(0.25)


def test_metrics_reject_bad_bands():
    with pytest.raises(ValueError, match="settling_band"):
        episode_metrics(synthetic_trace(), settling_band=2.0)
    with pytest.raises(ValueError, match="steady_state_fraction"):
        episode_metrics(synthetic_trace(), steady_state_fraction=0.0)


def test_integral_metrics_do_not_depend_on_the_control_period():
    target = quaternion.from_euler_321_deg(5.0, 5.0, 5.0)
    out = {}
    for dt in (0.01, 0.02):
        env = gym.make(
            "attitude_envs/ReactionWheel-v0", control_dt_s=dt, integrator_dt_s=dt, episode_duration_s=20.0,
            max_wheel_speed_rad_s=np.inf, initial_attitude=[0, 0, 0, 1.0],
        )  # fmt: skip
        out[dt] = episode_metrics(record_episode(env, FeedbackLinearizationPolicy(env), 0, {"target_attitude": target}))
    for key in ("eulerint_deg_s", "power_integral_j", "effort_integral_nm_s", "energy_integral_nm2_s", "J"):
        assert out[0.02][key] == pytest.approx(out[0.01][key], rel=5e-3), key
    assert out[0.01]["effort_sum_nm"] == pytest.approx(2 * out[0.02]["effort_sum_nm"], rel=5e-3)


def test_evaluator_grid_rows_and_files(tmp_path):
    base = {"control_dt_s": 0.1, "episode_duration_s": 3.0}
    scenarios = [
        Scenario("nominal", env_kwargs=base),
        Scenario("weak-wheels", env_kwargs={**base, "max_wheel_torque_nm": 0.002}),
    ]
    ev = evaluate(
        "attitude_envs/ReactionWheel-v0",
        {"zero": ZeroPolicy, "quaternion-lqr": QuaternionLQRPolicy},
        scenarios,
        seeds=[0, 1],
        keep_traces=True,
    )
    assert len(ev.rows) == 8 and len(ev.traces) == 8
    assert {(r["scenario"], r["controller"], r["seed"]) for r in ev.rows} == {
        (s, c, k) for s in ("nominal", "weak-wheels") for c in ("zero", "quaternion-lqr") for k in (0, 1)
    }
    # seeds draw different targets; the zero policy never moves; the weak wheels saturate
    lqr = ev.where(scenario="nominal", controller="quaternion-lqr")
    assert lqr[0]["initial_error_deg"] != lqr[1]["initial_error_deg"]
    zero = ev.where(scenario="nominal", controller="zero")[0]
    assert zero["final_error_deg"] == pytest.approx(zero["initial_error_deg"])
    assert lqr[0]["final_error_deg"] < zero["final_error_deg"]
    assert all(r["saturation_fraction"] > 0.5 for r in ev.where(scenario="weak-wheels", controller="quaternion-lqr"))
    assert all(r["saturation_fraction"] == 0.0 for r in ev.where(scenario="nominal"))
    with (write_csv(ev.rows, tmp_path / "t.csv")).open() as fh:
        back = list(csv.DictReader(fh))
    assert len(back) == 8 and float(back[0]["J"]) == pytest.approx(ev.rows[0]["J"])
    assert json.loads(write_json(ev.rows, tmp_path / "t.json").read_text())[3]["controller"] == ev.rows[3]["controller"]
    traces = {c: ev.traces[("nominal", c, 0)] for c in ("zero", "quaternion-lqr")}
    for path in (
        plot_episodes(traces, tmp_path / "ep.png"),
        plot_error_overlay(traces, tmp_path / "err.png"),
        plot_metric_bars(ev.rows, tmp_path / "bars.png"),
    ):
        assert path.stat().st_size > 10_000
    with pytest.raises(ValueError, match="seeds"):
        evaluate("attitude_envs/ReactionWheel-v0", {"zero": ZeroPolicy}, scenarios, seeds=[])


def test_sb3_adapter_runs_a_real_model():
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=1.0)
    model = sb3.PPO("MlpPolicy", env, n_steps=32, batch_size=32, seed=0, device="cpu")
    policy = SB3Policy(model)
    trace = record_episode(env, policy, seed=0)
    assert trace.steps == 10 and trace.action.shape == (10, 4)
    obs, _ = env.reset(seed=0)
    assert np.allclose(policy.act(obs, {}), model.predict(obs, deterministic=True)[0])
    with pytest.raises(ValueError, match="predict"):
        SB3Policy(object())
