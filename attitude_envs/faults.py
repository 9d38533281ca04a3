"""The one fault model of the suite (actuator stage), shared by every env.

A fault is a plain dict (YAML friendly)::

    {"kind": "loss_of_effectiveness", "target": "actuator", "index": 2, "value": 0.3,
     "onset_s": 20.0, "duration_s": None}

``index`` is an actuator index, ``"random"`` (drawn per episode) or ``"all"``;
``value``, ``onset_s`` and ``duration_s`` may be numbers or ``{"uniform": [low, high]}``
draws. Draws come from the env's RNG at ``reset``: same seed, same faults. A fault is
active for ``onset_s <= t < onset_s + duration_s`` (``duration_s`` None: permanent) and
the actuator recovers afterwards. Faults are evaluated at the start of each control step
and held over it.

=========================  ==================================================  =============
kind                       effect on the physical command ``u`` of actuator i  value
=========================  ==================================================  =============
loss_of_effectiveness      ``(1 − value) · u``                                 loss in [0, 1]
effectiveness              ``e(t) · u``; ``schedule`` ``[[t_s, e], ...]``      e in [0, 1]
                           piecewise-linear in absolute time (Sadigh et al. 2022's E(t)),
                           or a constant ``value``
bias                       ``u + value``                                       actuator units
drift                      ``u + value · (t − onset)``                         units per s
stuck                      held at ``value``, or at the command at onset if    actuator units
                           ``value`` is None
outage                     ``0``                                               —
saturation                 clipped to ``± value · limit``                      fraction [0, 1]
intermittent               ``0`` during off periods; on/off dwell times        —
                           exponential with means ``mean_on_s``, ``mean_off_s``
=========================  ==================================================  =============

The composite output is finally clipped to the actuator's own limit: a fault never makes
an actuator stronger than it is. Sensor faults (``"target": "sensor"``) use the same dict
format and live in :mod:`attitude_envs.sensors`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from attitude_envs import validation
from attitude_envs.plants.ops import PYTHON, Ops

ACTUATOR_KINDS = (
    "loss_of_effectiveness",
    "effectiveness",
    "bias",
    "drift",
    "stuck",
    "outage",
    "saturation",
    "intermittent",
)
#: kind code of each actuator fault kind (0: no fault, the JAX plants' padding)
KIND_CODES = {kind: code for code, kind in enumerate(ACTUATOR_KINDS, start=1)}
_COMMON_KEYS = {"kind", "target", "index", "value", "onset_s", "duration_s"}
_EXTRA_KEYS = {"effectiveness": {"schedule"}, "intermittent": {"mean_on_s", "mean_off_s"}}
_UNIT_VALUE = {"loss_of_effectiveness", "effectiveness", "saturation"}
_NEEDS_VALUE = {"loss_of_effectiveness", "bias", "drift", "saturation"}


def _draw(name: str, spec, rng: np.random.Generator | None, low: float | None = None, high: float | None = None):
    """A number, or a ``{"uniform": [a, b]}`` draw; checks the range ``[low, high]``."""
    if isinstance(spec, dict):
        if set(spec) != {"uniform"}:
            raise ValueError(f"{name} must be a number or {{'uniform': [low, high]}}, got {spec!r}")
        bounds = validation.finite_array(f"{name}.uniform", spec["uniform"], (2,))
        if bounds[0] > bounds[1]:
            raise ValueError(f"{name}.uniform needs low <= high, got {bounds.tolist()}")
        for b in bounds:
            _check_range(name, float(b), low, high)
        return None if rng is None else float(rng.uniform(bounds[0], bounds[1]))
    value = validation.number(name, spec, "a number or {'uniform': [low, high]}")
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite, got {spec!r}")
    _check_range(name, value, low, high)
    return value


def _check_range(name: str, value: float, low: float | None, high: float | None) -> None:
    if (low is not None and value < low) or (high is not None and value > high):
        lo = "-inf" if low is None else low
        hi = "inf" if high is None else high
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value}")


@functools.cache
def define_effect(ops: Ops) -> Callable:
    """``effect(kind, x, value, t_s, onset_s, effectiveness, latched, on)``: the output of one
    actuator's command ``x`` under an active fault of kind code ``kind`` (:data:`KIND_CODES`),
    the one statement of the table in the module docstring for every executor (the numba
    envs' layer here, the JAX plants, the CasADi model). ``value`` the fault's value (0.0
    where it has none), ``t_s`` and ``onset_s`` in s, ``effectiveness`` the value or the
    schedule at ``t_s`` (1.0 for other kinds), ``latched`` a stuck fault's held output,
    ``on`` an intermittent fault's phase. Saturation acts on the limit, not here (the output
    is ``x``)."""
    where = ops.where
    loe, eff, bias, drift, stuck, outage, _, inter = (KIND_CODES[k] for k in ACTUATOR_KINDS)

    @ops.compile
    def effect(kind, x, value, t_s, onset_s, effectiveness, latched, on):
        out = where(kind == inter, where(on, x, 0.0), x)
        out = where(kind == outage, 0.0, out)
        out = where(kind == stuck, latched, out)
        out = where(kind == drift, x + value * (t_s - onset_s), out)
        out = where(kind == bias, x + value, out)
        out = where(kind == eff, x * effectiveness, out)
        return where(kind == loe, x * (1.0 - value), out)

    return effect


_effect = define_effect(PYTHON)


@dataclass
class RealizedFault:
    """One fault on one actuator in one episode, with every draw made (ground truth)."""

    kind: str
    index: int
    value: float | None
    onset_s: float
    duration_s: float | None
    schedule: np.ndarray | None = None
    mean_on_s: float = 1.0
    mean_off_s: float = 1.0
    # Runtime state, kept by the fault layer as the episode runs: the stuck value once
    # latched, and an intermittent fault's on/off phase and next switch time (s).
    held: float | None = field(default=None, repr=False)
    on: bool = field(default=True, repr=False)
    next_switch_s: float | None = field(default=None, repr=False)

    def active(self, t_s: float) -> bool:
        end = np.inf if self.duration_s is None else self.onset_s + self.duration_s
        return self.onset_s <= t_s < end

    def as_dict(self) -> dict:
        d = {"kind": self.kind, "target": "actuator", "index": self.index, "value": self.value}
        d.update({"onset_s": self.onset_s, "duration_s": self.duration_s})
        if self.schedule is not None:
            d["schedule"] = self.schedule.tolist()
        return d


def validate_fault(config: dict, n_actuators: int, where: str = "faults") -> None:
    """Check one fault dict without drawing anything; raises ``ValueError`` naming the field."""
    if not isinstance(config, dict):
        raise ValueError(f"{where} entries must be dicts, got {config!r}")
    kind = validation.choice(f"{where}.kind", config.get("kind"), ACTUATOR_KINDS)
    target = config.get("target", "actuator")
    validation.choice(f"{where}.target", target, {"actuator"})
    validation.known_keys(f"{where} ({kind})", config, _COMMON_KEYS | _EXTRA_KEYS.get(kind, set()))
    index = config.get("index", "random")
    if isinstance(index, str):
        validation.choice(f"{where}.index", index, {"random", "all"})
    elif not (isinstance(index, (int, np.integer)) and 0 <= int(index) < n_actuators):
        raise ValueError(
            f"{where}.index must be an integer in [0, {n_actuators - 1}], 'random' or 'all', got {index!r}"
        )
    value = config.get("value")
    if kind in _NEEDS_VALUE and value is None:
        raise ValueError(f"{where}.value is required for kind {kind!r}")
    if value is not None:
        unit = kind in _UNIT_VALUE
        _draw(f"{where}.value", value, None, 0.0 if unit else None, 1.0 if unit else None)
    if kind == "effectiveness":
        if (value is None) == (config.get("schedule") is None):
            raise ValueError(f"{where} (effectiveness) needs exactly one of 'value' or 'schedule'")
        if config.get("schedule") is not None:
            _schedule(f"{where}.schedule", config["schedule"])
    _draw(f"{where}.onset_s", config.get("onset_s", 0.0), None, 0.0, None)
    if config.get("duration_s") is not None:
        _draw(f"{where}.duration_s", config["duration_s"], None, 0.0, None)
    if kind == "intermittent":
        for key in ("mean_on_s", "mean_off_s"):
            validation.positive(f"{where}.{key}", config.get(key, 1.0))


def _schedule(name: str, value) -> np.ndarray:
    sched = validation.finite_array(name, value)
    if sched.ndim != 2 or sched.shape[1] != 2 or sched.shape[0] < 1:
        raise ValueError(f"{name} must be a list of [t_s, effectiveness] pairs, got shape {sched.shape}")
    if np.any(np.diff(sched[:, 0]) < 0):
        raise ValueError(f"{name} times must be non-decreasing")
    if np.any((sched[:, 1] < 0) | (sched[:, 1] > 1)):
        raise ValueError(f"{name} effectiveness values must be in [0, 1]")
    return sched


class ActuatorFaults:
    """Applies a list of fault dicts to the physical commands of ``n_actuators`` actuators.

    ``limits`` are the actuators' own output limits (physical units), used by the
    ``saturation`` kind and the final clip. Entries whose ``target`` is in
    ``other_targets`` (e.g. ``{"sensor"}`` in envs with a :class:`~attitude_envs.sensors.SensorSuite`)
    are left to that layer; any other non-actuator target raises ``ValueError``.
    """

    def __init__(self, configs: list[dict] | None, n_actuators: int, limits, other_targets=()) -> None:
        self.n = int(n_actuators)
        self.other_targets = frozenset(other_targets)
        self.limits = np.broadcast_to(np.asarray(limits, dtype=float), (self.n,)).copy()
        self.configs = self._validated(configs)
        self.realized: list[RealizedFault] = []

    def _validated(self, configs) -> list[dict]:
        if configs is None:
            return []
        if not isinstance(configs, (list, tuple)):
            raise ValueError(f"faults must be a list of fault dicts, got {configs!r}")
        mine = [
            (i, c) for i, c in enumerate(configs) if not (isinstance(c, dict) and c.get("target") in self.other_targets)
        ]
        for i, c in mine:
            validate_fault(c, self.n, where=f"faults[{i}]")
        return [dict(c) for _, c in mine]

    def reset(self, rng: np.random.Generator, configs: list[dict] | None = None) -> None:
        """Draw this episode's faults (``configs`` replaces the construction-time list)."""
        chosen = self.configs if configs is None else self._validated(configs)
        self.realized = []
        for i, c in enumerate(chosen):
            where = f"faults[{i}]"
            kind = c["kind"]
            index = c.get("index", "random")
            if index == "random":
                indices = [int(rng.integers(self.n))]
            elif index == "all":
                indices = list(range(self.n))
            else:
                indices = [int(index)]
            unit = kind in _UNIT_VALUE
            value = c.get("value")
            onset = _draw(f"{where}.onset_s", c.get("onset_s", 0.0), rng, 0.0)
            duration = None if c.get("duration_s") is None else _draw(f"{where}.duration_s", c["duration_s"], rng, 0.0)
            for idx in indices:
                v = (
                    None
                    if value is None
                    else _draw(f"{where}.value", value, rng, 0.0 if unit else None, 1.0 if unit else None)
                )
                schedule = None if c.get("schedule") is None else _schedule(f"{where}.schedule", c["schedule"])
                self.realized.append(
                    RealizedFault(
                        kind,
                        idx,
                        v,
                        onset,
                        duration,
                        schedule,
                        float(c.get("mean_on_s", 1.0)),
                        float(c.get("mean_off_s", 1.0)),
                    )
                )
        self._rng = rng

    def apply(self, commanded: np.ndarray, t_s: float) -> np.ndarray:
        """The physical outputs the actuators deliver for ``commanded`` at time ``t_s``."""
        if not self.realized:
            return commanded
        out = np.array(commanded, dtype=float)
        limit = self.limits.copy()
        for f in self.realized:
            i = f.index
            if f.kind == "intermittent":
                self._advance_intermittent(f, t_s)
            if not f.active(t_s):
                f.held = None
                continue
            if f.kind == "saturation":
                limit[i] = min(limit[i], f.value * self.limits[i])
                continue
            if f.kind == "stuck" and f.held is None:
                f.held = float(out[i]) if f.value is None else f.value
            eff = 1.0
            if f.kind == "effectiveness":
                eff = f.value if f.schedule is None else float(np.interp(t_s, f.schedule[:, 0], f.schedule[:, 1]))
            value = 0.0 if f.value is None else f.value
            out[i] = _effect(KIND_CODES[f.kind], float(out[i]), value, t_s, f.onset_s, eff, f.held, f.on)
        return np.clip(out, -limit, limit)

    def _advance_intermittent(self, f: RealizedFault, t_s: float) -> None:
        if f.next_switch_s is None:
            f.on = False
            f.next_switch_s = f.onset_s + self._rng.exponential(f.mean_off_s)
        while t_s >= f.next_switch_s:
            f.on = not f.on
            f.next_switch_s += self._rng.exponential(f.mean_on_s if f.on else f.mean_off_s)

    def active_flags(self, t_s: float) -> np.ndarray:
        """1.0 per actuator with an active fault at ``t_s``, else 0.0 (the ``fault_hint``)."""
        flags = np.zeros(self.n)
        for f in self.realized:
            if f.active(t_s):
                flags[f.index] = 1.0
        return flags

    def info(self, t_s: float) -> list[dict]:
        """Ground truth for ``info["faults"]``: every fault of the episode and whether it is active."""
        return [dict(f.as_dict(), active=bool(f.active(t_s))) for f in self.realized]
