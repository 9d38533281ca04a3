"""A stabilizing initial gain from data, for policy iteration without ``initial_gain``
(the ``stabilize`` strategies of :class:`agents.QLearningLQR`, one interface,
:class:`Stabilizer`). A gain is accepted by the data Lyapunov test :func:`lyapunov_ok`.

* :class:`DiscountAnnealing` (``"discount_annealing"``, the default) — policy iteration from
  K = 0 at a small discount, raised while the test passes (Lamperski 2020). Its gains have a
  stability margin: on the Heravi & Novinzadeh 2017 plant the first PI evaluation after it
  has cond ≈ 60.
* :class:`ValueIterationWarmup` (``"value_iteration"``) — value iteration on the first batch
  until the greedy gain passes the test (its first accepted gain is barely stable: cond ≈
  1e13 on that plant).
"""

from __future__ import annotations

import warnings
from typing import Protocol

import numpy as np

from agents.qlqr.context import Context
from agents.qlqr.data import Transitions
from agents.qlqr.estimators import Design, InsufficientExcitationError, greedy_gain
from agents.qlqr.trace import relative_change
from agents.qlqr.value_iteration import iterate


class Stabilizer(Protocol):
    """Finds a stabilizing gain from one batch (``None`` if none within ``max_iterations``)."""

    name: str
    max_iterations: int

    def stabilizing_gain(self, ctx: Context, data: Transitions, design: Design) -> np.ndarray | None: ...


def lyapunov_ok(ctx: Context, data: Transitions, design: Design, K: np.ndarray, discount: float) -> bool:
    """Data Lyapunov test: ``T_Kᵀ Ĥ_K T_K ≻ 0`` ⇒ K stabilizing (exact data)."""
    try:
        with warnings.catch_warnings():  # probing near the stability boundary is ill-conditioned by design
            warnings.simplefilter("ignore")
            H, _, _ = ctx.evaluation.evaluate(data, design, K, discount)
    except (InsufficientExcitationError, np.linalg.LinAlgError):
        return False
    n = ctx.basis.n
    T = np.vstack([np.eye(n), -K])
    P = T.T @ H @ T
    s = ctx.basis.scale[:n]
    return bool(np.min(np.linalg.eigvalsh(0.5 * (P + P.T) * np.outer(s, s))) > 0)


class DiscountAnnealing:
    """Discount annealing (Lamperski 2020): K = 0 is stabilizing for a small enough discount
    γ₀ (``initial_discount``); policy iteration at γ, then raise γ towards the target while
    the data Lyapunov test at the new γ accepts the current gain (bisection for the largest
    such γ, 90 % of the way). Phase ``"annealing"`` in the history, with its ``discount``."""

    name = "discount_annealing"

    def __init__(self, initial_discount: float, max_iterations: int) -> None:
        self.initial_discount = initial_discount
        self.max_iterations = max_iterations

    def stabilizing_gain(self, ctx: Context, data: Transitions, design: Design) -> np.ndarray | None:
        target = ctx.discount
        gamma = self.initial_discount
        K = ctx.zero_gain()
        j = 0
        for _ in range(self.max_iterations):
            for _ in range(30):  # PI at this discount, on the same batch
                H, c, exc = ctx.evaluation.evaluate(data, design, K, gamma)
                K_new, ratio = greedy_gain(H, ctx.basis.n)
                dK = relative_change(K_new, K)
                ctx.trace.record(j, "annealing", exc, 1.0, dK, K_new, ratio, c)
                ctx.trace.history[-1]["discount"] = gamma
                j += 1
                K = K_new
                if dK < 1e-6:
                    break
            if gamma >= target:
                return K

            def ok(g: float, gain=K) -> bool:
                return lyapunov_ok(ctx, data, design, gain, g)

            if ok(target):
                gamma = target
                continue
            lo, hi = gamma, target
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if ok(mid) else (lo, mid)
            if lo <= gamma * (1 + 1e-9):
                return None
            gamma = gamma + 0.9 * (lo - gamma)
        return None


class ValueIterationWarmup:
    """Value iteration on the first batch (phase ``"vi_warmup"``) until the greedy gain
    passes the data Lyapunov test at the target discount."""

    name = "value_iteration"

    def __init__(self, max_iterations: int) -> None:
        self.max_iterations = max_iterations

    def stabilizing_gain(self, ctx: Context, data: Transitions, design: Design) -> np.ndarray | None:
        def gate(gain: np.ndarray) -> bool:
            return lyapunov_ok(ctx, data, design, gain, ctx.discount)

        return iterate(ctx, data, self.max_iterations, "vi_warmup", gate)
