"""LinearSystem-v0: its preset, a user's own system without preset values, and the info contract."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs import presets
from attitude_envs.envs.linear_system import LinearSystemEnv

LS = "attitude_envs/LinearSystem-v0"


def test_default_preset_is_heravi_2017_euler_model_bitwise():
    """The preset's matrices and start are the ones the old hard-coded plant computed."""
    dt, inertia = 0.01, np.array([1000.0, 1000.0, 800.0])
    A = np.eye(6)
    A[:3, 3:] = 0.5 * dt * np.eye(3)
    B = np.zeros((6, 3))
    B[3:, :] = dt * np.diag(1.0 / inertia)
    q0 = np.array([0.4783, 0.3722, -0.4329, 0.6645])
    q0 = q0 / np.linalg.norm(q0)
    x0 = np.concatenate([q0[1:], [0.01, -0.02, 0.01]])
    for env in (LinearSystemEnv(), LinearSystemEnv(preset="spec-001"), gym.make(LS).unwrapped):
        assert env.preset in ("heravi-2017", "spec-001")
        assert np.array_equal(env.model.A, A) and np.array_equal(env.model.B, B) and env.model.dt_s == dt
        assert np.array_equal(env.action_scale, [2.0, 2.0, 2.0])
        assert np.array_equal(env.reset(seed=3)[1]["truth"]["state"], x0)  # x0_std = 0
    p = presets.get("LinearSystem-v0")
    assert p.name == "heravi-2017" and p.aliases == ("spec-001",)
    assert p.source("A").startswith("Heravi & Novinzadeh 2017, eq. 59")
    assert p.source("action_scale").startswith("assumed")


@pytest.mark.parametrize(("n", "m"), [(6, 3), (2, 1)])
def test_a_users_system_takes_no_preset_values(n, m):
    """A and B without ``preset``: the neutral defaults, not the default preset's x0/scale."""
    rng = np.random.default_rng(n)
    A, B = np.eye(n) + 0.01 * rng.standard_normal((n, n)), rng.standard_normal((n, m))
    for env in (LinearSystemEnv(A=A, B=B), gym.make(LS, A=A, B=B).unwrapped):
        assert env.preset is None
        assert np.array_equal(env.model.Q, np.eye(n)) and np.array_equal(env.model.R, np.eye(m))
        assert np.array_equal(env.action_scale, np.ones(m)) and env.model.dt_s == 1.0
        draws = np.array([env.reset(seed=s)[1]["truth"]["state"] for s in range(400)])
        assert np.all(np.abs(draws.mean(axis=0)) < 0.2)  # x0_mean = 0
        assert np.all(np.abs(draws.std(axis=0) - 1.0) < 0.15)  # x0_std = 1
        expected = np.random.default_rng(7).normal(size=n)  # x0 = 0 + 1 · N(0, 1) from the env's RNG
        assert np.array_equal(env.reset(seed=7)[1]["truth"]["state"], expected)


def test_explicit_preset_with_a_users_matrix_overrides_only_that_matrix():
    A = 0.9 * np.eye(6)
    env = LinearSystemEnv(preset="heravi-2017", A=A)
    assert env.preset == "heravi-2017" and np.array_equal(env.model.A, A)
    assert np.array_equal(env.action_scale, [2.0, 2.0, 2.0]) and env.model.dt_s == 0.01
    assert np.array_equal(env.model.B, LinearSystemEnv().model.B)
    with pytest.raises(ValueError, match="Q must be 2x2"):  # the preset's 6-state weights do not fit
        LinearSystemEnv(preset="heravi-2017", A=np.eye(2), B=np.ones((2, 1)))
    with pytest.raises(ValueError, match="A is required"):
        LinearSystemEnv(preset=None)


def test_info_truth_is_the_transition_and_measured_is_the_observed_state():
    env = LinearSystemEnv()
    obs, info = env.reset(seed=0)
    x = info["truth"]["state"]
    assert np.array_equal(info["measured"], x) and info["measured"] is not x
    assert info["cost"] == 0.0 and info["time_s"] == 0.0 and np.array_equal(obs, x.astype(np.float32))
    assert np.array_equal(env.state, x)
    obs, reward, _, _, info = env.step(np.array([0.25, -0.5, 2.0], np.float32))
    truth = info["truth"]
    assert set(truth) == {"state", "previous_state", "applied", "faults"}
    assert np.array_equal(truth["previous_state"], x)  # the state the step started from
    assert np.array_equal(truth["state"], env.state)  # the state after the step
    assert np.array_equal(info["measured"], truth["state"])  # the latest measurement: after the step
    assert np.array_equal(info["commanded"], [0.5, -1.0, 2.0])  # action_scale · clipped action
    assert np.array_equal(truth["applied"], info["commanded"])
    assert info["time_s"] == 0.01 and reward == -info["cost"]


def test_measured_follows_the_state_sensor():
    env = LinearSystemEnv(sensors={"state": {"noise_std": 1e-3}}, process_noise_std=0.0)
    obs, info = env.reset(seed=0)
    for _ in range(3):
        assert np.array_equal(info["measured"], info["sensors"]["state"])
        assert np.array_equal(info["measured"].astype(np.float32), obs)
        truth = info["truth"]["state"]
        assert 0 < np.max(np.abs(info["measured"] - truth)) < 0.01
        assert "state" in info["truth"]["sensor_bias"]
        obs, _, _, _, info = env.step(np.zeros(3, np.float32))


def test_public_members():
    env = LinearSystemEnv(process_noise_std=0.1, faults=[{"kind": "outage", "index": 1}])
    env.reset(seed=0)
    assert env.process_noise_std == 0.1 and env.fault_layer.n == 3 and len(env.fault_layer.realized) == 1
    state = env.state
    state[0] = 99.0
    assert env.state[0] != 99.0  # a copy
