"""Every env declares its success metric (attitude_envs.evaluation.success) and exposes its
realized fault onsets; campaigns ask the env instead of guessing from its model or info."""

import math

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs
from attitude_envs.evaluation.success import FINAL_ERROR_DEG, FINAL_STATE_FRACTION, SuccessMetric
from attitude_envs.evaluation.trace import play
from attitude_envs.info import fault_onsets_s
from baselines.base import ZeroPolicy

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"
MT = "attitude_envs/Magnetorquer-v0"
FS = "attitude_envs/FuelSlosh-v0"
LS = "attitude_envs/LinearSystem-v0"
SHORT = {
    RW: {"episode_duration_s": 3.0},
    AB: {"episode_duration_s": 0.5},
    MT: {"episode_duration_s": 5.0, "control_dt_s": 1.0, "integrator_dt_s": 0.1},
    FS: {"episode_duration_s": 2.0},
    LS: {"episode_steps": 30},
}
DECLARED = {RW: FINAL_ERROR_DEG, AB: FINAL_ERROR_DEG, MT: FINAL_ERROR_DEG, FS: FINAL_STATE_FRACTION}
DECLARED[LS] = FINAL_STATE_FRACTION


def _zero_episode(env_id: str, seed: int = 3):
    env = gym.make(env_id, **SHORT[env_id])
    infos, _, terminated = play(env, ZeroPolicy(env), seed=seed)
    return env, infos[0], infos[-1], terminated


def test_every_registered_env_declares_its_metric_and_trace_kind():
    assert set(DECLARED) == set(attitude_envs.ENV_IDS)
    for env_id, metric in DECLARED.items():
        cls = type(gym.make(env_id).unwrapped)
        assert cls.success_metric is metric, env_id
        assert "**Success**" in cls.__doc__ and metric.name.upper() in cls.__doc__, env_id
        assert cls.wheel_trace == (env_id in (RW, AB)), env_id


def test_the_two_metrics_state_name_unit_threshold_and_criterion():
    assert (FINAL_ERROR_DEG.name, FINAL_ERROR_DEG.unit, FINAL_ERROR_DEG.threshold) == ("final_error_deg", "deg", 2.0)
    assert FINAL_ERROR_DEG.describe() == "final attitude error ≤ 2°"
    assert FINAL_ERROR_DEG.describe(0.5) == "final attitude error ≤ 0.5°"
    assert (FINAL_STATE_FRACTION.name, FINAL_STATE_FRACTION.threshold) == ("final_state_fraction", 0.1)
    assert FINAL_STATE_FRACTION.describe(0.25) == "final state norm ≤ 0.25 × the initial state norm (true state)"
    with pytest.raises(AttributeError):
        FINAL_ERROR_DEG.threshold = 3.0  # frozen: an env's declaration cannot be changed under it


@pytest.mark.parametrize("env_id", [RW, AB, MT])
def test_attitude_envs_judge_the_final_error_angle(env_id):
    env, first, last, _ = _zero_episode(env_id)
    metric: SuccessMetric = env.unwrapped.success_metric
    value = metric.value(first, last)
    assert value == last["truth"]["error_angle_deg"]
    assert metric.measurements(first, last) == {"final_error_deg": value}
    assert metric.succeeded(first, last, value) and not metric.succeeded(first, last, value * (1 - 1e-9))
    assert metric.succeeded(first, last) == (value <= 2.0)
    if env_id == RW:  # no torque from rest: the spacecraft keeps its attitude, far from the target
        assert value == first["truth"]["error_angle_deg"] and value > 2.0
        assert not metric.succeeded(first, last)
    else:
        assert value != first["truth"]["error_angle_deg"]


def test_lqr_on_the_reaction_wheel_env_succeeds():
    from baselines.lqr import LQRPolicy

    env = gym.make(RW)
    infos, _, terminated = play(env, LQRPolicy(env), seed=3)
    metric = env.unwrapped.success_metric
    value = metric.value(infos[0], infos[-1])
    assert not terminated and value < 2.0 < infos[0]["truth"]["error_angle_deg"]
    assert metric.succeeded(infos[0], infos[-1]) and not metric.succeeded(infos[0], infos[-1], value / 2)


def test_linear_system_judges_the_state_norm_against_the_start():
    env, first, last, _ = _zero_episode(LS)
    x0 = np.asarray(first["truth"]["state"])
    expected = np.linalg.norm(np.linalg.matrix_power(env.unwrapped.model.A, 30) @ x0) / np.linalg.norm(x0)
    metric = env.unwrapped.success_metric
    assert metric.value(first, last) == pytest.approx(expected, rel=1e-12) and expected > 0.1
    assert not metric.succeeded(first, last)  # free drift keeps most of the state
    assert metric.succeeded(first, last, expected * (1 + 1e-9))
    norms = metric.measurements(first, last)
    assert list(norms) == ["initial_state_norm", "final_state_norm"]
    assert norms["initial_state_norm"] == np.linalg.norm(x0)


def test_lqr_on_the_linear_system_succeeds():
    from baselines.linear_lqr import LinearLQRPolicy

    env = gym.make(LS, episode_steps=20000)
    infos, _, terminated = play(env, LinearLQRPolicy(env), seed=0)
    metric = env.unwrapped.success_metric
    assert not terminated and metric.value(infos[0], infos[-1]) < 0.1 and metric.succeeded(infos[0], infos[-1])


def test_fuel_slosh_judges_the_reduced_state_x_not_the_state_dict():
    env, first, last, _ = _zero_episode(FS)
    metric = env.unwrapped.success_metric
    expected = np.linalg.norm(last["truth"]["x"]) / np.linalg.norm(first["truth"]["x"])
    assert metric.value(first, last) == expected
    assert metric.succeeded(first, last) == (expected <= 0.1)
    assert metric.succeeded(first, last, expected) and not metric.succeeded(first, last, expected * (1 - 1e-9))


def test_a_relative_metric_from_a_zero_start():
    metric = FINAL_STATE_FRACTION
    zero = {"truth": {"state": np.zeros(3)}}
    one = {"truth": {"state": np.ones(3)}}
    assert metric.value(zero, zero) == 0.0 and metric.succeeded(zero, zero)
    assert metric.value(zero, one) == math.inf and not metric.succeeded(zero, one)


def test_realized_fault_onsets_are_public_and_include_drawn_ones():
    faults = [
        {"kind": "outage", "target": "actuator", "index": "random", "onset_s": {"uniform": [1.0, 5.0]}},
        {"kind": "loss_of_effectiveness", "target": "actuator", "index": "all", "value": 0.5, "onset_s": 7},
    ]
    env = gym.make(RW, faults=faults)
    _, info = env.reset(seed=1)
    onsets = fault_onsets_s(info)
    assert len(onsets) == 1 + 4 and onsets[1:] == [7.0] * 4  # index all: one fault per wheel
    assert 1.0 <= onsets[0] <= 5.0 and onsets[0] == info["truth"]["faults"][0]["onset_s"]
    _, again = env.reset(seed=1)
    _, other = env.reset(seed=2)
    assert fault_onsets_s(again) == onsets and fault_onsets_s(other)[0] != onsets[0]
    assert fault_onsets_s(gym.make(RW).reset(seed=0)[1]) == []
