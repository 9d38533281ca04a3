"""What learning has produced so far: the current gain and kernel, one history row per
iteration, the stop reason."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.qlqr.estimators import Excitation
from agents.qlqr.nominal import NominalModel, spectral_radius
from agents.qlqr.sampling import Sampler


def relative_change(new: np.ndarray, old: np.ndarray | None) -> float:
    """``‖new − old‖/‖new‖`` (1 without ``old``; ∞ from a nonzero ``old`` to zero)."""
    if old is None:
        return 1.0
    den = np.sqrt(np.vdot(new, new))
    diff = new - old
    num = np.sqrt(np.vdot(diff, diff))
    return float(num / den) if den > 0 else (0.0 if num == 0 else float("inf"))


class Trace:
    """The learner's state across ``learn()`` calls: ``gain`` (m×n, u = −Kx), ``kernel`` (H)
    and, per call, ``history`` and ``stop_reason``. The history rows read the samples used
    and the input-signal ratio from ``sampler``; the spectral radius comes from the env's
    nominal ``model`` (reporting only; ``None`` without one)."""

    def __init__(self, gain: np.ndarray, sampler: Sampler, model: NominalModel | None) -> None:
        self.gain = gain
        self.kernel: np.ndarray | None = None
        self.history: list[dict[str, Any]] = []
        self.stop_reason: str | None = None
        self.sampler = sampler
        self.model = model

    def start(self) -> None:
        """A new ``learn()`` call: empty history, no stop reason (gain and kernel are kept)."""
        self.history = []
        self.stop_reason = None

    def spectral_radius(self, K: np.ndarray) -> float | None:
        return spectral_radius(self.model, K)

    def record(self, j, phase, exc: Excitation, dH, dK, K, ratio, c, rho: bool = True) -> None:
        """Append one iteration's row (the spectral radius only when ``rho``)."""
        rho = self.spectral_radius(K) if rho else None
        self.history.append(
            {
                "iteration": j,
                "phase": phase,
                "samples_used": self.sampler.samples_used,
                "rank": exc.rank,
                "n_unknowns": exc.n_unknowns,
                "cond": exc.cond,
                "delta_H": dH,
                "delta_K": dK,
                "spectral_radius": rho,
                "huu_eig_ratio": ratio,
                "input_signal_ratio": self.sampler.input_signal,
                "constant": c,
                "gain": K,
            }
        )
