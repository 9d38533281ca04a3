"""Minimum-norm, saturation-aware wheel allocation (feedback-linearization paper, eqs. 9–12)."""

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401
from baselines.allocation import WheelAllocator


def model(max_torque=0.5):
    return gym.make("attitude_envs/ReactionWheel-v0", max_wheel_torque_nm=max_torque).unwrapped.model


def test_pyramid_pseudo_inverse_is_eq_12():
    alloc = WheelAllocator(model())
    eq12 = (np.sqrt(3) / 4) * np.array([[1, 1, 1], [-1, 1, 1], [-1, -1, 1], [1, -1, 1.0]])
    # the env's axes equal eq. 10's columns; the body receives −A u, hence the sign
    assert np.allclose(alloc.matrix, -eq12, atol=1e-12)


def test_unsaturated_demand_is_delivered_exactly():
    m = model()
    alloc = WheelAllocator(m)
    T = np.array([0.05, -0.1, 0.08])
    u = alloc.motor_torque_nm(T)
    assert np.allclose(-m.params.wheel_axes @ u, T, atol=1e-15)
    assert alloc.saturated_calls == 0


def test_infeasible_demand_is_scaled_keeping_direction():
    m = model(max_torque=0.1)
    alloc = WheelAllocator(m)
    T = np.array([0.0, 0.0, 0.3])  # needs 0.13 N·m on every wheel: no null-space help possible
    assert np.max(np.abs(alloc.matrix @ T)) > 0.1
    u = alloc.motor_torque_nm(T)
    delivered = -m.params.wheel_axes @ u
    assert np.max(np.abs(u)) == pytest.approx(0.1, abs=1e-12)
    assert np.allclose(np.cross(delivered, T), 0, atol=1e-12) and delivered @ T > 0
    assert alloc.saturated_calls == 1


def test_null_space_redistribution_keeps_full_torque_when_feasible():
    m = model(max_torque=0.13)
    alloc = WheelAllocator(m)
    # a minimum-norm solution (orthogonal to the null vector [1, -1, 1, -1]) peaking at 0.15 N·m;
    # adding -0.025·[1, -1, 1, -1] lowers the peak to 0.125 N·m
    u0 = np.array([0.15, 0.05, -0.1, 0.0])
    T = -m.params.wheel_axes @ u0
    assert np.allclose(alloc.matrix @ T, u0, atol=1e-12)
    u = alloc.motor_torque_nm(T)
    assert np.max(np.abs(u)) == pytest.approx(0.125, abs=1e-9)
    assert np.allclose(-m.params.wheel_axes @ u, T, atol=1e-9)  # the full demand is still delivered


def test_clip_mode_and_bad_mode():
    m = model(max_torque=0.1)
    u = WheelAllocator(m, "clip").motor_torque_nm(np.array([0.0, 0.0, 0.3]))
    assert np.allclose(np.abs(u), 0.1)
    assert np.all(np.abs(WheelAllocator(m).action(np.array([1.0, 2.0, 3.0]))) <= 1.0)
    with pytest.raises(ValueError, match="saturation"):
        WheelAllocator(m, "ignore")


def test_body_action_frame_allocates_minimum_norm_and_keeps_the_null_space_at_rest():
    env = gym.make("attitude_envs/ReactionWheel-v0", action_frame="body")
    assert env.action_space.shape == (3,)
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    axes = env.unwrapped.model.params.wheel_axes
    null = np.linalg.svd(axes)[2][3:]  # rows spanning the wheels' null space
    for _ in range(50):
        a = rng.uniform(-0.3, 0.3, 3)  # unsaturated: every wheel within its limit
        _, _, _, _, info = env.step(a)
        assert np.allclose(-axes @ info["truth"]["applied"], a * 0.5, atol=1e-12)
        assert np.allclose(null @ info["truth"]["applied"], 0.0, atol=1e-12)
    # wheel momentum stays in the row space of A: nothing accumulates in the null space
    assert np.allclose(null @ info["truth"]["state"]["wheel_speed_rad_s"], 0.0, atol=1e-9)


def test_lqr_cost_is_the_same_in_both_action_frames():
    from baselines.lqr import LQRPolicy

    costs = {}
    for frame in ("wheel", "body"):
        env = gym.make("attitude_envs/ReactionWheel-v0", action_frame=frame, episode_duration_s=20.0)
        policy, (obs, info), J, done = LQRPolicy(env), env.reset(seed=3), 0.0, False
        while not done:
            obs, r, term, trunc, info = env.step(policy.act(obs, info))
            J, done = J - r, term or trunc
        costs[frame] = J
    # the same torques up to the float32 rounding of the two actions (4 vs 3 numbers)
    assert costs["body"] == pytest.approx(costs["wheel"], rel=1e-6)


def test_allocator_returns_body_demand_for_body_frame_envs():
    env = gym.make("attitude_envs/ReactionWheel-v0", action_frame="body")
    alloc = WheelAllocator.for_env(env)
    assert np.allclose(alloc.action(np.array([0.1, -0.2, 0.7])), [0.2, -0.4, 1.0])
    with pytest.raises(ValueError, match="action_frame"):
        gym.make("attitude_envs/ReactionWheel-v0", action_frame="motor")
