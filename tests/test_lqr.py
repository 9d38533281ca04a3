"""attitude_envs.lqr: closed-form scalar cases, Riccati residuals, closed-loop eigenvalues,
the cross term and the discount as transformed problems, optimality by finite differences
of the closed-loop cost, and the input checks."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from attitude_envs.lqr import dlqr, lqr


def random_problem(seed: int, n: int = 5, m: int = 2, radius: float = 1.3, cross: bool = True):
    """Random (A, B, Q, R, N): A with spectral radius ``radius`` (unstable in both time
    domains for radius > 1), Q and R positive definite, ``[[Q, N], [Nᵀ, R]] ≻ 0``."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A *= radius / np.max(np.abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n, m))
    L = rng.standard_normal((n + m, n + m))
    W = L @ L.T + 0.5 * np.eye(n + m)
    Q, R, N = W[:n, :n], W[n:, n:], W[:n, n:]
    return A, B, Q, R, (0.5 * N if cross else None)


def care_residual(A, B, Q, R, N, S):
    return A.T @ S + S @ A - (S @ B + N) @ np.linalg.solve(R, B.T @ S + N.T) + Q


def dare_residual(A, B, Q, R, N, S):
    return A.T @ S @ A - S - (A.T @ S @ B + N) @ np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A + N.T) + Q


def sorted_eigs(M):
    e = np.linalg.eigvals(M)
    return e[np.lexsort((e.imag, e.real))]


def closed_loop_cost(A, B, Q, R, N, K, discount=None):
    """``P_K`` with ``x₀ᵀP_Kx₀`` the cost of ``u = −Kx`` from ``x₀``: a Lyapunov equation
    (continuous when ``discount is None``), independent of the Riccati solvers."""
    W = Q - N @ K - K.T @ N.T + K.T @ R @ K
    Acl = A - B @ K
    if discount is None:
        return scipy.linalg.solve_continuous_lyapunov(Acl.T, -W)
    return scipy.linalg.solve_discrete_lyapunov(np.sqrt(discount) * Acl.T, W)


# ---------------------------------------------------------------- closed forms (scalar)


@pytest.mark.parametrize("a, b, q, r", [(-1.0, 1.0, 1.0, 1.0), (0.0, 2.0, 3.0, 0.5), (2.0, 0.5, 1.0, 4.0)])
def test_scalar_continuous_closed_form(a, b, q, r):
    K, S, E = lqr([[a]], [[b]], [[q]], [[r]])
    s = (a + np.sqrt(a**2 + b**2 * q / r)) * r / b**2
    assert S.shape == (1, 1) and K.shape == (1, 1) and E.shape == (1,)
    assert S[0, 0] == pytest.approx(s, rel=1e-12)
    assert K[0, 0] == pytest.approx(b * s / r, rel=1e-12)
    assert E[0] == pytest.approx(-np.sqrt(a**2 + b**2 * q / r), rel=1e-12)
    assert E.dtype == complex


def scalar_dare(a, b, q, r):
    """Positive root of b²s² + (r − qb² − a²r)s − qr = 0, the scalar DARE."""
    c = r - q * b**2 - a**2 * r
    return (-c + np.sqrt(c**2 + 4 * b**2 * q * r)) / (2 * b**2)


@pytest.mark.parametrize("a, b, q, r", [(0.5, 1.0, 1.0, 1.0), (1.0, 0.3, 2.0, 1.0), (1.8, 2.0, 0.1, 3.0)])
def test_scalar_discrete_closed_form(a, b, q, r):
    K, S, E = dlqr(a, b, q, r)  # scalars are 1×1
    s = scalar_dare(a, b, q, r)
    assert S[0, 0] == pytest.approx(s, rel=1e-12)
    assert K[0, 0] == pytest.approx(a * b * s / (r + b**2 * s), rel=1e-12)
    assert E[0] == pytest.approx(a * r / (r + b**2 * s), rel=1e-12)
    assert abs(E[0]) < 1.0


def test_scalar_discounted_closed_form():
    a, b, q, r, gamma = 1.5, 1.0, 1.0, 2.0, 0.8
    K, S, E = dlqr(a, b, q, r, discount=gamma)
    s = scalar_dare(np.sqrt(gamma) * a, np.sqrt(gamma) * b, q, r)
    assert S[0, 0] == pytest.approx(s, rel=1e-12)
    assert K[0, 0] == pytest.approx(gamma * a * b * s / (r + gamma * b**2 * s), rel=1e-12)
    assert E[0] == pytest.approx(a - b * K[0, 0], rel=1e-12)


