"""The actuator fault layer (:class:`attitude_envs.faults.ActuatorFaults`) as a CasADi
expression of the step's start time: the episode's realized faults are known (an oracle).

Mirrors :meth:`~attitude_envs.faults.ActuatorFaults.apply` operation by operation (the faults
in their list order, each active for ``onset_s <= t < onset_s + duration_s``, then the clip
at the possibly reduced limit), so the symbolic command equals the env's to rounding.
"""

from __future__ import annotations

import casadi
import numpy as np

from attitude_envs.faults import KIND_CODES, define_effect
from attitude_envs.symbolic.ops import CASADI

_effect = define_effect(CASADI)

#: fault kinds the symbolic model represents (deterministic given the episode's draws)
SUPPORTED = ("loss_of_effectiveness", "effectiveness", "bias", "drift", "stuck", "outage", "saturation")


def check_supported(realized) -> None:
    """Raise ValueError for a realized fault the symbolic model cannot represent."""
    for f in realized:
        if f.kind not in SUPPORTED:
            raise ValueError(
                f"faults: kind {f.kind!r} has no symbolic model (random switching); accepted: {list(SUPPORTED)}"
            )
        if f.kind == "stuck" and f.value is None:
            raise ValueError("faults: kind 'stuck' needs a value for the symbolic model (the held command is unknown)")


def clip(v, lo, hi):
    """``min(max(v, lo), hi)`` elementwise."""
    return casadi.fmin(casadi.fmax(v, lo), hi)


def _schedule_value(schedule: np.ndarray, t):
    """``np.interp(t, schedule[:, 0], schedule[:, 1])`` as an expression (clamped at the ends)."""
    times, values = schedule[:, 0], schedule[:, 1]
    out = casadi.SX(float(values[0]))
    for j in range(1, len(times)):
        t0, t1, v0, v1 = float(times[j - 1]), float(times[j]), float(values[j - 1]), float(values[j])
        if t1 > t0:
            out = casadi.if_else(t >= t0, v0 + (v1 - v0) * (t - t0) / (t1 - t0), out)
        out = casadi.if_else(t >= t1, v1, out)
    return out


def delivered(commanded, t, realized, limits: np.ndarray):
    """The actuator outputs (SX column) for the ``commanded`` outputs (SX column, physical
    units) at the step's start time ``t`` (SX scalar, s) with the realized faults
    ``realized`` (:attr:`ActuatorFaults.realized`) and the actuators' limits ``limits``."""
    if not realized:
        return commanded  # the fault layer returns the command unchanged (no clip)
    check_supported(realized)
    out = [commanded[i] for i in range(commanded.shape[0])]
    limit = [casadi.SX(float(v)) for v in limits]
    for f in realized:
        i = f.index
        end = np.inf if f.duration_s is None else f.onset_s + f.duration_s
        active = t >= f.onset_s if not np.isfinite(end) else casadi.logic_and(t >= f.onset_s, t < end)
        if f.kind == "saturation":
            limit[i] = casadi.if_else(active, casadi.fmin(limit[i], f.value * float(limits[i])), limit[i])
            continue
        value = 0.0 if f.value is None else float(f.value)
        eff = 1.0
        if f.kind == "effectiveness":
            eff = f.value if f.schedule is None else _schedule_value(f.schedule, t)
        latched = casadi.SX(value)  # a stuck fault's value (one without is refused above)
        new = _effect(KIND_CODES[f.kind], out[i], value, t, f.onset_s, eff, latched, True)
        out[i] = casadi.if_else(active, new, out[i])
    return casadi.vertcat(*[clip(out[i], -limit[i], limit[i]) for i in range(len(out))])
