"""Fault-tolerant LQR: the IMM FDI isolates a wheel outage from measured and commanded data,
the LQR is redesigned over the wheels left, and the policy never needs the truth."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs.estimation.fdi import ActuatorFDI
from attitude_envs.info import TRUTH, policy_view
from attitude_envs.scenarios import make_scenario_env
from baselines.fault_tolerant import FaultTolerantLQRPolicy, controllable_subspace
from baselines.lqr import LQRPolicy

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"


def outage(index: int, onset_s: float) -> dict:
    return {"kind": "outage", "target": "actuator", "index": index, "onset_s": onset_s, "duration_s": None}


def episode(env, policy, seed: int) -> tuple[float, dict, list[np.ndarray]]:
    """J, the last info and the actions; the policy gets the policy view (no truth)."""
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    total, actions = 0.0, []
    while True:
        view = policy_view(info)
        assert TRUTH not in view
        actions.append(policy.act(obs, view))
        obs, _, terminated, truncated, info = env.step(actions[-1])
        total += info["cost"]
        if terminated or truncated:
            return total, info, actions


@pytest.mark.parametrize("frame", ["wheel", "body"])
def test_a_wheel_outage_is_isolated_and_the_dead_wheel_gets_no_more_demand(frame):
    env = gym.make(RW, episode_duration_s=4.0, action_frame=frame, faults=[outage(2, 1.0)])
    policy = FaultTolerantLQRPolicy(env)
    _, info, actions = episode(env, policy, seed=0)
    assert [d["index"] for d in policy.isolated] == [2]
    assert policy.isolated[0]["effectiveness"] == 0.0
    assert 1.0 < policy.isolated[0]["time_s"] <= 2.0
    assert policy.effectiveness.tolist() == [1.0, 1.0, 0.0, 1.0]
    if frame == "wheel":
        assert actions[-1][2] == 0.0  # re-allocated over wheels 0, 1, 3
    assert info["truth"]["error_angle_deg"] < 60.0


def test_healthy_episodes_are_the_plain_lqr():
    env = gym.make(RW, episode_duration_s=10.0)
    ft = FaultTolerantLQRPolicy(env)
    j_ft, _, a_ft = episode(env, ft, seed=1)
    j_lqr, _, a_lqr = episode(env, LQRPolicy(env), seed=1)
    assert ft.isolated == [] and j_ft == j_lqr
    assert all(np.array_equal(a, b) for a, b in zip(a_ft, a_lqr, strict=True))


def test_two_wheel_failure_isolates_both_and_beats_or_matches_the_lqr():
    env = make_scenario_env("two-wheel-failure", episode_duration_s=30.0)
    for seed in (0, 3):
        ft = FaultTolerantLQRPolicy(env)
        j_ft, _, _ = episode(env, ft, seed)
        j_lqr, _, _ = episode(env, LQRPolicy(env), seed)
        assert sorted(d["index"] for d in ft.isolated) == [0, 1]
        assert all(2.0 < d["time_s"] <= 3.0 for d in ft.isolated)
        assert j_ft <= j_lqr * (1 + 1e-3)  # 60 s episodes: 975.5 vs 986.5 (seed 0), 45.9 vs 46.5 (seed 3)


def test_air_bearing_outage_is_isolated_without_false_alarms():
    # the FDI gets the nominal offset torque at the measured attitude (else it false-alarms)
    healthy = gym.make(AB, episode_duration_s=3.0)
    ft = FaultTolerantLQRPolicy(healthy)
    episode(healthy, ft, seed=0)
    assert ft.isolated == []
    env = gym.make(AB, episode_duration_s=3.0, faults=[outage(0, 1.5)])
    ft = FaultTolerantLQRPolicy(env)
    j_ft, _, actions = episode(env, ft, seed=0)
    assert [d["index"] for d in ft.isolated] == [0] and ft.isolated[0]["time_s"] > 1.5
    assert actions[-1][0] == 0.0
    j_lqr, _, _ = episode(env, LQRPolicy(env), seed=0)
    assert j_ft <= 1.05 * j_lqr


def test_controllable_subspace_of_a_double_integrator_pair():
    a = np.zeros((4, 4))
    a[0, 2] = a[1, 3] = 1.0  # positions (0, 1), rates (2, 3)
    b = np.array([[0.0], [0.0], [1.0], [0.0]])  # only axis 0 is actuated
    basis = controllable_subspace(a, b)
    assert basis.shape == (4, 2)
    assert np.allclose(basis @ basis.T, np.diag([1.0, 0.0, 1.0, 0.0]))  # position and rate of axis 0


def test_no_wheel_left_commands_nothing():
    env = gym.make(RW, episode_duration_s=1.0)
    ft = FaultTolerantLQRPolicy(env)
    ft.effectiveness = np.zeros(4)
    ft._redesign()
    obs, info = env.reset(seed=0)
    assert not np.any(ft._to_action @ (-ft._gain @ obs.astype(float)))


def test_fdi_with_a_known_fault_monitors_only_the_other_wheels():
    env = gym.make(RW)
    fdi = ActuatorFDI.for_env(env, known_effectiveness=[0.0, 1.0, 1.0, 1.0], degraded_effectiveness=(0.0, 0.5))
    assert len(fdi.effectiveness) == 1 + 3 * 2  # healthy + 3 wheels x 2 levels
    assert all(e[0] == 0.0 for e in fdi.effectiveness)
    with pytest.raises(ValueError, match=r"known_effectiveness must be 4 values in \[0, 1\]"):
        ActuatorFDI.for_env(env, known_effectiveness=[0.0, 0.0, 0.0, 0.0])


def test_bad_envs_and_parameters_raise():
    with pytest.raises(ValueError, match="ReactionWheel-v0 or AirBearing-v0"):
        FaultTolerantLQRPolicy(gym.make("attitude_envs/LinearSystem-v0"))
    with pytest.raises(ValueError, match="degraded_effectiveness must be in"):
        FaultTolerantLQRPolicy(gym.make(RW), degraded_effectiveness=1.5)
