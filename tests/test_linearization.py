"""The nominal model's linearization and exact discretization, checked numerically."""

import gymnasium as gym
import numpy as np
import pytest
from conftest import asymmetric_inertia
from scipy.integrate import quad_vec, solve_ivp

from attitude_envs.linearization import LinearModel, complex_step_jacobian, zoh, zoh_cost


def model_of(**kwargs):
    return gym.make("attitude_envs/ReactionWheel-v0", **kwargs).unwrapped.model


def finite_difference_jacobians(model, wheel, eps=1e-6):
    n, m = model.n_state, model.params.n_wheels
    x0, u0 = np.zeros(n), np.zeros(m)
    if model.include_wheel_momentum:
        x0[6:] = model.params.wheel_inertia_kg_m2 * wheel

    def f(x, u):
        return model.error_derivative(x, u, None if model.include_wheel_momentum else wheel)

    A = np.column_stack([(f(x0 + eps * e, u0) - f(x0 - eps * e, u0)) / (2 * eps) for e in np.eye(n)])
    B = np.column_stack([(f(x0, u0 + eps * e) - f(x0, u0 - eps * e)) / (2 * eps) for e in np.eye(m)])
    return A, B


@pytest.mark.parametrize("wheel_speed", [np.zeros(4), np.array([300.0, -150.0, 80.0, 20.0])])
@pytest.mark.parametrize("momentum", [False, True])
def test_linearization_matches_finite_differences(wheel_speed, momentum):
    model = model_of(
        inertia_kg_m2=asymmetric_inertia(), cost_input="wheel", R=np.eye(4), wheel_momentum_weight=float(momentum)
    )
    lin = model.linearize(wheel_speed_rad_s=wheel_speed, input="wheel")
    A_fd, B_fd = finite_difference_jacobians(model, wheel_speed)
    assert np.allclose(lin.A, A_fd, rtol=1e-6, atol=1e-8)
    assert np.allclose(lin.B, B_fd, rtol=1e-6, atol=1e-8)
    if np.any(wheel_speed):
        assert np.abs(lin.A[3:6, 3:6]).max() > 1e-3  # the gyroscopic coupling is really there


def test_body_input_linearization_is_the_allocated_wheel_one():
    model = model_of()
    body, wheel = model.linearize(input="body"), model.linearize(input="wheel")
    assert np.allclose(body.B, wheel.B @ model.allocation)
    # with the minimum-norm allocation the body receives exactly the demanded torque
    assert np.allclose(-model.params.wheel_axes @ model.allocation, np.eye(3))
    # small-wheel limit: B_ω ≈ I⁻¹ of the feedback-linearization paper (I_eff differs by J_s A Aᵀ = 6.7e-4 I)
    assert np.allclose(body.B[3:6], np.linalg.inv(np.diag([4.0, 4.0, 3.0])), rtol=3e-4)


def test_zoh_matches_integrating_the_linear_system(rng):
    A = rng.normal(size=(4, 4))
    B = rng.normal(size=(4, 2))
    x0, u = rng.normal(size=4), rng.normal(size=2)
    A_d, B_d = zoh(A, B, 0.3)
    sol = solve_ivp(lambda t, x: A @ x + B @ u, (0, 0.3), x0, rtol=1e-12, atol=1e-14)
    assert np.allclose(A_d @ x0 + B_d @ u, sol.y[:, -1], rtol=1e-9, atol=1e-12)


def test_zoh_cost_matches_quadrature(rng):
    A = rng.normal(size=(3, 3))
    B = rng.normal(size=(3, 2))
    Q = np.diag([1.0, 2.0, 3.0])
    R = np.array([[2.0, 0.3], [0.3, 1.0]])
    x0, u = rng.normal(size=3), rng.normal(size=2)
    Q_d, R_d, N_d = zoh_cost(A, B, Q, R, 0.4)

    def integrand(t):
        x = zoh(A, B, t)[0] @ x0 + zoh(A, B, t)[1] @ u if t > 0 else x0
        return np.array([x @ Q @ x + u @ R @ u])

    ref = quad_vec(integrand, 0.0, 0.4, epsabs=1e-13, epsrel=1e-12)[0][0]
    assert x0 @ Q_d @ x0 + 2 * x0 @ N_d @ u + u @ R_d @ u == pytest.approx(ref, rel=1e-9)


