"""Value iteration (``method="value_iteration"``): the method of Heravi & Novinzadeh 2017
(eqs. 17–30; Al-Tamimi, Lewis & Abu-Khalaf 2007; Lewis & Vrabie 2009).

``H_{j+1} = argmin Σ (φ(z_k)ᵀθ − r_k − γ x_{k+1}ᵀ P_j x_{k+1})²`` from ``H₀ = 0``, with
``P_j = H_xx − H_xu K_j`` (eq. 16) and the greedy gain ``K_j = H_uu⁻¹H_ux`` (eq. 13, u = −Kx).
By default one batch is reused for every iteration (fitted-Q iteration): each iteration is
then a p-dimensional affine map, so 10⁵ iterations cost seconds. ``reuse_data=False``
collects a fresh batch per iteration, as the paper does.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from agents.qlqr.context import Context
from agents.qlqr.data import Transitions
from agents.qlqr.estimators import Design, NotPositiveDefiniteError, greedy_gain
from agents.qlqr.features import svec
from agents.qlqr.trace import relative_change


class ValueIteration:
    """The method strategy: VI from H = 0 until :func:`converged` at ``tol`` (or
    ``max_iterations``); one batch reused (``reuse_data``) or a fresh batch per iteration."""

    name = "value_iteration"
    default_max_iterations = 100_000

    def __init__(self, reuse_data: bool = True, tol: float = 1e-10) -> None:
        self.reuse_data = reuse_data
        self.tol = tol

    def run(self, ctx: Context, max_iterations: int) -> None:
        behaviour = ctx.trace.gain if ctx.initial_gain is not None else ctx.zero_gain()
        data = ctx.collect(behaviour)
        iterate(ctx, data, max_iterations, "value_iteration", fresh_batches=not self.reuse_data, tol=self.tol)


def affine_map(ctx: Context, data: Transitions, design: Design) -> tuple[np.ndarray, np.ndarray]:
    """``θ_{j+1} = a + G·svec(P_j in scaled x)`` for the batch (fitted-Q iteration): the target
    ``r_k + γ x⁺ᵀP_j x⁺`` is linear in svec(P_j), so one solve with n(n+1)/2 + 1
    right-hand sides serves every iteration (by the ``estimator`` strategy)."""
    Phi_x = ctx.basis.state_features(data.Xn)
    Y = np.hstack([data.r[:, None], ctx.discount * Phi_x])
    AG = ctx.estimator.least_squares(design, Y)
    return AG[:, 0], AG[:, 1:]


def iterate(
    ctx: Context,
    data: Transitions,
    max_iterations: int,
    phase: str,
    gate: Callable[[np.ndarray], bool] | None = None,
    *,
    fresh_batches: bool = False,
    tol: float = 0.0,
) -> np.ndarray | None:
    """Iterate VI on ``data`` (a fresh batch per iteration with ``fresh_batches``); history
    rows of ``phase``. ``gate(K)`` (a warm-up) stops at the first gain it accepts and returns
    ``None`` if none is; without a gate, stops when :func:`converged` at ``tol``."""
    basis, trace = ctx.basis, ctx.trace
    design = ctx.design(data, "value iteration")
    a, G = affine_map(ctx, data, design)
    n = basis.n
    sxx = basis.outer[:n, :n]
    P = np.zeros((n, n))
    K = ctx.zero_gain()
    H_prev = None
    d_hist: list[float] = []
    for j in range(max_iterations):
        if fresh_batches and j > 0 and gate is None:
            data = ctx.collect(K)
            design = ctx.design(data, "value iteration")
            a, G = affine_map(ctx, data, design)
        theta = a + G @ svec(P * sxx)
        H, c = basis.kernel(theta)
        try:
            K_new, ratio = greedy_gain(H, n)
        except NotPositiveDefiniteError:
            trace.stop_reason = "H_uu not positive definite"
            raise
        P = H[:n, :n] - H[:n, n:] @ K_new
        P = 0.5 * (P + P.T)
        dK = relative_change(K_new, K)
        dH = relative_change(H, H_prev) if H_prev is not None else 1.0
        # the (reporting-only) spectral radius costs an eigensolve: every iteration early on,
        # then every 100th (None in between)
        trace.record(j, phase, design.excitation, dH, dK, K_new, ratio, c, rho=j < 100 or j % 100 == 0)
        K, H_prev = K_new, H
        trace.gain, trace.kernel = K, H
        d_hist.append(dK)
        if gate is not None:
            if np.any(K) and gate(K):
                return K
            continue
        if converged(d_hist, tol):
            trace.stop_reason = "converged"
            trace.history[-1]["spectral_radius"] = trace.spectral_radius(K)
            return K
    if trace.history:
        trace.history[-1]["spectral_radius"] = trace.spectral_radius(K)
    trace.stop_reason = "max_iterations" if gate is None else "no stabilizing gain found"
    return None if gate is not None else K


def converged(d: list[float], tol: float, window: int = 10) -> bool:
    """VI converges linearly: error ≈ ΔK·r/(1−r) with the contraction rate r estimated
    over the last ``window`` iterations; stop when that bound is below ``tol``, or when
    ΔK has reached round-off."""
    dk = d[-1]
    if dk == 0.0 and len(d) > 1 and any(v > 0 for v in d):
        return True
    if len(d) <= window or d[-1 - window] <= 0 or dk <= 0:
        return False
    r = (dk / d[-1 - window]) ** (1.0 / window)
    if dk < 1e-3 * tol:
        return True
    return r < 1.0 and dk * r / (1.0 - r) < tol
