"""Policy iteration (``method="policy_iteration"``, ``"lspi"``): Bradtke/Lewis PI
(Hewer 1971; Bradtke, Ydstie & Barto 1994; Lewis & Vrabie 2009).

Evaluate the current gain from data (the ``td_estimator`` strategy,
:mod:`agents.qlqr.evaluation`), improve greedily (``K = H_uu⁻¹H_ux``, u = −Kx). On-policy by
default: a fresh batch per iteration under the behaviour ``u = −K_j x + η``. With
``reuse_data=True`` (``method="lspi"``) it is off-policy LSPI on one batch (Lagoudakis &
Parr 2003). PI needs a stabilizing initial gain: ``initial_gain``, or one found from the first
batch by the ``stabilize`` strategy (:mod:`agents.qlqr.stabilizers`).
"""

from __future__ import annotations

import numpy as np

from agents.qlqr.context import Context
from agents.qlqr.estimators import InsufficientExcitationError, NotPositiveDefiniteError, greedy_gain
from agents.qlqr.stabilizers import Stabilizer
from agents.qlqr.trace import relative_change


class PolicyIteration:
    """The method strategy: ``stabilizer`` (without ``initial_gain``), then evaluate/improve
    until the relative gain change is below ``tol``, the change stops contracting (the
    estimation floor) or ``max_iterations``; one batch (``reuse_data``) or a fresh one per
    iteration."""

    name = "policy_iteration"
    default_max_iterations = 30

    def __init__(self, stabilizer: Stabilizer, reuse_data: bool = False, tol: float = 1e-10) -> None:
        self.stabilizer = stabilizer
        self.reuse_data = reuse_data
        self.tol = tol

    def run(self, ctx: Context, max_iterations: int) -> None:
        trace = ctx.trace
        behaviour = ctx.initial_gain if ctx.initial_gain is not None else ctx.zero_gain()
        data = ctx.collect(behaviour)
        K = ctx.initial_gain
        if K is None:
            K = self.stabilizer.stabilizing_gain(ctx, data, ctx.design(data, "value-iteration warm-up"))
            if K is None:
                raise InsufficientExcitationError(
                    "no stabilizing gain passed the data Lyapunov test within max_warmup_iterations "
                    f"= {self.stabilizer.max_iterations}; pass initial_gain"
                )
            trace.stop_reason = None
        design = ctx.design(data, "policy evaluation")
        d_prev = np.inf
        for j in range(max_iterations):
            if j > 0 and not self.reuse_data:
                data = ctx.collect(K)
                design = ctx.design(data, "policy evaluation")
            H, c, exc = ctx.evaluation.evaluate(data, design, K, ctx.discount)
            try:
                K_new, ratio = greedy_gain(H, ctx.basis.n)
            except NotPositiveDefiniteError as err:
                trace.stop_reason = "H_uu not positive definite"
                raise NotPositiveDefiniteError(
                    f"{err} at iteration {j}: the data do not determine the Q-function of the current gain "
                    "(too few or too noisy samples, or a non-stabilizing gain); collect more samples_per_iteration"
                ) from None
            dK = relative_change(K_new, K)
            dH = relative_change(H, trace.kernel)
            trace.record(j, "policy_iteration", exc, dH, dK, K_new, ratio, c)
            K = K_new
            trace.gain, trace.kernel = K, H
            if dK < self.tol:
                trace.stop_reason = "converged"
                return
            if j >= 2 and dK >= d_prev:  # no longer contracting: estimation floor reached
                trace.stop_reason = "stalled"
                return
            d_prev = dK
        trace.stop_reason = "max_iterations"
