"""Least-squares solvers for quadratic Q-functions, with an excitation guard, and the
``estimator`` strategies of :class:`agents.QLearningLQR` built on them.

All solvers work on *weighted, column-scaled* rows (row normalization; Jacobi column
scaling), factor the instrument matrix once by QR (never the normal equations) and report
rank and condition number (persistence of excitation).

Strategies (one interface, :class:`Estimator`): :class:`BatchLeastSquares`
(``estimator="batch"``) and :class:`RecursiveLeastSquares` (``estimator="rls"``). They solve
the LSTD-Q systems of policy evaluation (:mod:`agents.qlqr.evaluation`) and the fitted-Q
regression of value iteration (:mod:`agents.qlqr.value_iteration`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.linalg

from agents.qlqr.features import smat, svec


class InsufficientExcitationError(ValueError):
    """The regressors do not span the p unknowns (rank) or are too ill-conditioned to
    give a trustworthy kernel: collect more samples or raise ``exploration_std``."""


class NotPositiveDefiniteError(ValueError):
    """The learned ``H_uu`` is not positive (semi-)definite: no greedy gain exists."""


@dataclass(frozen=True)
class Excitation:
    """Persistence-of-excitation diagnostics of an (instrument) matrix."""

    rank: int
    n_unknowns: int
    cond: float


def excitation(Fn: np.ndarray) -> Excitation:
    """Numerical rank and 2-norm condition number of a column-scaled matrix (via SVD)."""
    s = np.linalg.svd(Fn, compute_uv=False)
    if s.size == 0 or s[0] == 0:
        return Excitation(0, Fn.shape[1], float("inf"))
    rank = int(np.sum(s > s[0] * max(Fn.shape) * np.finfo(float).eps))
    cond = float(s[0] / s[-1]) if s[-1] > 0 and s.size == Fn.shape[1] else float("inf")
    return Excitation(rank, Fn.shape[1], cond)


def guard(exc: Excitation, what: str, cond_limit: float, cond_warn: float) -> None:
    """Raise :class:`InsufficientExcitationError` when rank < p or cond > ``cond_limit``."""
    if exc.rank < exc.n_unknowns:
        raise InsufficientExcitationError(
            f"{what}: regressor rank {exc.rank} < {exc.n_unknowns} unknowns (not persistently exciting); "
            f"samples_per_iteration must be >= {exc.n_unknowns} with generic exploration_std > 0"
        )
    if exc.cond > cond_limit:
        raise InsufficientExcitationError(
            f"{what}: regressor condition number {exc.cond:.3g} > cond_limit {cond_limit:.3g}; "
            "raise exploration_std relative to the state, or collect more samples"
        )
    if exc.cond > cond_warn:
        warnings.warn(f"{what}: regressor condition number {exc.cond:.3g} is large", stacklevel=3)


def r_factor(M: np.ndarray, chunk: int = 512) -> np.ndarray:
    """Upper-triangular ``R`` of ``M = QR`` by tall-skinny QR (QR of row blocks, then of the
    stacked R's): the same R up to row signs, without forming Q, and fast for N ≫ p (one
    big LAPACK QR is slow when BLAS threads compete for few cores)."""
    while len(M) > chunk:
        M = np.vstack([np.linalg.qr(M[i : i + chunk], mode="r") for i in range(0, len(M), chunk)])
    return np.linalg.qr(M, mode="r")


def _projected(A: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R_A, Q_Aᵀ Y)`` from one QR of ``[A Y]`` (the top blocks of its R factor)."""
    k = A.shape[1]
    R = r_factor(np.hstack([A, Y.reshape(len(A), -1)]))
    R = np.vstack([R, np.zeros((max(0, k - R.shape[0]), R.shape[1]))])
    return R[:k, :k], R[:k, k:]