# ---------------------------------------------------------------- random systems


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_continuous_riccati_residual_eigenvalues_and_gain(seed):
    A, B, Q, R, N = random_problem(seed)
    K, S, E = lqr(A, B, Q, R, N)
    assert np.linalg.norm(care_residual(A, B, Q, R, N, S)) <= 1e-10 * np.linalg.norm(S)
    np.testing.assert_array_equal(S, S.T)
    assert np.min(np.linalg.eigvalsh(S)) > 0
    np.testing.assert_allclose(K, np.linalg.solve(R, B.T @ S + N.T), rtol=1e-12, atol=0)
    np.testing.assert_allclose(sorted_eigs(A - B @ K), E[np.lexsort((E.imag, E.real))], rtol=1e-12, atol=1e-12)
    assert np.max(E.real) < 0 < np.max(np.linalg.eigvals(A).real)  # unstable plant, stable loop


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_discrete_riccati_residual_eigenvalues_and_gain(seed):
    A, B, Q, R, N = random_problem(seed)
    K, S, E = dlqr(A, B, Q, R, N)
    assert np.linalg.norm(dare_residual(A, B, Q, R, N, S)) <= 1e-10 * np.linalg.norm(S)
    assert np.min(np.linalg.eigvalsh(S)) > 0
    np.testing.assert_allclose(K, np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A + N.T), rtol=1e-12, atol=0)
    np.testing.assert_allclose(sorted_eigs(A - B @ K), E[np.lexsort((E.imag, E.real))], rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(E)) < 1 < np.max(np.abs(np.linalg.eigvals(A)))


@pytest.mark.parametrize("kind", ["continuous", "discrete", "discounted"])
def test_gain_is_optimal_by_finite_differences_of_the_closed_loop_cost(kind):
    """x₀ᵀSx₀ is the cost of u = −Kx (a Lyapunov equation, no Riccati solver), and every
    perturbation of K costs more, with a zero central-difference derivative."""
    A, B, Q, R, N = random_problem(3)
    discount = {"continuous": None, "discrete": 1.0, "discounted": 0.7}[kind]
    K, S, _ = lqr(A, B, Q, R, N) if discount is None else dlqr(A, B, Q, R, N, discount=discount)
    np.testing.assert_allclose(closed_loop_cost(A, B, Q, R, N, K, discount), S, rtol=1e-9, atol=1e-9)
    rng = np.random.default_rng(4)
    x0 = rng.standard_normal(A.shape[0])
    J = x0 @ S @ x0
    eps = 1e-4
    for _ in range(5):
        D = rng.standard_normal(K.shape)
        plus = x0 @ closed_loop_cost(A, B, Q, R, N, K + eps * D, discount) @ x0
        minus = x0 @ closed_loop_cost(A, B, Q, R, N, K - eps * D, discount) @ x0
        assert plus > J and minus > J
        assert abs(plus - minus) / (2 * eps) <= 1e-6 * J  # the gradient vanishes at the optimum
        assert (plus + minus - 2 * J) / eps**2 > 0  # and the curvature is positive


@pytest.mark.parametrize("solver", [lqr, dlqr])
def test_cross_term_is_the_transformed_problem(solver):
    """u = v − R⁻¹Nᵀx removes the cross term: (A − BR⁻¹Nᵀ, B, Q − NR⁻¹Nᵀ, R) has the same S
    and the gain K − R⁻¹Nᵀ."""
    A, B, Q, R, N = random_problem(5)
    K, S, E = solver(A, B, Q, R, N)
    F = np.linalg.solve(R, N.T)
    K0, S0, E0 = solver(A - B @ F, B, Q - N @ F, R)
    np.testing.assert_allclose(S, S0, rtol=1e-9)
    np.testing.assert_allclose(K, K0 + F, rtol=1e-9)
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(E0), rtol=1e-9)


def test_discount_is_the_dare_of_the_scaled_system():
    A, B, Q, R, N = random_problem(6, radius=1.1)
    gamma = 0.6
    K, S, E = dlqr(A, B, Q, R, N, discount=gamma)
    Ks, Ss, Es = dlqr(np.sqrt(gamma) * A, np.sqrt(gamma) * B, Q, R, N)
    np.testing.assert_allclose(S, Ss, rtol=1e-12)
    np.testing.assert_allclose(K, Ks, rtol=1e-12)
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(Es / np.sqrt(gamma)), rtol=1e-10)
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(np.linalg.eigvals(A - B @ K)), rtol=1e-12)
    # and the discounted residual: S = Q + γAᵀSA − (γAᵀSB + N)(R + γBᵀSB)⁻¹(γBᵀSA + Nᵀ)
    res = dare_residual(np.sqrt(gamma) * A, np.sqrt(gamma) * B, Q, R, N, S)
    assert np.linalg.norm(res) <= 1e-10 * np.linalg.norm(S)


