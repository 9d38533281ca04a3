"""Model-based ground truth for checking the learners (tests, reproductions, benchmarks).

Never used by :class:`agents.QLearningLQR` itself. Convention u = −Kx. The optimal gain
``K*`` and Riccati solution ``P*`` of the (discounted) problem are
:func:`attitude_envs.lqr.dlqr`'s; here are the iterations that converge to them.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from attitude_envs.lqr import dlqr


def relative_error(K: np.ndarray, K_ref: np.ndarray) -> float:
    """``‖K − K_ref‖_F / ‖K_ref‖_F``."""
    return float(np.linalg.norm(K - K_ref) / np.linalg.norm(K_ref))


def riccati_gains(A, B, Q, R, iterations: int, discount: float = 1.0) -> np.ndarray:
    """Gains of the Riccati difference recursion from P₀ = 0 (Heravi & Novinzadeh 2017, eq. 10):
    ``out[j] = K(P_j) = (R + γBᵀP_jB)⁻¹γBᵀP_jA`` with ``P_{j+1} = Q + γAᵀP_j(A − BK(P_j))``,
    j = 0 … iterations−1 — aligned with VI's ``history[j]["gain"]`` (H_{j+1} is built on P_j)."""
    P = np.zeros_like(Q, dtype=float)
    out = np.empty((iterations, B.shape[1], A.shape[0]))
    for j in range(iterations):
        K = np.linalg.solve(R + discount * B.T @ P @ B, discount * B.T @ P @ A)
        out[j] = K
        P = Q + discount * A.T @ P @ (A - B @ K)
        P = 0.5 * (P + P.T)
    return out


def riccati_iterations(A, B, Q, R, tol: float = 1e-8, max_iterations: int = 200_000) -> int:
    """Number of Riccati-recursion steps from P₀ = 0 until ``relative_error(K(P_j), K*) < tol``,
    counted like VI's history (the count is j + 1)."""
    Ks = dlqr(A, B, Q, R)[0]
    P = np.zeros_like(Q, dtype=float)
    for j in range(max_iterations):
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        if relative_error(K, Ks) < tol:
            return j + 1
        P = Q + A.T @ P @ (A - B @ K)
        P = 0.5 * (P + P.T)
    raise ValueError(f"Riccati recursion did not reach {tol} in max_iterations = {max_iterations}")


def hewer_iterations(A, B, Q, R, K0, tol: float = 1e-8, max_iterations: int = 100) -> int:
    """Model-based policy iteration (Hewer 1971) from a stabilizing ``K0`` until
    ``relative_error(K_j, K*) < tol``."""
    Ks = dlqr(A, B, Q, R)[0]
    K = np.asarray(K0, dtype=float)
    for j in range(1, max_iterations + 1):
        Acl = A - B @ K
        if np.max(np.abs(np.linalg.eigvals(Acl))) >= 1:
            raise ValueError("K0 must be stabilizing (spectral radius of A − B K0 < 1)")
        P = scipy.linalg.solve_discrete_lyapunov(Acl.T, Q + K.T @ R @ K)
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        if relative_error(K, Ks) < tol:
            return j
    raise ValueError(f"Hewer iteration did not reach {tol} in max_iterations = {max_iterations}")
