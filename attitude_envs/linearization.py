"""Linear models of the plants and their exact zero-order-hold discretization.

A controller that uses these sees only the *nominal* model (DESIGN "Truth vs. nominal").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from attitude_envs.lqr import dlqr, lqr


def complex_step_jacobian(f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, step: float = 1e-20) -> np.ndarray:
    """``∂f/∂x`` at ``x0`` to rounding, by the complex step ``Im f(x0 + i h e_k) / h`` (Squire &
    Trapp 1998: no difference is taken, so no cancellation). ``f`` maps states stacked as the
    columns of an ``(n, k)`` array to ``(m, k)`` and is written with analytic operations only
    (a plant definition on :data:`~attitude_envs.plants.ops.NUMPY`); it is called once, on
    the ``n`` perturbed columns."""
    x0 = np.asarray(x0, dtype=float)
    z = np.repeat(x0[:, None], x0.size, axis=1).astype(complex)
    z[np.arange(x0.size), np.arange(x0.size)] += 1j * step
    return np.imag(np.asarray(f(z))) / step


def zoh(A: np.ndarray, B: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretization ``(A_d, B_d)`` of ``ẋ = Ax + Bu`` over ``dt_s``."""
    n, m = B.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n] = A
    block[:n, n:] = B
    e = scipy.linalg.expm(block * dt_s)
    return e[:n, :n], e[:n, n:]


def zoh_cost(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, dt_s: float):
    """Exact discretization of ``∫₀^dt (xᵀQx + uᵀRu) dt`` under a zero-order hold.

    Returns ``(Q_d, R_d, N_d)`` with the step cost ``xᵀQ_d x + 2xᵀN_d u + uᵀR_d u`` for the
    state ``x`` at the start of the step and ``u`` held over it (Van Loan 1978: with
    ``F = [[A, B], [0, 0]]`` and ``W = blkdiag(Q, R)``, ``∫ e^{Fᵀt} W e^{Ft} dt = G₂₂ᵀ G₁₂``
    where ``G = expm([[−Fᵀ, W], [0, F]] dt)``).
    """
    n, m = B.shape
    k = n + m
    F = np.zeros((k, k))
    F[:n, :n] = A
    F[:n, n:] = B
    W = scipy.linalg.block_diag(Q, R)
    M = np.zeros((2 * k, 2 * k))
    M[:k, :k] = -F.T
    M[:k, k:] = W
    M[k:, k:] = F
    G = scipy.linalg.expm(M * dt_s)
    Wd = G[k:, k:].T @ G[:k, k:]
    Wd = 0.5 * (Wd + Wd.T)
    return Wd[:n, :n], Wd[n:, n:], Wd[:n, n:]


@dataclass(frozen=True)
class LinearModel:
    """``ẋ = Ax + Bu`` (``dt_s is None``) or ``x⁺ = Ax + Bu`` (``dt_s`` the period, s),
    with the cost weights of the same ``x`` and ``u``: ``Q``, ``R`` and cross term ``N``
    (``xᵀQx + 2xᵀNu + uᵀRu``, per second when continuous, per step when discrete)."""

    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    N: np.ndarray | None = None
    dt_s: float | None = None

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    def discretize(self, dt_s: float) -> LinearModel:
        """Exact ZOH discretization of the plant and of the cost over ``dt_s`` seconds."""
        if self.dt_s is not None:
            raise ValueError("the model is already discrete")
        if self.N is not None and np.any(self.N):
            raise ValueError("discretizing a continuous cost with a cross term is not supported")
        A_d, B_d = zoh(self.A, self.B, dt_s)
        Q_d, R_d, N_d = zoh_cost(self.A, self.B, self.Q, self.R, dt_s)
        return LinearModel(A_d, B_d, Q_d, R_d, N_d, dt_s)

    def lqr_gain(self) -> np.ndarray:
        """Infinite-horizon LQR gain ``K`` (``u = −K x``): :func:`attitude_envs.lqr.lqr` when
        continuous, :func:`attitude_envs.lqr.dlqr` when discrete."""
        solve = lqr if self.dt_s is None else dlqr
        return solve(self.A, self.B, self.Q, self.R, self.N)[0]
