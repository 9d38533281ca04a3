"""Scenario presets load and run; the fault campaign grid reports J relative to healthy."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs.scenarios import list_scenarios, load_scenario, make_scenario_env
from baselines.lqr import LQRPolicy
from experiments import fault_campaign as fc

PRESETS = {"fault-campaign", "magnetorquer-fault", "sensor-bias", "stuck-wheel", "wheel-degraded", "wheel-failure"}


def test_presets_ship_and_build_envs_with_their_faults():
    assert PRESETS <= set(list_scenarios())
    for name in PRESETS - {"magnetorquer-fault"}:
        sc = load_scenario(name)
        env = make_scenario_env(sc)
        _, info = env.reset(seed=0)
        assert len(info["truth"]["faults"]) == len(sc["faults"])
        for truth, given in zip(info["truth"]["faults"], sc["faults"], strict=True):
            assert truth["kind"] == given["kind"] and truth["onset_s"] == given["onset_s"]


def test_wheel_failure_reaches_the_plant_and_three_wheels_keep_control():
    env = make_scenario_env("wheel-failure")
    policy = LQRPolicy(env)
    obs, info = env.reset(seed=0)
    while True:
        t = info["time_s"]
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        if t >= 2.0 - 1e-9:
            assert info["truth"]["applied"][0] == 0.0
        else:
            assert info["truth"]["applied"][0] == pytest.approx(info["commanded"][0], abs=1e-15)
        if terminated or truncated:
            break
    assert not terminated
    assert info["truth"]["error_angle_deg"] < 2.0  # still converging on three wheels (healthy: 1.41 deg at 60 s)


def test_magnetorquer_fault_is_the_papers_step_at_50_s():
    env = make_scenario_env("magnetorquer-fault", env_id="attitude_envs/LinearSystem-v0", episode_steps=5002)
    env.reset(seed=0)
    applied = [env.step(np.ones(3))[4]["truth"]["applied"] for _ in range(5002)]
    assert np.allclose(applied[4999], [2.0, 2.0, 2.0])  # t = 49.99 s, action_scale 2
    assert np.allclose(applied[5000], [1.8, 1.4, 1.2])  # t = 50 s: E = diag(0.9, 0.7, 0.6)
    with pytest.raises(ValueError, match="names no env"):
        make_scenario_env("magnetorquer-fault")


def test_bad_scenarios_raise(tmp_path):
    with pytest.raises(ValueError, match="scenario must be one of"):
        load_scenario("no-such-scenario")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nenv: attitude_envs/ReactionWheel-v0\nfautls: []\n")
    with pytest.raises(ValueError, match=r"unknown keys \['fautls'\]"):
        load_scenario(str(bad))
    bad.write_text("name: x\nenv: attitude_envs/ReactionWheel-v0\nfaults: [{kind: outage, index: 9}]\n")
    with pytest.raises(ValueError, match=r"faults\[0\].index must be an integer in \[0, 3\]"):
        make_scenario_env(str(bad))


def test_severity_maps_to_fault_dicts():
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=30.0)
    f = fc.campaign_fault(env, "bias", 0.5, 10.0)
    assert f == {"kind": "bias", "target": "actuator", "index": 0, "onset_s": 10.0, "value": 0.25}
    assert fc.campaign_fault(env, "saturation", 0.25, 1.0)["value"] == 0.75
    assert fc.campaign_fault(env, "outage", 0.5, 10.0)["duration_s"] == 10.0
    assert fc.campaign_fault(env, "drift", 1.0, 0.0)["value"] == pytest.approx(0.05)
    with pytest.raises(ValueError, match=r"severity must be in \[0, 1\]"):
        fc.campaign_fault(env, "bias", 1.5, 0.0)
    with pytest.raises(ValueError, match="kind must be one of"):
        fc.campaign_fault(env, "melt", 0.5, 0.0)


def test_campaign_rows_table_and_heatmap(tmp_path):
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=6.0)
    rows = fc.run_campaign(env, LQRPolicy(env), ["bias", "loss_of_effectiveness"], [0.5, 1.0], [1.0], [0, 1])
    assert len(rows) == 2 + 2 * 2 * 2
    healthy = {r["seed"]: r["J"] for r in rows if r["kind"] == "healthy"}
    for r in rows[2:]:
        assert r["J_healthy"] == healthy[r["seed"]] and r["J_ratio"] == pytest.approx(r["J"] / healthy[r["seed"]])
    bias = [r["J_ratio"] for r in rows if r["kind"] == "bias"]
    assert min(bias) > 1.2  # a 0.25-0.5 N·m bias on one wheel costs a lot
    table = fc.campaign_table(rows)
    assert "| bias | 1 |" in table and "s = 0.5" in table
    png = fc.campaign_heatmap(rows, tmp_path / "h.png")
    assert png.stat().st_size > 5000


def test_scenario_command_line(capsys):
    assert fc.main(["scenario", "stuck-wheel", "--seeds", "1"]) == 0
    out = capsys.readouterr().out
    assert "| 0 |" in out and "J / J_healthy" in out
    assert fc.main(["scenario", "nope"]) == 2


def test_sensor_kinds_in_the_campaign_grid():
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=30.0)
    f = fc.campaign_fault(env, "gyro.bias", 0.5, 10.0)
    assert f == {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "onset_s": 10.0, "value": 0.005}
    f = fc.campaign_fault(env, "star_tracker.dropout", 0.5, 10.0)
    assert f["index"] == "all" and f["duration_s"] == 10.0 and f["mode"] == "hold"
    assert fc.campaign_fault(env, "gyro.noise_increase", 1.0, 0.0)["value"] == 10.0
    with pytest.raises(ValueError, match=r"kind \(sensor part\) must be one of"):
        fc.campaign_fault(env, "sun.bias", 0.5, 0.0)
    rows = fc.run_campaign(
        gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=8.0),
        LQRPolicy(env),
        ["gyro.bias"],
        [1.0],
        [1.0],
        [0],
    )
    assert rows[1]["J_ratio"] > 1.05  # the controller chases the biased rate
