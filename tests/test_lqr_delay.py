"""The delay-compensating LQR: the gain of the state augmented with the commands in flight."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401
from attitude_envs.linearization import LinearModel
from baselines.lqr import LQRPolicy, _delay_gain

AB = "attitude_envs/AirBearing-v1"


def _total(env, policy, seeds):
    total = 0.0
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        policy.reset(seed)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
            total -= reward
            done = terminated or truncated
    return total


def test_the_delay_gain_is_optimal_on_a_scalar_plant():
    """x⁺ = a x + b u_{k−1}: the augmented Riccati gain equals brute-force search over
    linear feedbacks u = −k₁ x − k₂ p of the infinite-horizon cost from a few starts."""
    model = LinearModel(np.array([[1.05]]), np.array([[0.5]]), np.array([[1.0]]), np.array([[0.3]]), None, 0.1)
    k = _delay_gain(model, 1)[0]
    a, b, q, r = 1.05, 0.5, 1.0, 0.3

    def cost(k1, k2):
        total = 0.0
        for x0, p0 in ((1.0, 0.0), (0.0, 1.0), (1.0, 1.0)):
            x, p = x0, p0
            for _ in range(400):
                u = -k1 * x - k2 * p
                total += q * x * x + r * p * p
                x, p = a * x + b * p, u
        return total

    best = cost(*k)
    for dk1 in (-0.02, 0.02):
        for dk2 in (-0.02, 0.02):
            assert cost(k[0] + dk1, k[1] + dk2) >= best


def test_no_delay_is_the_nominal_lqr():
    env = gym.make(AB)
    np.testing.assert_array_equal(LQRPolicy(env).gain, LQRPolicy(env, delay_steps="env").gain)


def test_compensating_the_delay_lowers_j_under_it():
    env = gym.make(AB, conditions={"delay_steps": 1})
    nominal = _total(env, LQRPolicy(env), range(3))
    compensated = _total(env, LQRPolicy(env, delay_steps="env"), range(3))
    assert compensated < 0.99 * nominal  # the 0.5 s delay costs the nominal LQR about 15 %


def test_bad_delay_is_named():
    env = gym.make(AB)
    with pytest.raises(ValueError, match="delay_steps"):
        LQRPolicy(env, delay_steps=-1)
    with pytest.raises(ValueError, match="delay_steps > 0 needs discretization='zoh'"):
        LQRPolicy(env, discretization="continuous", delay_steps=1)
