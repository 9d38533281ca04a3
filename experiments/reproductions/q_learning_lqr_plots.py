"""Figures of the Q-learning LQR reproduction (Heravi & Novinzadeh 2017) (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from agents.qlqr.truth import relative_error


def _figure(rows: int, cols: int, size: tuple[float, float]):
    fig = Figure(figsize=size, dpi=100)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def convergence(path: Path, vi_err: np.ndarray, riccati_err: np.ndarray, pi, ce_err: float, K_star: np.ndarray) -> None:
    """Left: gain error vs iteration (VI = Riccati recursion). Right: gain error vs env
    samples: the paper's scheme (45 fresh samples per VI iteration) vs ours."""
    fig, ax = _figure(1, 2, (11, 4))
    it = np.arange(1, len(vi_err) + 1)
    ax[0, 0].loglog(it, riccati_err, "k-", lw=3, alpha=0.3, label="Riccati recursion from P=0 (model-based)")
    ax[0, 0].loglog(it, np.maximum(vi_err, 1e-16), "C0--", label="Q-learning VI, one batch of 90 samples")
    ax[0, 0].set(xlabel="iteration", ylabel="‖K − K*‖ / ‖K*‖", title="Heravi & Novinzadeh 2017 plant: value iteration")
    ax[0, 0].legend(fontsize=8)
    paper_samples = 45 * np.arange(1, len(riccati_err) + 1)
    ax[0, 1].loglog(paper_samples, riccati_err, "k-", alpha=0.5, label="paper: VI, 45 fresh samples/iteration")
    pi_s = [h["samples_used"] for h in pi.history]
    pi_e = [max(relative_error(h["gain"], K_star), 1e-16) for h in pi.history]
    ax[0, 1].loglog(pi_s, pi_e, "C1o-", label="ours: on-policy PI (LSTD-Q), 90 fresh samples/iteration")
    ax[0, 1].loglog(
        [90], [max(vi_err[-1], 1e-16)], "C0*", ms=12, label=f"ours: VI on one batch of 90 ({len(vi_err)} it.)"
    )
    ax[0, 1].loglog([90], [max(ce_err, 1e-16)], "C2s", label="certainty equivalence, same 90 samples")
    ax[0, 1].set(xlabel="env samples", ylabel="‖K − K*‖ / ‖K*‖", title="gain error vs samples (log)")
    ax[0, 1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def trajectories(path: Path, sims: dict) -> None:
    """Quaternion vector part, rates and wheel torques from the paper's initial condition."""
    fig, ax = _figure(3, 1, (9, 9))
    for (name, s), style in zip(sims.items(), ("k-", "C1--", "C0:"), strict=False):
        t = 0.01 * np.arange(len(s["X"]))
        tu = 0.01 * np.arange(len(s["T"]))
        ax[0, 0].plot(t, s["X"][:, :3], style, lw=1)
        ax[1, 0].plot(t, s["X"][:, 3:], style, lw=1)
        ax[2, 0].plot(tu, s["T"][:, 3], style, lw=1, label=name)
    ax[0, 0].set(ylabel="q1, q2, q3")
    ax[1, 0].set(ylabel="ω [rad/s]")
    ax[2, 0].set(ylabel="wheel 4 torque [N·m]", xlabel="time [s]")
    ax[2, 0].legend(fontsize=8)
    ax[0, 0].set_title("Heravi & Novinzadeh 2017: learned (time-varying VI gain) vs LQR, paper's initial condition")
    fig.tight_layout()
    fig.savefig(path)
