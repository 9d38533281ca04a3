"""The feedback-linearization paper's baselines: gains from the paper's weights, exact linearization, singularity guard."""

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import attitude_envs  # noqa: F401
from attitude_envs import quaternion
from attitude_envs.evaluation import record_episode
from attitude_envs.plants import gyrostat
from baselines.feedback_linearization import (
    FeedbackLinearizationPolicy,
    SingularControlError,
    outer_loop_gain,
    q_double_prime,
)
from baselines.measured import MeasuredState
from baselines.quaternion_lqr import QuaternionLQRPolicy, quaternion_lqr_gains

M1 = quaternion.from_euler_321_deg(20.0, -30.0, -40.0)


def make_env(**kw):
    base = dict(
        control_dt_s=0.01, max_wheel_speed_rad_s=np.inf, max_wheel_torque_nm=1.0, initial_attitude=[0, 0, 0, 1.0]
    )
    base.update(kw)
    return gym.make("attitude_envs/ReactionWheel-v0", **base)


def test_outer_loop_gains_match_paper_and_closed_form():
    K = outer_loop_gain()
    k1, k2 = K[0, 0], K[0, 3]
    assert round(k1, 4) == 0.0316 and round(k2, 4) == 0.2535  # the paper's eqs. 81-82
    assert k1 == pytest.approx(np.sqrt(0.001), rel=1e-10)
    assert k2 == pytest.approx(np.sqrt(0.001 + 2 * np.sqrt(0.001)), rel=1e-10)
    assert np.allclose(K, np.hstack([k1 * np.eye(3), k2 * np.eye(3)]), atol=1e-12)


def test_quaternion_lqr_gains_match_paper_to_4_decimals():
    kq, kw = quaternion_lqr_gains(np.diag([4.0, 4.0, 3.0]))
    assert np.array_equal(np.round(np.diag(kq), 4), [0.2608] * 3)  # eq. 77
    assert np.array_equal(np.round(np.diag(kw), 4), [2.5091, 2.5091, 2.4566])  # eq. 78
    assert np.allclose(kq - np.diag(np.diag(kq)), 0, atol=1e-12)


def _sig4(values):
    return [float(f"{v:.4g}") for v in values]


def test_policy_gains_from_nominal_model_match_paper_to_4_digits():
    """The policy designs on I_eff = I − J_s A Aᵀ (5th-digit change): equal to 4 significant digits."""
    pol = QuaternionLQRPolicy(make_env())
    assert _sig4(np.diag(pol.attitude_gain)) == _sig4([0.2608] * 3)
    assert _sig4(np.diag(pol.rate_gain)) == _sig4([2.5091, 2.5091, 2.4566])
    flc = FeedbackLinearizationPolicy(make_env())
    assert (round(flc.k1, 4), round(flc.k2, 4)) == (0.0316, 0.2535)


def test_gain_functions_reject_bad_weights():
    with pytest.raises(ValueError, match="R"):
        quaternion_lqr_gains(np.diag([4.0, 4.0, 3.0]), R=-np.eye(3))
    with pytest.raises(ValueError, match="Q"):
        outer_loop_gain(Q=np.ones((5, 5)))


def _output_acceleration(params, q, w, wheel, u):
    """ÿ = d/dt(½ Q''(q) ω) of the exact gyrostat under motor torques u."""
    dy = gyrostat.derivative(params, np.concatenate([q, w, wheel]), u, np.zeros(3))
    return 0.5 * q_double_prime(dy[:4]) @ w + 0.5 * q_double_prime(q) @ dy[4:7]


def test_flc_makes_output_acceleration_equal_v_exactly():
    env = make_env()
    pol = FeedbackLinearizationPolicy(env)
    params = env.unwrapped.model.params
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = quaternion.random_within_angle(rng, 80.0)
        w = rng.normal(scale=0.05, size=3)
        wheel = rng.normal(scale=300.0, size=4)  # spinning wheels: gyroscopic coupling matters
        state = MeasuredState(q, w, wheel, M1)
        u = pol.allocator.matrix @ pol.body_torque_nm(state)
        qv_dot = 0.5 * q_double_prime(q) @ w
        v = -pol.gain @ np.concatenate([q[:3] - M1[:3], qv_dot])
        assert np.allclose(_output_acceleration(params, q, w, wheel, u), v, rtol=0, atol=1e-12)


