"""Certainty-equivalence (CE) reference: least-squares model + Riccati on the same data.

``[Â B̂] = X⁺ Z⁺`` (Z = [X U]); the stage-cost kernel ``W = [[Q, N], [Nᵀ, R]]`` is fitted
from the observed costs with the same quadratic features unless given; then ``K`` from
:func:`attitude_envs.lqr.dlqr` (the DARE of ``(√γÂ, √γB̂)`` with ``Q, R, N``). This is the
sample-efficiency ceiling a Q-learner is compared with (it equals the matrix Bellman equation of Lopez, Alsalti & Müller 2023). It is a *model-based* method on the agent's data, for reference only.
"""

from __future__ import annotations

import numpy as np

from agents.qlqr.data import Transitions
from agents.qlqr.estimators import lstsq_tall
from agents.qlqr.features import quadratic_features, smat
from attitude_envs.lqr import dlqr


def fit_model(data: Transitions) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``(Â, B̂)`` of ``x⁺ ≈ Âx + B̂u`` (column-scaled ``lstsq``)."""
    Z = np.hstack([data.X, data.U])
    scale = np.sqrt(np.mean(Z**2, axis=0))
    scale[scale == 0] = 1.0
    theta = lstsq_tall(Z / scale, data.Xn) / scale[:, None]
    n = data.X.shape[1]
    return theta[:n].T, theta[n:].T


def fit_cost(data: Transitions) -> np.ndarray:
    """Least-squares stage-cost kernel ``W`` with ``r ≈ zᵀWz`` (z = [x; u])."""
    Z = np.hstack([data.X, data.U])
    scale = np.sqrt(np.mean(Z**2, axis=0))
    scale[scale == 0] = 1.0
    Phi = quadratic_features(Z / scale)
    theta = lstsq_tall(Phi, data.r)
    return smat(theta, Z.shape[1]) / np.outer(scale, scale)


def ce_gain(data: Transitions, discount: float = 1.0, Q=None, R=None) -> np.ndarray:
    """CE gain ``K`` (u = −Kx) from the data; ``Q``/``R`` known or fitted from the costs."""
    n = data.X.shape[1]
    A, B = fit_model(data)
    W = fit_cost(data)
    Qm = W[:n, :n] if Q is None else np.asarray(Q, float)
    Rm = W[n:, n:] if R is None else np.asarray(R, float)
    Nm = W[:n, n:] if (Q is None and R is None) else np.zeros((n, B.shape[1]))
    return dlqr(A, B, Qm, Rm, Nm, discount=discount)[0]
