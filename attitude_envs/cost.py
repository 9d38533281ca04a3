"""The one cost every env and controller is scored on: J = ∫ (xᵀQx + uᵀRu) dt.

Each env defines its error state ``x`` and physical input ``u``; this module holds the
weights and their evaluation. Envs integrate the stage cost next to the plant, with the
same integrator, so the reward does not depend on the control period (DESIGN "One cost").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude_envs import validation


@dataclass(frozen=True)
class QuadraticCost:
    """Weights of ``xᵀQx + uᵀRu`` (per second for continuous-time envs, per step for
    discrete ones). ``Q`` is n×n positive semi-definite, ``R`` m×m positive definite; a
    scalar or a vector is taken as a diagonal."""

    Q: np.ndarray
    R: np.ndarray

    @classmethod
    def build(cls, Q, R, n: int, m: int) -> QuadraticCost:
        return cls(validation.psd_matrix("Q", Q, n), validation.psd_matrix("R", R, m, definite=True))

    @property
    def n(self) -> int:
        return self.Q.shape[0]

    @property
    def m(self) -> int:
        return self.R.shape[0]

    def stage(self, x: np.ndarray, u: np.ndarray) -> float:
        """``xᵀQx + uᵀRu``."""
        return float(x @ self.Q @ x + u @ self.R @ u)