def test_flc_closed_loop_tracks_designed_double_integrator():
    """Continuous-time control on the exact nominal gyrostat: q_vec(t) = (1 − φ(t)) q_T,vec (the designed double integrator)."""
    env = make_env()
    pol = FeedbackLinearizationPolicy(env)
    params = env.unwrapped.model.params
    k1, k2 = pol.k1, pol.k2

    def closed_loop(t, y):
        q = y[:4] / np.linalg.norm(y[:4])
        u = pol.allocator.matrix @ pol.body_torque_nm(MeasuredState(q, y[4:7], y[7:11], M1))
        return np.concatenate([gyrostat.derivative(params, y[:11], u, np.zeros(3)), [y[12], -k1 * y[11] - k2 * y[12]]])

    y0 = np.zeros(13)
    y0[3] = 1.0
    y0[11] = 1.0  # φ(0) = 1, φ̇(0) = 0
    sol = solve_ivp(closed_loop, (0.0, 60.0), y0, rtol=1e-11, atol=1e-13, t_eval=np.linspace(0, 60, 121))
    assert sol.success
    designed = (1.0 - sol.y[11])[:, None] * M1[:3]
    assert np.max(np.abs(sol.y[:3].T - designed)) < 1e-6
    # the wheels really spin up (the gyroscopic terms were exercised): > 2000 rpm
    assert np.max(np.abs(sol.y[7:11])) * 60 / (2 * np.pi) > 2000


def test_flc_in_env_tracks_design_up_to_the_zero_order_hold():
    """Sampled at the control period the only deviation is the torque hold: O(dt)."""
    errors = []
    for dt in (0.01, 0.005):
        env = make_env(control_dt_s=dt, integrator_dt_s=dt, episode_duration_s=10.0)
        pol = FeedbackLinearizationPolicy(env)
        trace = record_episode(env, pol, 0, {"target_attitude": M1})
        phi = solve_ivp(
            lambda t, y, k1=pol.k1, k2=pol.k2: [y[1], -k1 * y[0] - k2 * y[1]],
            (0, trace.time_s[-1]),
            [1.0, 0.0],
            t_eval=trace.time_s,
            rtol=1e-12,
            atol=1e-14,
        ).y[0]
        errors.append(np.max(np.abs(trace.attitude[:, :3] - (1 - phi)[:, None] * M1[:3])))
    assert errors[0] < 2e-4
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)


def test_flc_singularity_guard():
    env = make_env()
    q = quaternion.from_axis_angle([1.0, 0.0, 0.0], np.radians(178.0))  # q4 = cos(89°) ≈ 0.017
    state = MeasuredState(q, np.zeros(3), np.zeros(4), M1)
    pol = FeedbackLinearizationPolicy(env)
    fallback = QuaternionLQRPolicy(env)
    assert np.allclose(pol.body_torque_nm(state), fallback.body_torque_nm(state))
    assert pol.singular_steps == 1
    pol.reset(0)
    assert pol.singular_steps == 0
    with pytest.raises(SingularControlError, match="q4"):
        FeedbackLinearizationPolicy(env, on_singular="raise").body_torque_nm(state)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [({"q4_min": 0.0}, "q4_min"), ({"output": "euler"}, "output"), ({"on_singular": "ignore"}, "on_singular")],
)
def test_flc_rejects_bad_parameters(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FeedbackLinearizationPolicy(make_env(), **kwargs)


def test_flc_error_output_mode_converges_from_any_start():
    env = make_env(episode_duration_s=60.0)
    pol = FeedbackLinearizationPolicy(env, output="error")
    start = quaternion.from_axis_angle([0.3, -1.0, 0.5], np.radians(120.0))
    trace = record_episode(env, pol, 0, {"attitude": start, "target_attitude": M1})
    assert trace.error_angle_deg[0] > 100.0
    assert trace.error_angle_deg[-1] < 0.5
    assert pol.singular_steps == 0


def test_quaternion_lqr_is_the_paper_law_in_paper_convention():
    """T = 2K q_E,vec q_E4 − K_d ω with q_E = q_S* ⊗ q_T (the paper's eqs. 60-61)."""
    pol = QuaternionLQRPolicy(make_env())
    rng = np.random.default_rng(0)
    for _ in range(10):
        q_s = quaternion.random_within_angle(rng, 90.0)
        w = rng.normal(scale=0.02, size=3)
        q_e_paper = quaternion.multiply(quaternion.conjugate(q_s), M1)
        q_e_paper = q_e_paper if q_e_paper[3] >= 0 else -q_e_paper
        expected = 2 * pol.attitude_gain @ q_e_paper[:3] * q_e_paper[3] - pol.rate_gain @ w
        assert np.allclose(pol.body_torque_nm(MeasuredState(q_s, w, np.zeros(4), M1)), expected, atol=1e-14)
    consistent = QuaternionLQRPolicy(make_env(), stiffness="consistent")
    state = MeasuredState(quaternion.from_axis_angle([0, 0, 1.0], 0.1), np.zeros(3), np.zeros(4), [0, 0, 0, 1.0])
    assert np.allclose(consistent.body_torque_nm(state), 0.5 * pol.body_torque_nm(state))
