"""The regression a batch poses: instrument rows ``f_k = [φ(z_k); 1]`` of the *scaled*
``z = [x/s_x; u/s_u]`` (scales from the first batch), row weights, the excitation-guarded
:class:`~agents.qlqr.estimators.Design`, the TD regressors of a gain, and the kernel H (in
physical units) of a coefficient vector θ.
"""

from __future__ import annotations

import numpy as np

from agents.qlqr.data import Transitions
from agents.qlqr.estimators import Design
from agents.qlqr.features import n_features, quadratic_features, smat


class QuadraticBasis:
    """Quadratic features of the scaled ``z`` (n states, m inputs, p = (n+m)(n+m+1)/2 kernel
    coefficients), with the constant regressor of the noisy Bellman equation when
    ``constant`` is set (per ``learn()`` call).

    ``scale`` (length n+m, ``None`` until :meth:`fit_scale`) is fixed by the first batch and
    kept for every later one; ``outer`` is ``scale ⊗ scale``. ``row_normalize``: divide each
    equation by ``‖z_k‖²`` (``None``: when ‖z‖² spans more than 10⁴ in the batch).
    ``cond_limit``/``cond_warn``: the excitation guard's thresholds.
    """

    def __init__(self, n: int, m: int, row_normalize: bool | None, cond_limit: float, cond_warn: float) -> None:
        self.n, self.m = n, m
        self.p = n_features(n + m)
        self.row_normalize = row_normalize
        self.cond_limit, self.cond_warn = cond_limit, cond_warn
        self.constant = False
        self.scale: np.ndarray | None = None
        self.outer: np.ndarray | None = None

    def fit_scale(self, data: Transitions) -> None:
        """Set ``scale`` from the first batch (later batches keep it)."""
        if self.scale is not None:
            return
        # RMS of the *directions* z_k/‖z_k‖: the typical proportions of the coordinates,
        # not dominated by the largest rows when the data span many orders of magnitude
        # (unstable trajectories)
        Z = np.hstack([data.X, data.U])
        norms = np.linalg.norm(Z, axis=1)
        Z = Z[norms > 0] / norms[norms > 0, None]
        s = np.sqrt(np.mean(Z**2, axis=0)) if len(Z) else np.ones(self.n + self.m)
        s[~(s > 0)] = 1.0
        self.scale = s
        self.outer = np.outer(s, s)

    def rows(self, data: Transitions) -> tuple[np.ndarray, np.ndarray]:
        """Instrument rows ``f_k = [φ(z_k); 1]`` and row weights (scaled coordinates)."""
        Zs = np.hstack([data.X, data.U]) / self.scale
        F = quadratic_features(Zs)
        if self.constant:
            F = np.hstack([F, np.ones((len(F), 1))])
        sq = np.sum(Zs**2, axis=1)
        normalize = self.row_normalize
        if normalize is None:  # when ‖z‖² spans more than 10⁴ (1st to 99th percentile)
            lo, hi = np.percentile(sq, [1.0, 99.0])
            normalize = bool(hi > 1e4 * max(float(lo), 1e-300))
        if normalize:  # an all-zero z_k gives the equation 0 = 0: weight 0
            w = np.divide(1.0, sq, out=np.zeros_like(sq), where=sq > 0)
        else:
            w = np.ones(len(F))
        return F, w

    def design(self, data: Transitions, what: str) -> Design:
        """The guarded design of a batch's rows (``what`` names the step in the guard's errors)."""
        F, w = self.rows(data)
        return Design(F, w, self.cond_limit, self.cond_warn, what)

    def reweighted(self, design: Design, weights: np.ndarray, what: str) -> Design:
        """The same instrument rows with other row weights."""
        return Design(design.F, weights, self.cond_limit, self.cond_warn, what)

    def td_regressors(self, design: Design, Xn: np.ndarray, K: np.ndarray, discount: float) -> np.ndarray:
        """``ψ_k = f_k − γ [φ(z⁺_k); 0]`` with ``z⁺ = [x⁺; −Kx⁺]``: the TD regressors of gain K."""
        Xn_s = Xn / self.scale[: self.n]
        Un_s = (-Xn @ K.T) / self.scale[self.n :]
        Phi_next = quadratic_features(np.hstack([Xn_s, Un_s]))
        Psi = design.F.copy()
        Psi[:, : self.p] -= discount * Phi_next  # the constant column is not differenced
        return Psi

    def state_features(self, X: np.ndarray) -> np.ndarray:
        """``φ(x/s_x)``: the quadratic features of scaled states alone."""
        return quadratic_features(X / self.scale[: self.n])

    def kernel(self, theta: np.ndarray) -> tuple[np.ndarray, float | None]:
        """``(H, λ̂)``: the kernel of θ in physical units and the constant coefficient (if any)."""
        d = self.n + self.m
        H = smat(theta[: self.p], d) / self.outer
        return H, (float(theta[self.p]) if self.constant else None)
