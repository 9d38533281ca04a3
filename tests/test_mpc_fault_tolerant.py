"""Fault-tolerant MPC (baselines.mpc_fault_tolerant): its degraded actuator model is the env's
step under the same fault, it commands nothing to a wheel the FDI isolated as out, and it is
the nominal MPC (bitwise) while no fault is detected."""

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

from attitude_envs.info import TRUTH, policy_view  # noqa: E402
from attitude_envs.symbolic.gyrostat import GyrostatParameters, step_function, with_effectiveness  # noqa: E402
from baselines.mpc import MPCPolicy, model_parameters  # noqa: E402
from baselines.mpc_fault_tolerant import FaultTolerantMPCPolicy, degraded_terminal_weight  # noqa: E402

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"


def _faults(eff: list[float]) -> list[dict]:
    """Env faults from t = 0 that make wheel i deliver eff[i] of its command."""
    out = []
    for i, e in enumerate(eff):
        if e == 0.0:
            out.append({"kind": "outage", "target": "actuator", "index": i, "onset_s": 0.0})
        elif e < 1.0:
            out.append(
                {"kind": "loss_of_effectiveness", "target": "actuator", "index": i, "value": 1.0 - e, "onset_s": 0.0}
            )
    return out


@pytest.mark.parametrize(
    ("env_id", "kwargs", "eff"),
    [
        (RW, {}, [0.0, 0.5, 1.0, 1.0]),
        (RW, {"action_frame": "body"}, [0.0, 0.0, 1.0, 1.0]),
        (AB, {}, [1.0, 1.0, 0.0]),
        (AB, {"action_frame": "body"}, [0.5, 1.0, 0.0]),
    ],
)
def test_the_degraded_model_is_the_envs_step_under_the_fault(env_id, kwargs, eff):
    # the MPC's degraded prediction model (nominal parameters + assumed effectiveness, smooth)
    # against the env's compiled step with the same outage / loss of effectiveness as faults
    env = gym.make(env_id, episode_duration_s=1.5 if env_id == RW else 0.3, faults=_faults(eff), **kwargs)
    base = env.unwrapped
    step = step_function(with_effectiveness(model_parameters(env), eff), smooth=True)
    env.reset(seed=2)
    rng = np.random.default_rng(1)
    y, target = np.array(base.state_row), np.array(base.target_attitude)
    worst = 0.0
    while True:
        a = rng.uniform(-0.3, 0.3, env.action_space.shape).astype(np.float32)  # no clip, no limiter
        y_next, cost = step(y, a.astype(float), 0.0, target)
        _, _, terminated, truncated, info = env.step(a)
        y = np.array(base.state_row)
        worst = max(worst, float(np.max(np.abs(np.asarray(y_next).ravel() - y))))
        assert float(cost) == pytest.approx(info["cost"], rel=1e-9, abs=1e-12)
        assert not terminated
        if truncated:
            break
    assert worst <= 1e-9


@pytest.mark.parametrize("smooth", [False, True])
def test_all_ones_effectiveness_is_bit_identical(smooth):
    env = gym.make(RW, action_frame="body")
    params = model_parameters(env)
    plain = step_function(params, smooth=smooth)
    ones = step_function(with_effectiveness(params, np.ones(4)), smooth=smooth)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    y, target = np.array(env.unwrapped.state_row), np.array(env.unwrapped.target_attitude)
    y[4:] = rng.normal(0.0, 0.1, y.size - 4)
    for _ in range(5):
        a = rng.uniform(-1.2, 1.2, 3)
        y1, c1 = plain(y, a, 0.0, target)
        y2, c2 = ones(y, a, 0.0, target)
        assert np.array_equal(np.asarray(y1), np.asarray(y2)) and float(c1) == float(c2)
        y = np.asarray(y1).ravel()


