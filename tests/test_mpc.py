"""Nonlinear MPC on the nominal gyrostat: its model step (the shared symbolic gyrostat of
:mod:`attitude_envs.symbolic.gyrostat`) is the env's, it stabilizes, its cost is the LQR's or
better, and it reads only the measured state."""

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

from attitude_envs import quaternion  # noqa: E402
from attitude_envs.info import TRUTH, policy_view  # noqa: E402
from attitude_envs.symbolic.gyrostat import GyrostatParameters  # noqa: E402
from baselines.lqr import LQRPolicy  # noqa: E402
from baselines.mpc import MPCPolicy, model_parameters, model_step  # noqa: E402

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"


def episode(env, policy, seed: int, options: dict | None = None) -> tuple[float, dict]:
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    total = 0.0
    while True:
        view = policy_view(info)
        assert TRUTH not in view
        obs, _, terminated, truncated, info = env.step(policy.act(obs, view))
        total += info["cost"]
        if terminated or truncated:
            return total, info


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        (RW, {}),
        (RW, {"action_frame": "body"}),
        (RW, {"preset": "heravi-2017", "action_frame": "body", "episode_duration_s": 1.0}),
        (RW, {"wheel_momentum_weight": 1.0, "cost_input": "wheel", "R": np.eye(4), "integrator_dt_s": 0.025}),
        (AB, {}),
        (AB, {"action_frame": "body"}),
    ],
)
def test_the_mpcs_model_is_the_envs_step(env_id, kwargs):
    # the MPC's prediction model (the shared symbolic gyrostat on the nominal parameters)
    # against the env's compiled step, one step at a time over a whole short episode of a
    # plant whose truth is its nominal model (no drawn inertia, offset, faults or disturbance)
    env = gym.make(env_id, **{"episode_duration_s": 3.0 if env_id == RW else 1.0, **kwargs})
    base = env.unwrapped
    step = model_step(env)
    env.reset(seed=1)
    params, truth = model_parameters(env), GyrostatParameters.true_plant(base)
    for name in ("inertia_kg_m2", "inertia_eff_inv", "offset_torque_nm"):
        np.testing.assert_array_equal(getattr(params, name), getattr(truth, name))
    assert truth.faults == () and truth.external_torque is None
    rng = np.random.default_rng(0)
    y, target = np.array(base.state_row), np.array(base.target_attitude)
    steps, max_wheel_speed = 0, 0.0
    while True:
        a = rng.uniform(-0.3, 0.3, env.action_space.shape).astype(np.float32)  # no wheel at its limit
        y_next, cost = step(y, a.astype(float), 0.0, target)
        _, _, terminated, truncated, info = env.step(a)
        y = np.array(base.state_row)
        np.testing.assert_allclose(np.asarray(y_next).ravel(), y, rtol=1e-12, atol=1e-15)
        assert float(cost) == pytest.approx(info["cost"], rel=1e-12)
        steps += 1
        max_wheel_speed = max(max_wheel_speed, np.max(np.abs(y[7:])))
        assert not terminated
        if truncated:
            break
    assert steps == int(round(base.episode_duration_s / base.control_dt_s))
    assert max_wheel_speed < base.model.params.max_wheel_speed_rad_s  # the env's speed limiter never acted


def test_mpc_stabilizes_a_5_degree_slew_at_the_lqrs_cost():
    # the preset's weights (Q, R of the feedback-linearization paper) make a slow response:
    # the LQR takes a 5 deg error to 1.8 deg in 20 s, a 30 deg one to 11 deg
    env = gym.make(RW, episode_duration_s=20.0)
    target = quaternion.from_axis_angle(np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0), np.radians(5.0))
    options = {"target_attitude": target}
    mpc = MPCPolicy(env, horizon_steps=10)
    j_mpc, info = episode(env, mpc, seed=0, options=options)
    j_lqr, info_lqr = episode(env, LQRPolicy(env), seed=0, options=options)
    assert info["truth"]["error_angle_deg"] < 2.5
    assert info["truth"]["error_angle_deg"] <= info_lqr["truth"]["error_angle_deg"] + 0.2
    assert j_mpc <= 1.05 * j_lqr  # the same model, a receding horizon with the LQR's cost-to-go at its end
    assert len(mpc.solve_times_s) == 200 and mpc.failures == 0


def test_mpc_on_the_air_bearing_and_in_the_body_frame():
    for env in (gym.make(AB, episode_duration_s=0.5), gym.make(RW, episode_duration_s=3.0, action_frame="body")):
        mpc = MPCPolicy(env, horizon_steps=8)
        j_mpc, _ = episode(env, mpc, seed=0)
        j_lqr, _ = episode(env, LQRPolicy(env), seed=0)
        assert j_mpc <= 1.05 * j_lqr
        assert mpc.failures == 0


def test_mpc_respects_the_torque_limit_it_plans_with():
    env = gym.make(RW, episode_duration_s=1.0, target_angle_deg=150.0, max_wheel_torque_nm=0.01, action_frame="body")
    mpc = MPCPolicy(env, horizon_steps=5)
    obs, info = env.reset(seed=0)
    mpc.reset(0)
    for _ in range(3):
        a = mpc.act(obs, policy_view(info))
        assert np.all(np.abs(a) <= 1.0)
        assert np.all(np.abs(env.unwrapped.model.allocation @ a) <= 1.0 + 1e-6)  # no wheel clipped by the env
        obs, _, _, _, info = env.step(a)


def test_bad_parameters_raise():
    with pytest.raises(ValueError, match="horizon_steps must be an integer >= 1"):
        MPCPolicy(gym.make(RW), horizon_steps=0)
    with pytest.raises(ValueError, match="ReactionWheel-v0 or AirBearing-v0"):
        MPCPolicy(gym.make("attitude_envs/LinearSystem-v0"))


def test_a_coarser_prediction_model_keeps_the_period_and_converges_at_rk4s_order():
    # model_substeps trades the prediction model's accuracy for a smaller NLP (AirBearing-v0
    # decides every 0.5 s over 50 sub-steps of 0.01 s); the period is kept, and one step's error
    # against the env's own 50 sub-steps falls as h⁴ (RK4) from 5 to 10 sub-steps
    env = gym.make(AB, control_dt_s=0.5, episode_duration_s=2.0)
    env.reset(seed=1)
    base = env.unwrapped
    exact = MPCPolicy(env, horizon_steps=1)
    assert exact.model_parameters.n_substeps == 50
    y = np.array(base.state_row)
    y[4:7] = [0.05, -0.04, 0.03]  # rad/s: a spinning, tilted platform
    target = np.array(base.target_attitude)
    a = np.array([0.3, -0.2, 0.1])
    y_ref, c_ref = (np.asarray(v).ravel() for v in exact.model_step(y, a, 0.0, target))
    errors = []
    for k in (5, 10):
        coarse = MPCPolicy(env, horizon_steps=1, model_substeps=k)
        p = coarse.model_parameters
        assert p.n_substeps == k and p.n_substeps * p.integrator_dt_s == pytest.approx(0.5, rel=1e-15)
        y_k, c_k = (np.asarray(v).ravel() for v in coarse.model_step(y, a, 0.0, target))
        errors.append(np.max(np.abs(y_k - y_ref)))
        assert abs(c_k[0] - c_ref[0]) <= 1e-6 * abs(c_ref[0])
    assert 0.0 < errors[1] < errors[0]
    assert 2.0**3.5 < errors[0] / errors[1] < 2.0**4.5  # order 4
    for bad in (0, 2.5, "5"):
        with pytest.raises(ValueError, match="model_substeps"):
            MPCPolicy(env, model_substeps=bad)
