"""The env's nominal linear model, for reporting only: the closed-loop spectral radius in
the learning history and the reference optimum beside the learned gain. Never used for
learning.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attitude_envs.lqr import dlqr


class NominalModel(NamedTuple):
    """Discrete nominal model in the learner's input coordinates (reporting only)."""

    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray | None
    R: np.ndarray | None
    N: np.ndarray | None


def reporting_model(env, input_map) -> NominalModel | None:
    """Discrete (A, B) and stage-cost weights (Q, R, N) of the env's nominal model of its
    decision period (``env.unwrapped.decision_model`` where the env has one), in the
    learner's input coordinates ``v`` (actuators ``u = M v``: ``B M``, ``MᵀRM``, ``N M``), for
    the spectral-radius diagnostic and the reference optimum of
    :meth:`agents.QLearningLQR.compare_with_certainty_equivalence` only."""
    # LinearSystem-v0's decision-period model (input held over control_dt_s; its ``model``
    # when one plant step is one decision): the transitions the learner sees
    model = getattr(env.unwrapped, "decision_model", None) or getattr(env.unwrapped, "model", None)
    try:
        if model is not None and hasattr(model, "A") and getattr(model, "dt_s", None) is not None:
            lin = model
        elif model is not None and hasattr(model, "discrete"):
            lin = model.discrete(input="wheel")
        else:
            return None
        A, B = np.asarray(lin.A, float), np.asarray(lin.B, float)
        Q, R, N = (getattr(lin, key, None) for key in ("Q", "R", "N"))
        M = np.eye(B.shape[1]) if input_map is None else input_map
        R = None if R is None else M.T @ np.asarray(R, float) @ M
        N = None if N is None else np.asarray(N, float) @ M
        return NominalModel(A, B @ M, None if Q is None else np.asarray(Q, float), R, N)
    except (ValueError, TypeError, AttributeError, np.linalg.LinAlgError):
        return None


def spectral_radius(model: NominalModel | None, K: np.ndarray) -> float | None:
    """ρ(A − BK) of the nominal model; ``None`` without one."""
    if model is None:
        return None
    A, B = model.A, model.B
    return float(np.max(np.abs(np.linalg.eigvals(A - B @ K))))


def optimal_gain(model: NominalModel | None, discount: float) -> np.ndarray | None:
    """DARE gain of the nominal model; ``None`` without a model or its cost weights."""
    if model is None or model.Q is None or model.R is None:
        return None
    A, B, Q, R, N = model
    try:
        return dlqr(A, B, Q, R, N, discount=discount)[0]
    except (ValueError, np.linalg.LinAlgError):
        return None
