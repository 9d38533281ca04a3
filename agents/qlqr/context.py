"""What the method strategies of one ``learn()`` call share (:class:`Context`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agents.qlqr.basis import QuadraticBasis
from agents.qlqr.data import Transitions
from agents.qlqr.estimators import Design, Estimator
from agents.qlqr.evaluation import PolicyEvaluation
from agents.qlqr.sampling import Sampler
from agents.qlqr.trace import Trace


@dataclass
class Context:
    """The agent's components and the call's settings, as the methods
    (:mod:`agents.qlqr.value_iteration`, :mod:`agents.qlqr.policy_iteration`) and the
    stabilizers (:mod:`agents.qlqr.stabilizers`) use them: batches from ``sampler``, their
    designs from ``basis``, ``estimator`` and ``evaluation`` strategies, results into
    ``trace``; the target ``discount`` γ, ``batch_size`` N of each fresh batch and the
    ``initial_gain`` (``None``: none given)."""

    sampler: Sampler
    basis: QuadraticBasis
    estimator: Estimator
    evaluation: PolicyEvaluation
    trace: Trace
    discount: float
    batch_size: int
    initial_gain: np.ndarray | None

    def collect(self, gain: np.ndarray) -> Transitions:
        """The next batch under the behaviour gain (the first one also fixes the feature scales)."""
        data = self.sampler.collect(self.batch_size, gain)
        self.basis.fit_scale(data)
        return data

    def design(self, data: Transitions, what: str) -> Design:
        return self.basis.design(data, what)

    def zero_gain(self) -> np.ndarray:
        return np.zeros((self.basis.m, self.basis.n))
