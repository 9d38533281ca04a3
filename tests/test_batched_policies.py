"""PID and the Q-learning LQR act on a batch of observations exactly as row by row."""

import gymnasium as gym
import numpy as np
import pytest

from agents import QLearningLQR
from baselines.allocation import WheelAllocator
from baselines.pid import PAPER_FIXED, PIDPolicy, paper_schedule

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"


def batched_state(infos):
    """The rows' measured states ``info["measured"]`` stacked into one batched ``measured`` dict."""
    keys = ("attitude", "rate_rad_s", "target_attitude")
    return {"measured": {k: np.stack([i["measured"][k] for i in infos]) for k in keys}}


@pytest.mark.parametrize("env_id,gains", [(RW, PAPER_FIXED), (AB, paper_schedule("deg"))])
def test_pid_batch_equals_row_by_row_along_closed_loop_episodes(env_id, gains):
    n = 4
    envs = [gym.make(env_id) for _ in range(n)]
    rows = [PIDPolicy(envs[0], gains) for _ in range(n)]  # one integral each
    batch = PIDPolicy(envs[0], gains)
    batch.reset()
    steps = [e.reset(seed=10 + i) for i, e in enumerate(envs)]
    for _ in range(30):
        obs = np.stack([s[0] for s in steps])
        infos = [s[1] for s in steps]
        actions = batch.act(obs, batched_state(infos))
        torques = batch.last_torque_nm.copy()
        assert actions.shape == (n, envs[0].action_space.shape[0])
        for i, pol in enumerate(rows):
            single = pol.act(obs[i], infos[i])
            assert np.allclose(torques[i], pol.last_torque_nm, rtol=1e-12, atol=1e-300)
            assert np.allclose(actions[i], single, rtol=0, atol=1e-6)
        steps = [e.step(a)[::4] for e, a in zip(envs, actions, strict=True)]  # (obs, info)
    assert np.abs(batch._integral).max() > 0  # the integral term took part (schedule KI ≠ 0)


def test_pid_batch_from_observations_matches_the_state_to_float32():
    env = gym.make(RW)
    envs = [gym.make(RW) for _ in range(5)]
    resets = [e.reset(seed=i) for i, e in enumerate(envs)]
    obs = np.stack([r[0] for r in resets])
    from_state = PIDPolicy(env, paper_schedule("rad"))
    from_obs = PIDPolicy(env, paper_schedule("rad"))
    from_state.act(obs, batched_state([r[1] for r in resets]))
    from_obs.act(obs, {})  # batched envs' infos carry no state: the error state is read from obs
    scale = np.abs(from_state.last_torque_nm).max()
    assert scale > 0 and np.allclose(from_obs.last_torque_nm, from_state.last_torque_nm, rtol=0, atol=1e-5 * scale)


def test_pid_reset_rows_zeroes_only_those_rows():
    env = gym.make(AB)
    pid = PIDPolicy(env, paper_schedule("rad"))
    pid.reset()
    obs = np.random.default_rng(0).normal(scale=0.05, size=(3, 6)).astype(np.float32)
    pid.act(obs, {})
    before = pid._integral.copy()
    pid.reset_rows([False, True, False])
    assert np.array_equal(pid._integral[[0, 2]], before[[0, 2]]) and np.all(pid._integral[1] == 0.0)
    with pytest.raises(ValueError, match="obs has 2 rows but the PID integrates 3"):
        pid.act(obs[:2], {})


@pytest.mark.parametrize("saturation", ["scale", "clip"])
def test_allocator_batch_equals_row_by_row_with_saturation(saturation):
    model = gym.make(RW).unwrapped.model  # 4-wheel pyramid: the LP of the scale mode acts
    alloc = WheelAllocator(model, saturation=saturation)
    demand = np.random.default_rng(1).normal(scale=2.0 * model.params.max_wheel_torque_nm, size=(12, 3))
    batch = alloc.motor_torque_nm(demand)
    rows = np.stack([alloc.motor_torque_nm(d) for d in demand])
    assert alloc.saturated_calls > 2  # some rows saturated, both times
    assert np.allclose(batch, rows, rtol=1e-12, atol=1e-15)
    assert np.abs(batch).max() <= model.params.max_wheel_torque_nm * (1 + 1e-12)


def test_q_learning_lqr_acts_on_a_batch():
    env = gym.make(RW)
    probe = QLearningLQR(env)
    gain = np.random.default_rng(2).normal(size=probe.gain.shape)
    agent = QLearningLQR(env, initial_gain=gain)
    obs = np.random.default_rng(3).normal(scale=0.05, size=(6, agent.n)).astype(np.float32)
    batch = agent.act(obs, {})
    assert batch.shape == (6, env.action_space.shape[0])
    assert np.allclose(batch, np.stack([agent.act(o, {}) for o in obs]), rtol=0, atol=1e-7)
    assert np.array_equal(agent.predict(obs)[0], batch)
    assert np.abs(batch).max() > 0.01  # not a trivially zero action
