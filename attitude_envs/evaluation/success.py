"""What a successful episode is, per env: every env class declares a :class:`SuccessMetric`.

``env.unwrapped.success_metric`` names the quantity judged at the end of an episode, its
unit, its default threshold and the criterion as one line for reports, and computes it from
the episode's first info (after ``reset``) and last info (after the last ``step``):

==========================  ======================================================  ========  =========
metric                      value                                                   unit      threshold
==========================  ======================================================  ========  =========
``final_error_deg``         ``truth["error_angle_deg"]`` of the last info           deg       2.0
``final_state_fraction``    norm of the true state at the end / at the start        1         0.1
==========================  ======================================================  ========  =========

ReactionWheel-v0, AirBearing-v0 and Magnetorquer-v0 use ``final_error_deg``;
LinearSystem-v0 and FuelSlosh-v0 ``final_state_fraction`` (:func:`true_state_norm`).
An episode meets its metric when the value is at most the threshold. Campaigns also require a
finite J and an episode that was not terminated (``experiments.campaign``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from attitude_envs.info import TRUTH

Info = Mapping[str, Any]


@dataclass(frozen=True)
class SuccessMetric:
    """How an env judges an episode: ``measure`` one info (``quantity``, e.g. ``error_deg``)
    and compare it at the end with ``threshold`` (``relative``: with ``threshold`` × its value
    at the start). ``criterion`` is the report's line, with ``{threshold:g}`` for the threshold."""

    name: str
    unit: str
    threshold: float
    criterion: str
    quantity: str
    measure: Callable[[Info], float]
    relative: bool = False

    def value(self, first: Info, last: Info) -> float:
        """The metric of an episode, in :attr:`unit` (a relative one from a zero start: 0 if it
        ends at zero too, else inf)."""
        end = self.measure(last)
        if not self.relative:
            return end
        start = self.measure(first)
        if start == 0.0:
            return 0.0 if end == 0.0 else math.inf
        return end / start

    def succeeded(self, first: Info, last: Info, threshold: float | None = None) -> bool:
        """Whether the episode meets the metric: value ≤ ``threshold`` (default :attr:`threshold`),
        compared as ``end ≤ threshold × start`` for a relative metric (no division)."""
        limit = self.threshold if threshold is None else float(threshold)
        end = self.measure(last)
        return bool(end <= limit * self.measure(first) if self.relative else end <= limit)

    def measurements(self, first: Info, last: Info) -> dict[str, float]:
        """The measured values the decision compares, named for tables: ``final_<quantity>``,
        and ``initial_<quantity>`` first for a relative metric (in :attr:`unit` for an absolute
        metric, in the quantity's own units for a relative one)."""
        end = {f"final_{self.quantity}": self.measure(last)}
        return {f"initial_{self.quantity}": self.measure(first), **end} if self.relative else end

    def measurement_names(self) -> tuple[str, ...]:
        """The keys of :meth:`measurements`, in its order."""
        end = f"final_{self.quantity}"
        return (f"initial_{self.quantity}", end) if self.relative else (end,)

    def met(self, measurements: Mapping[str, float], threshold: float | None = None) -> bool:
        """Whether the episode whose :meth:`measurements` these are meets the metric at
        ``threshold`` (default :attr:`threshold`): the same comparison as :meth:`succeeded`
        (``end ≤ threshold × start`` for a relative metric), so the two always agree. A NaN
        measurement never meets it; KeyError when a measurement of this metric is missing."""
        limit = self.threshold if threshold is None else float(threshold)
        end = float(measurements[f"final_{self.quantity}"])
        if self.relative:
            return bool(end <= limit * float(measurements[f"initial_{self.quantity}"]))
        return bool(end <= limit)

    def describe(self, threshold: float | None = None) -> str:
        """The criterion as one line, e.g. ``final attitude error ≤ 2°``."""
        return self.criterion.format(threshold=self.threshold if threshold is None else float(threshold))


def error_angle_deg(info: Info) -> float:
    """The attitude error angle of an info's truth, deg."""
    return float(info[TRUTH]["error_angle_deg"])


def true_state_norm(info: Info) -> float:
    """Euclidean norm of the true state the cost weighs, in the env's state units:
    ``truth["x"]`` where the env has one (FuelSlosh-v0's reduced states), else
    ``truth["state"]`` (an array, or a mapping of arrays, flattened in order)."""
    truth = info[TRUTH]
    state = truth["x"] if "x" in truth else truth["state"]
    if isinstance(state, Mapping):
        state = np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in state.values()])
    return float(np.linalg.norm(np.asarray(state, dtype=float)))


FINAL_ERROR_DEG = SuccessMetric(
    name="final_error_deg",
    unit="deg",
    threshold=2.0,
    criterion="final attitude error ≤ {threshold:g}°",
    quantity="error_deg",
    measure=error_angle_deg,
)

FINAL_STATE_FRACTION = SuccessMetric(
    name="final_state_fraction",
    unit="1",
    threshold=0.1,
    criterion="final state norm ≤ {threshold:g} × the initial state norm (true state)",
    quantity="state_norm",
    measure=true_state_norm,
    relative=True,
)

#: the metrics envs declare, by :attr:`SuccessMetric.name`
METRICS: dict[str, SuccessMetric] = {m.name: m for m in (FINAL_ERROR_DEG, FINAL_STATE_FRACTION)}


#: the prefixes of the constraint outcome beside a success metric's measurements
#: (:func:`attitude_envs.constraints.episode_summary`)
CONSTRAINT_KEYS = ("violations", "min_margin_deg")


def metric_of(names: Iterable[str]) -> SuccessMetric | None:
    """The metric of :data:`METRICS` whose :meth:`~SuccessMetric.measurements` are the keys
    ``names`` (e.g. ``{"final_error_deg"}``), besides the constraint outcome an env with
    constraints adds (:data:`CONSTRAINT_KEYS`), or None when none is."""
    have = {n for n in names if not n.startswith(CONSTRAINT_KEYS)}
    return next((m for m in METRICS.values() if set(m.measurement_names()) == have), None)