def test_env_step_matches_discrete_model_near_the_target():
    env = gym.make("attitude_envs/ReactionWheel-v0", control_dt_s=0.1).unwrapped
    disc = env.model.discrete()
    assert disc.dt_s == 0.1
    eps = 1e-5
    x0 = eps * np.array([0.3, -0.5, 0.2, 0.4, 0.1, -0.2])
    qe = np.concatenate([x0[:3], [np.sqrt(1 - x0[:3] @ x0[:3])]])
    u_body = 1e-3 * np.array([0.2, -0.1, 0.3])
    action = env.model.allocation @ u_body / env.model.params.max_wheel_torque_nm
    env.reset(seed=0, options={"attitude": qe, "rate_rad_s": x0[3:], "target_attitude": [0, 0, 0, 1.0]})
    obs, reward, _, _, info = env.step(action)
    u = -env.model.params.wheel_axes @ info["truth"]["applied"]
    x_pred = disc.A @ x0 + disc.B @ u
    assert np.allclose(env.error_state(), x_pred, rtol=0, atol=1e-4 * np.abs(x_pred).max())
    cost_pred = x0 @ disc.Q @ x0 + 2 * x0 @ disc.N @ u + u @ disc.R @ u
    assert info["cost"] == pytest.approx(cost_pred, rel=1e-4)
    assert reward == -info["cost"]


def test_lqr_gain_of_the_pyramid_preset_reproduces_the_papers_gains():
    model = model_of(wheel_inertia_kg_m2=1e-12)  # the paper designs with the small-wheel model
    K = model.linearize().lqr_gain()
    # the paper's eqs. 77-78 (gains on ω and q_v); here x is ordered (q_v, ω) and u = −K x
    assert np.allclose(np.diag(K[:, :3]), 0.2608, atol=5e-5)
    assert np.allclose(np.diag(K[:, 3:]), [2.5091, 2.5091, 2.4566], atol=5e-5)


def test_linear_model_rejects_double_discretization():
    lin = LinearModel(np.zeros((2, 2)), np.eye(2), np.eye(2), np.eye(2))
    with pytest.raises(ValueError, match="already discrete"):
        lin.discretize(0.1).discretize(0.1)


def test_complex_step_jacobian_is_exact_to_rounding():
    def f(z):  # analytic: sin, sqrt, products
        return np.array([np.sin(z[0]) * z[1], np.sqrt(1.0 + z[0] * z[0]) - z[2] / z[1]])

    x0 = np.array([0.7, -1.3, 2.1])
    expected = np.array(
        [
            [np.cos(x0[0]) * x0[1], np.sin(x0[0]), 0.0],
            [x0[0] / np.sqrt(1.0 + x0[0] ** 2), x0[2] / x0[1] ** 2, -1.0 / x0[1]],
        ]
    )
    assert np.allclose(complex_step_jacobian(f, x0), expected, rtol=1e-15, atol=1e-16)


@pytest.mark.parametrize("momentum", [False, True])
def test_linearization_has_the_closed_form_of_the_gyrostat(momentum):
    """The definition's Jacobians at rest against their closed form: q̇_e = ½ω, I_eff ω̇ =
    h₀ × ω − A u (h₀ = J_s A Ω), and ḣ_w = u − J_s Aᵀ ω̇ when the wheel momentum is in x."""
    model = model_of(
        inertia_kg_m2=asymmetric_inertia(), cost_input="wheel", R=np.eye(4), wheel_momentum_weight=float(momentum)
    )
    p = model.params
    wheel = np.array([300.0, -150.0, 80.0, 20.0])
    lin = model.linearize(wheel_speed_rad_s=wheel, input="wheel")
    h0 = p.wheel_inertia_kg_m2 * p.wheel_axes @ wheel
    skew = np.array([[0.0, -h0[2], h0[1]], [h0[2], 0.0, -h0[0]], [-h0[1], h0[0], 0.0]])
    A = np.zeros((model.n_state, model.n_state))
    B = np.zeros((model.n_state, 4))
    A[:3, 3:6] = 0.5 * np.eye(3)
    A[3:6, 3:6] = p.inertia_eff_inv @ skew
    B[3:6] = -p.inertia_eff_inv @ p.wheel_axes
    if momentum:
        A[6:, 3:6] = -p.wheel_inertia_kg_m2 * p.wheel_axes.T @ A[3:6, 3:6]
        B[6:] = np.eye(4) - p.wheel_inertia_kg_m2 * p.wheel_axes.T @ B[3:6]
    assert np.allclose(lin.A, A, rtol=1e-14, atol=1e-16)
    assert np.allclose(lin.B, B, rtol=1e-14, atol=1e-16)