def lstsq_tall(A: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Least-squares solution of ``A X ≈ Y`` for tall ``A`` via :func:`r_factor` (minimum norm
    if ``A`` is rank deficient)."""
    Ra, QtY = _projected(A, Y)
    X = np.linalg.lstsq(Ra, QtY, rcond=None)[0]
    return X[:, 0] if Y.ndim == 1 else X


class Design:
    """The instrument rows ``F`` (N×p), row weights ``w`` and their R factor.

    ``F`` holds ``f_k = φ(z_k)`` (plus a constant column when used). Every solve multiplies
    rows by ``w`` and columns by ``1/‖column‖`` first, and uses the QR of ``[F Y]``.
    """

    def __init__(self, F: np.ndarray, weights: np.ndarray, cond_limit: float, cond_warn: float, what: str):
        self.F = F
        self.weights = weights
        Fw = F * weights[:, None]
        col = np.linalg.norm(Fw, axis=0)
        col[col == 0] = 1.0
        self.col = col
        self.Fn = Fw / col
        self.excitation = excitation(r_factor(self.Fn)) if len(F) >= F.shape[1] else Excitation(0, F.shape[1], np.inf)
        guard(self.excitation, what, cond_limit, cond_warn)
        self.cond_limit, self.cond_warn = cond_limit, cond_warn

    def least_squares(self, Y: np.ndarray) -> np.ndarray:
        """``argmin_θ Σ w_k² (f_kᵀθ − y_k)²`` for each column of ``Y`` (fitted-Q / VI)."""
        Yw = Y * (self.weights if Y.ndim == 1 else self.weights[:, None])
        Rf, QtY = _projected(self.Fn, Yw)
        theta = scipy.linalg.solve_triangular(Rf, QtY) / self.col[:, None]
        return theta[:, 0] if Y.ndim == 1 else theta

    def instrumental(self, Psi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, Excitation]:
        """LSTD-Q: solve ``Σ w_k² f_k ψ_kᵀ θ = Σ w_k² f_k y_k`` as the equivalent
        square system ``(Q_Fᵀ Ψ_w) θ = Q_Fᵀ y_w`` (``F_w = Q_F R_F``), column-scaled."""
        Pw = Psi * self.weights[:, None]
        pcol = np.linalg.norm(Pw, axis=0)
        pcol[pcol == 0] = 1.0
        _, QtY = _projected(self.Fn, np.hstack([Pw / pcol, (y * self.weights)[:, None]]))
        M, rhs = QtY[:, :-1], QtY[:, -1]
        exc = excitation(M)
        guard(exc, "LSTD-Q policy evaluation", self.cond_limit, self.cond_warn)
        theta = np.linalg.solve(M, rhs)
        return theta / pcol, exc


def ordinary_least_squares(
    Psi: np.ndarray, y: np.ndarray, weights: np.ndarray, cond_limit: float, cond_warn: float
) -> tuple[np.ndarray, Excitation]:
    """Legacy Bradtke-style fit of the Bellman *residual* ``ψ_kᵀθ = r_k`` by OLS.

    Exact on deterministic data, **inconsistent under process noise** (errors in
    variables); kept only as an option to demonstrate that bias."""
    Pw = Psi * weights[:, None]
    col = np.linalg.norm(Pw, axis=0)
    col[col == 0] = 1.0
    Rp, Qty = _projected(Pw / col, y * weights)
    exc = excitation(Rp)
    guard(exc, "OLS Bellman-residual fit", cond_limit, cond_warn)
    theta = scipy.linalg.solve_triangular(Rp, Qty[:, 0])
    return theta / col, exc


def recursive_least_squares(
    F: np.ndarray,
    Psi: np.ndarray,
    Y: np.ndarray,
    weights: np.ndarray,
    initial_covariance: float | None = None,
    forgetting: float = 1.0,
) -> np.ndarray:
    """Instrumental-variable RLS (Bradtke & Barto 1996, "RLS-TD"), one row at a time.

    Solves ``Σ λ^{N−k} w_k² f_k ψ_kᵀ θ = Σ λ^{N−k} w_k² f_k y_k`` for each column of ``Y``
    (``Psi is F`` gives ordinary RLS, used by value iteration). ``initial_covariance=None``
    initializes *exactly* from the first p rows (no ridge bias); a number β starts from
    ``P₀ = βI, θ₀ = 0``, which is ridge regression with penalty 1/β.
    """
    Fw, Pw = F * weights[:, None], Psi * weights[:, None]
    Yw = (Y * (weights if Y.ndim == 1 else weights[:, None])).reshape(len(weights), -1)
    col = np.linalg.norm(Fw, axis=0)
    col[col == 0] = 1.0
    Fw, Pw = Fw / col, Pw / col
    p = F.shape[1]
    if initial_covariance is None:
        M0 = Fw[:p].T @ Pw[:p]
        P = np.linalg.inv(M0)
        theta = P @ (Fw[:p].T @ Yw[:p])
        start = p
    else:
        P = float(initial_covariance) * np.eye(p)
        theta = np.zeros((p, Yw.shape[1]))
        start = 0
    lam = float(forgetting)
    for k in range(start, len(weights)):
        f, psi = Fw[k], Pw[k]
        Pf = P @ f
        gain = Pf / (lam + psi @ Pf)
        theta += np.outer(gain, Yw[k] - psi @ theta)
        P = (P - np.outer(gain, psi @ P)) / lam
    theta = theta / col[:, None]
    return theta[:, 0] if Y.ndim == 1 else theta


def greedy_gain(H: np.ndarray, n: int, rel_tol: float = 1e-6, cond_limit: float = 1e4) -> tuple[np.ndarray, float]:
    """Greedy gain ``K = H_uu⁺ H_ux`` (u = −Kx; Heravi & Novinzadeh 2017, eq. 13 with the sign moved out).

    ``H_uu`` must be positive semi-definite (the paper's eq. 14): eigenvalues below
    ``−rel_tol·λ_max`` raise :class:`NotPositiveDefiniteError`. Eigen-directions with
    ``λ < rel_tol·λ_max`` are input directions that change neither cost nor state (e.g. the
    null space of four wheels on three axes); they get no gain (minimum-norm input).
    Between the two, ``λ_max/λ_min > cond_limit`` raises: such a direction is neither
    clearly null nor determined well enough by the data to give it a gain.
    Returns ``(K, λ_min/λ_max)``."""
    lam, V = np.linalg.eigh(H[n:, n:])  # symmetric input; eigh reads one triangle
    top = lam[-1]
    if top <= 0 or lam[0] < -rel_tol * top:
        raise NotPositiveDefiniteError(f"H_uu is not positive definite (eigenvalues {lam.tolist()})")
    keep = lam > rel_tol * top
    if np.min(lam[keep]) * cond_limit < top:
        raise NotPositiveDefiniteError(
            f"H_uu is nearly singular (eigenvalue ratio {np.min(lam[keep]) / top:.2g}): an input direction barely "
            "changes cost or state (redundant actuators?); learn in fewer input coordinates with input_map"
        )
    Vk = V[:, keep]
    K = Vk @ ((Vk.T @ H[n:, :n]) / lam[keep, None])
    return K, float(lam[0] / top)


def variance_weights(
    F: np.ndarray, residuals: np.ndarray, noise_free: float = 0.0, iterations: int = 3, floor: float = 1e-3
) -> np.ndarray | None:
    """Row weights ``1/√v̂(z_k)`` of feasible generalized least squares for a TD equation
    (weights that depend on ``z_k`` only keep LSTD-Q consistent).

    Under Gaussian process noise the TD error of the Q-function of gain K,
    ``ε_k = γ(x⁺ᵀP_K x⁺ − E[x⁺ᵀP_K x⁺ | z_k])``, has the conditional variance
    ``v(z) = γ²(4 μᵀP_K W P_K μ + 2 tr((P_K W)²))`` with ``μ = A x + B u``: ``zᵀSz + c`` with
    S ⪰ 0, c ≥ 0. It is fitted model-free from the squared first-stage residuals on the
    instrument rows ``F = [φ(z_k); 1]`` (svec quadratic features then the constant column):
    least squares, S projected onto the PSD cone and c onto [0, ∞), refitted ``iterations``
    times with weights ``1/v̂²`` (Var(ε²) ∝ v²: iterated variance-function estimation,
    Carroll & Ruppert 1988). Fitted values are floored at ``floor`` × the mean squared
    residual. Weighting each TD equation by ``1/v(z_k)`` makes ``φ(z_k)/v(z_k)`` the efficient
    instrument for ``E[ε_k | z_k] = 0`` (Chamberlain 1987), since ``E[ψ_k | z_k]`` lies in the
    span of F. Returns ``None`` when no residual exceeds ``noise_free`` in magnitude (noise-free
    data: residuals at round-off level carry no variance information)."""
    e2 = np.asarray(residuals, dtype=float) ** 2
    if not np.max(e2, initial=0.0) > noise_free**2:
        return None
    p = F.shape[1] - 1
    d = int(round((np.sqrt(8 * p + 1) - 1) / 2))
    col = np.linalg.norm(F, axis=0)
    col[col == 0] = 1.0
    Fn = F / col
    lower = floor * float(np.mean(e2))
    rw = np.ones(len(e2))
    for _ in range(max(1, int(iterations))):
        beta = lstsq_tall(Fn * rw[:, None], e2 * rw) / col
        lam, V = np.linalg.eigh(smat(beta[:p], d))
        beta = np.concatenate([svec((V * np.maximum(lam, 0.0)) @ V.T), [max(beta[p], 0.0)]])
        v = np.maximum(F @ beta, lower)
        rw = 1.0 / v
    return 1.0 / np.sqrt(v)


# ------------------------------------------------------------------ estimator strategies
class Estimator(Protocol):
    """How the coefficients θ are estimated from a :class:`Design` (``estimator=``)."""

    name: str

    def instrumental(self, design: Design, Psi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, Excitation]:
        """LSTD-Q: θ with ``Σ w_k² f_k ψ_kᵀ θ = Σ w_k² f_k y_k`` (instruments ``design.F``)."""
        ...

    def least_squares(self, design: Design, Y: np.ndarray) -> np.ndarray:
        """``argmin_θ Σ w_k² (f_kᵀθ − y_k)²`` for each column of ``Y``."""
        ...


class BatchLeastSquares:
    """``estimator="batch"``: one QR of the row-weighted, column-scaled design
    (:meth:`Design.instrumental`, :meth:`Design.least_squares`)."""

    name = "batch"

    def instrumental(self, design: Design, Psi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, Excitation]:
        return design.instrumental(Psi, y)

    def least_squares(self, design: Design, Y: np.ndarray) -> np.ndarray:
        return design.least_squares(Y)


class RecursiveLeastSquares:
    """``estimator="rls"``: instrumental-variable RLS, one row at a time
    (:func:`recursive_least_squares`); ``initial_covariance=None`` is the exact
    initialization, a number β starts from ``P₀ = βI``; ``forgetting`` λ ∈ (0, 1]. The
    excitation reported is the design's."""

    name = "rls"

    def __init__(self, initial_covariance: float | None = None, forgetting: float = 1.0):
        self.initial_covariance = initial_covariance
        self.forgetting = forgetting

    def instrumental(self, design: Design, Psi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, Excitation]:
        theta = recursive_least_squares(design.F, Psi, y, design.weights, self.initial_covariance, self.forgetting)
        return theta, design.excitation

    def least_squares(self, design: Design, Y: np.ndarray) -> np.ndarray:
        return recursive_least_squares(design.F, design.F, Y, design.weights, self.initial_covariance, self.forgetting)
