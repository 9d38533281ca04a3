"""Policy evaluation: the Q-function kernel H of a gain K from one batch (the
``td_estimator`` strategies of :class:`agents.QLearningLQR`, one interface,
:class:`PolicyEvaluation`).

* :class:`LSTDQ` (``"lstd"``) — LSTD-Q: the TD equations ``ψ_kᵀθ = r_k`` with the instrument
  ``f_k = [φ(z_k); 1]`` (consistent under process noise, with the constant feature), solved
  by the ``estimator`` strategy.
* :class:`FeasibleGLSLSTDQ` (``"lstd_gls"``) — a second LSTD-Q pass with every TD equation
  weighted by the inverse of its fitted noise variance
  (:func:`agents.qlqr.estimators.variance_weights`).
* :class:`BellmanResidualOLS` (``"ols"``) — the legacy Bradtke-style OLS fit of the Bellman
  residual (biased under noise; always a batch fit).
* :class:`MatrixBellman` (``"matrix_bellman"``) — Lopez, Alsalti & Müller 2023, eq. 29
  (algebraically certainty equivalence; always a batch fit).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.linalg

from agents.qlqr.basis import QuadraticBasis
from agents.qlqr.data import Transitions
from agents.qlqr.estimators import (
    Design,
    Estimator,
    Excitation,
    lstsq_tall,
    ordinary_least_squares,
    variance_weights,
)
from agents.qlqr.features import smat

Evaluated = tuple[np.ndarray, float | None, Excitation]  # (H, λ̂ or None, excitation)


class PolicyEvaluation(Protocol):
    """Q-function of gain ``K`` (u = −Kx) at discount γ from one batch and its design."""

    name: str

    def evaluate(self, data: Transitions, design: Design, K: np.ndarray, discount: float) -> Evaluated: ...


class _TemporalDifference:
    """The TD evaluations: regress the observed costs on ``ψ_k = f_k − γφ(z⁺_k)``; a
    subclass says how θ is solved for."""

    name = ""

    def __init__(self, basis: QuadraticBasis, estimator: Estimator) -> None:
        self.basis = basis
        self.estimator = estimator

    def evaluate(self, data: Transitions, design: Design, K: np.ndarray, discount: float) -> Evaluated:
        Psi = self.basis.td_regressors(design, data.Xn, K, discount)
        theta, exc = self.solve(design, Psi, data.r)
        H, c = self.basis.kernel(theta)
        return H, c, exc

    def solve(self, design: Design, Psi: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, Excitation]:
        raise NotImplementedError


class LSTDQ(_TemporalDifference):
    """``td_estimator="lstd"``: LSTD-Q (instrument ``F``, regressor ``Ψ``, the design's row
    weights) by the ``estimator`` strategy (batch QR or RLS)."""

    name = "lstd"

    def solve(self, design: Design, Psi: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, Excitation]:
        return self.estimator.instrumental(design, Psi, r)


class FeasibleGLSLSTDQ(LSTDQ):
    """``td_estimator="lstd_gls"``: LSTD-Q, then the second stage of feasible GLS: reweight
    every TD equation by the inverse of its conditional noise variance, fitted from the
    first stage's residuals (:func:`agents.qlqr.estimators.variance_weights`); no model is used."""

    name = "lstd_gls"

    def solve(self, design: Design, Psi: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, Excitation]:
        theta, exc = super().solve(design, Psi, r)
        F = design.F
        F1 = F if self.basis.constant else np.hstack([F, np.ones((len(F), 1))])
        # residuals within 1e-10 of the largest cost are round-off of exact (noise-free) data
        w = variance_weights(F1, r - Psi @ theta, noise_free=1e-10 * float(np.max(np.abs(r), initial=0.0)))
        if w is None:  # noise-free data: the first stage is exact
            return theta, exc
        return super().solve(self.basis.reweighted(design, w, "GLS policy evaluation"), Psi, r)


class BellmanResidualOLS(_TemporalDifference):
    """``td_estimator="ols"``: the legacy OLS Bellman-residual fit
    (:func:`agents.qlqr.estimators.ordinary_least_squares`; biased under noise). A batch
    fit whatever the ``estimator``."""

    name = "ols"

    def solve(self, design: Design, Psi: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, Excitation]:
        return ordinary_least_squares(Psi, r, design.weights, self.basis.cond_limit, self.basis.cond_warn)


class MatrixBellman:
    """``td_estimator="matrix_bellman"``: policy evaluation by the matrix Bellman equation
    (Lopez et al. 2023, eq. 29): ``ZᵀHZ = ZᵀΛZ + γ YᵀHY`` for all sample pairs; with
    ``M = Y Z⁺`` it reduces to the Stein equation ``H = Λ + γ MᵀHM``. The stage-cost kernel Λ
    is fitted from the observed costs (the agent is not told Q and R). A batch fit whatever
    the ``estimator`` (taken for a uniform constructor, unused)."""

    name = "matrix_bellman"

    def __init__(self, basis: QuadraticBasis, estimator: Estimator) -> None:
        self.basis = basis
        self.estimator = estimator

    def evaluate(self, data: Transitions, design: Design, K: np.ndarray, discount: float) -> Evaluated:
        basis = self.basis
        n, s = basis.n, basis.scale
        Zs = np.hstack([data.X, data.U]) / s
        Ys = np.hstack([data.Xn, -data.Xn @ K.T]) / s
        M = lstsq_tall(Zs, Ys).T
        lam_theta = design.least_squares(data.r)
        Lam = smat(lam_theta[: basis.p], n + basis.m)
        Hs = scipy.linalg.solve_discrete_lyapunov(np.sqrt(discount) * M.T, Lam)
        return 0.5 * (Hs + Hs.T) / np.outer(s, s), None, design.excitation