def test_degraded_terminal_weight():
    env = gym.make(RW, action_frame="body", preset="pyramid-4wheel")
    mpc = MPCPolicy(env, horizon_steps=2)
    model = env.unwrapped.model
    # healthy: the Riccati solution of the nominal design, whatever the input basis
    p_ones, basis = degraded_terminal_weight(model, np.ones(4), model.control_dt_s)
    assert basis.shape == (6, 6)
    np.testing.assert_allclose(p_ones, mpc.terminal_weight, rtol=1e-8, atol=1e-8 * np.abs(mpc.terminal_weight).max())
    # two pyramid wheels out: one body axis (rate and attitude) is lost
    p_two, basis = degraded_terminal_weight(model, [0.0, 0.0, 1.0, 1.0], model.control_dt_s, mpc.terminal_weight)
    assert basis.shape == (6, 4)
    assert np.min(np.linalg.eigvalsh(p_two)) > 0.0  # the nominal weight on the lost axis
    p_zero, _ = degraded_terminal_weight(model, [0.0, 0.0, 1.0, 1.0], model.control_dt_s)
    assert np.linalg.matrix_rank(p_zero, tol=1e-9 * np.abs(p_zero).max()) == 4
    with pytest.raises(ValueError, match="effectiveness must be 4 values in"):
        degraded_terminal_weight(model, [1.0, 2.0, 1.0, 1.0], model.control_dt_s)


def _play(env, policy, seed: int, steps: int) -> tuple[list[np.ndarray], list[dict]]:
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    actions, infos = [], []
    for _ in range(steps):
        view = policy_view(info)
        assert TRUTH not in view
        a = policy.act(obs, view)
        actions.append(a)
        obs, _, terminated, truncated, info = env.step(a)
        infos.append(info)
        if terminated or truncated:
            break
    return actions, infos


def test_ft_mpc_commands_nothing_to_a_wheel_it_isolated_as_out():
    env = gym.make(
        RW, episode_duration_s=2.0, faults=[{"kind": "outage", "target": "actuator", "index": 0, "onset_s": 0.5}]
    )
    ft = FaultTolerantMPCPolicy(env, horizon_steps=5)
    actions, _ = _play(env, ft, seed=3, steps=20)
    assert [d["index"] for d in ft.isolated] == [0]
    det = ft.isolated[0]
    assert 0.5 < det["time_s"] <= 1.0 and det["effectiveness"] == 0.0  # detection delay <= 0.5 s
    k = int(round(det["time_s"] / env.unwrapped.control_dt_s))  # the first action after the detection
    assert any(a[0] != 0.0 for a in actions[:k])
    for a in actions[k:]:
        assert a[0] == 0.0 and np.any(a[1:] != 0.0)
    np.testing.assert_array_equal(ft.effectiveness, [0.0, 1.0, 1.0, 1.0])
    assert ft.failures == 0 and len(ft.reconfigure_times_s) == 1


def test_ft_mpc_is_the_nominal_mpc_without_a_fault():
    env = gym.make(RW, action_frame="body", episode_duration_s=1.0)
    nominal, _ = _play(env, MPCPolicy(env, horizon_steps=5), seed=0, steps=10)
    ft = FaultTolerantMPCPolicy(env, horizon_steps=5)
    tolerant, _ = _play(env, ft, seed=0, steps=10)
    assert ft.isolated == [] and len(nominal) == len(tolerant) == 10
    for a, b in zip(nominal, tolerant, strict=True):
        assert np.array_equal(a, b)


def test_bad_parameters_raise():
    env = gym.make(RW)
    with pytest.raises(ValueError, match="uncontrollable_weight must be one of"):
        FaultTolerantMPCPolicy(env, uncontrollable_weight="big")
    with pytest.raises(ValueError, match="coarse_steps must be an integer >= 0"):
        FaultTolerantMPCPolicy(env, coarse_steps=-1)
    with pytest.raises(ValueError, match="effectiveness must be 4 values in"):
        with_effectiveness(GyrostatParameters.nominal(env.unwrapped.model, 1, 0.1), [1.0, 1.0, 1.0])


def test_the_coarser_prediction_model_survives_a_reconfiguration():
    # model_substeps reaches the fault-tolerant MPC's nominal model and every degraded one it
    # builds after an isolation (the air-bearing campaign runs it at 2 sub-steps per 0.5 s)
    env = gym.make(AB, control_dt_s=0.5, episode_duration_s=2.0)
    policy = FaultTolerantMPCPolicy(env, horizon_steps=2, model_substeps=2, coarse_steps=1)
    env.reset(seed=0)
    policy.reset(0)
    for params in (policy.model_parameters,):
        assert params.n_substeps == 2 and params.integrator_dt_s == pytest.approx(0.25, rel=1e-15)
    policy._reconfigure((1.0, 1.0, 0.0))
    degraded = policy.model_parameters
    assert degraded.n_substeps == 2 and degraded.integrator_dt_s == pytest.approx(0.25, rel=1e-15)
    assert policy.horizon_steps == 3  # the coarse stage appended
    policy.reset(0)  # back to the nominal configuration, still coarse
    assert policy.model_parameters.n_substeps == 2
