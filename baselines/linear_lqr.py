"""Model-based LQR on a discrete linear env (``LinearSystem-v0``): the Q-learning LQR's reference."""

from __future__ import annotations

from typing import Any

import numpy as np


class LinearLQRPolicy:
    """``u = −K x`` with ``K`` from :func:`attitude_envs.lqr.dlqr` on the env's nominal
    model of its decision period: ``env.unwrapped.decision_model`` (a discrete
    :class:`LinearModel` ``(A_k, B_k, Q_k, R_k, N_k)`` of ``control_dt_s``, the input held
    over the plant steps of a decision, cross term ``N_k`` included), else
    ``env.unwrapped.model``; at one plant step per decision both are the plant's
    ``(A, B, Q, R)``. The action is ``u / action_scale`` clipped to [-1, 1]."""

    def __init__(self, env, name: str = "lqr") -> None:
        base = env.unwrapped
        model = getattr(base, "decision_model", None) or getattr(base, "model", None)
        if getattr(model, "dt_s", None) is None or not hasattr(model, "lqr_gain"):
            raise ValueError("LinearLQRPolicy needs an env whose model is a discrete LinearModel (LinearSystem-v0)")
        self.name = name
        self.gain = model.lqr_gain()
        self._n = self.gain.shape[1]
        self._scale = np.broadcast_to(np.asarray(base.action_scale, dtype=float), (self.gain.shape[0],))

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        u = -self.gain @ np.asarray(obs, dtype=float)[: self._n]
        return np.clip(u / self._scale, -1.0, 1.0).astype(np.float32)