def test_discount_one_is_the_undiscounted_problem_exactly():
    A, B, Q, R, N = random_problem(7)
    for a, b in zip(dlqr(A, B, Q, R, N), dlqr(A, B, Q, R, N, discount=1.0), strict=True):
        np.testing.assert_array_equal(a, b)


def test_discounting_may_leave_the_plant_unstable():
    """K = 0 is optimal when Q = 0; with γ < 1/ρ(A)² the DARE of (√γA, √γB) exists, and
    E = eig(A) is the plant's (unstable) closed loop, inside the circle of radius 1/√γ."""
    A = np.diag([1.2, 0.5])
    K, S, E = dlqr(A, np.ones((2, 1)), np.zeros((2, 2)), np.eye(1), discount=0.5)
    np.testing.assert_array_equal(K, 0.0)
    np.testing.assert_array_equal(S, 0.0)
    assert np.max(np.abs(E)) == pytest.approx(1.2) and np.max(np.abs(E)) < 1 / np.sqrt(0.5)


# ---------------------------------------------------------------- bad input


def good():
    A, B, Q, R, N = random_problem(8, n=3, m=2)
    return {"A": A, "B": B, "Q": Q, "R": R, "N": N}


def with_(name, value):
    args = good()
    args[name] = value
    return args


BAD = [
    (with_("A", np.ones((3, 2))), r"^A must be a non-empty square matrix"),
    (with_("A", np.ones(3)), r"^A must be a 2-D matrix"),
    (with_("B", np.ones((2, 2))), r"^B must be n x m with n = 3 rows"),
    (with_("B", np.ones((3, 0))), r"^B must be n x m"),
    (with_("Q", np.eye(2)), r"^Q must be 3 x 3"),
    (with_("Q", np.eye(3) + np.triu(np.ones((3, 3)), 1)), r"^Q must be symmetric"),
    (with_("R", np.diag([1.0, -1.0])), r"^R must be positive definite"),
    (with_("R", np.zeros((2, 2))), r"^R must be positive definite"),
    (with_("R", np.eye(3)), r"^R must be 2 x 2"),
    (with_("N", np.zeros((2, 3))), r"^N must be n x m = 3 x 2"),
    (with_("A", np.array([[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]])), r"^A must be finite"),
    (with_("B", np.full((3, 2), np.inf)), r"^B must be finite"),
    (with_("Q", np.full((3, 3), np.nan)), r"^Q must be finite"),
    (with_("R", np.array([[1.0, np.nan], [np.nan, 1.0]])), r"^R must be finite"),
    (with_("N", np.full((3, 2), np.nan)), r"^N must be finite"),
    (with_("A", np.eye(3) * 1j), r"^A must be real"),
    (with_("Q", "eye"), r"^Q must be numeric"),
]


@pytest.mark.parametrize("solver", [lqr, dlqr])
@pytest.mark.parametrize(
    "args, message", BAD, ids=[m.strip("^").split(" must")[0] + str(i) for i, (_, m) in enumerate(BAD)]
)
def test_bad_input_names_the_argument(solver, args, message):
    with pytest.raises(ValueError, match=message):
        solver(**args)


@pytest.mark.parametrize("discount", [0.0, -0.5, 1.5, np.nan, "0.9", None, True, [0.9]])
def test_bad_discount(discount):
    with pytest.raises(ValueError, match=r"^discount must be"):
        dlqr(**good(), discount=discount)


@pytest.mark.parametrize("solver", [lqr, dlqr])
def test_not_stabilizable_is_a_value_error_that_says_so(solver):
    A = np.diag([2.0, -0.5])  # the unstable mode is not actuated
    with pytest.raises(ValueError, match="no stabilizing solution.*stabilizable"):
        solver(A, np.array([[0.0], [1.0]]), np.eye(2), np.eye(1))


@pytest.mark.parametrize("solver, a", [(lqr, 0.0), (dlqr, 1.0)])
def test_unobserved_mode_on_the_stability_boundary_is_a_value_error(solver, a):
    with pytest.raises(ValueError, match="no stabilizing solution"):
        solver([[a]], [[1.0]], [[0.0]], [[1.0]])
