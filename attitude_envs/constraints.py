"""Path constraints of an attitude maneuver as objects: keep-out cones, wheel-speed and
body-rate limits.

**Sign convention (the one place it is stated).** Every constraint is a function
``g(x, u) ≤ 0``: it is *satisfied* when ``g ≤ 0`` and *violated* when ``g > 0``; the size of a
positive ``g`` says by how much, in the constraint's :attr:`Constraint.units`. This is the
sign of Safety-Gymnasium's costs and of an NLP's inequality ``g(x) ≤ 0`` (CasADi's ``ubg = 0``);
a control barrier function's safe set ``h ≥ 0`` is ``h = −g``.

The state ``x`` is the gyrostat's physical state row ``[q (4, scalar last, body to inertial),
ω (3, rad/s, body axes), Ω (N, rad/s, wheel speeds relative to the body)]``, as
:attr:`attitude_envs.envs.reaction_wheel.ReactionWheelEnv.state_row` and
``info["truth"]["state"]`` (a mapping with ``attitude``, ``rate_rad_s`` and
``wheel_speed_rad_s``) hold it; :meth:`Constraint.value` takes either. The constraints here
depend on the state only; ``u`` is accepted (and ignored) so that input constraints fit the
same call.

============================  ===================================================  ==========
constraint                    g                                                    units
============================  ===================================================  ==========
:class:`KeepOutCone`          ``cos θ − cos α``, θ the angle between the body      —
                              axis rotated to inertial, ``R(q) b``, and the        (cosine)
                              inertial direction ``s``; α the half-angle
:class:`WheelSpeedLimit`      ``max_i |Ω_i| − limit`` (or per wheel)               rad/s
:class:`BodyRateLimit`        ``max_k |ω_k| − limit`` (largest body-axis rate)     rad/s
============================  ===================================================  ==========

A keep-out cone also gives its margin in degrees, ``θ − α`` (:meth:`KeepOutCone.margin_deg`:
positive outside the cone, negative inside; the opposite sign of ``g``, as a margin is).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from attitude_envs import quaternion

__all__ = [
    "BodyRateLimit",
    "Constraint",
    "KeepOutCone",
    "WheelSpeedLimit",
    "episode_summary",
    "split_state",
]


def split_state(state: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, ω, Ω)`` of a physical state: a row ``[q (4), ω (3), Ω (N)]``, a mapping with
    ``attitude``, ``rate_rad_s`` and ``wheel_speed_rad_s`` (``info["truth"]["state"]``), or a
    quaternion alone (4 entries: at rest, no wheels)."""
    if isinstance(state, Mapping):
        return (
            np.asarray(state["attitude"], dtype=float),
            np.asarray(state["rate_rad_s"], dtype=float),
            np.asarray(state.get("wheel_speed_rad_s", np.zeros(0)), dtype=float),
        )
    y = np.asarray(state, dtype=float)
    if y.shape == (4,):  # an attitude alone: at rest, no wheels
        return y, np.zeros(3), np.zeros(0)
    if y.ndim != 1 or y.shape[0] < 7:
        raise ValueError(
            f"state must be a row [q (4), ω (3), Ω (N)] of at least 7 entries or a quaternion (4), got shape {y.shape}"
        )
    return y[:4], y[4:7], y[7:]


def _unit(name: str, value) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a unit vector (|v| = 1 ± 1e-6), got |v| = {norm:.9g}")
    return v / norm


def _positive_limit(name: str, value) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be in (0, inf), got {value!r}")
    return v


class Constraint(ABC):
    """One path constraint ``g(x, u) ≤ 0`` (satisfied when ``g ≤ 0``; see the module)."""

    #: a short identifier, unique within an env (the key of ``info["constraints"]``)
    name: str
    #: the unit of ``g``
    units: str

    @abstractmethod
    def value(self, state: Any, u: np.ndarray | None = None) -> float | np.ndarray:
        """``g`` at ``state`` (see :func:`split_state`); ``> 0`` is a violation."""

    def violated(self, state: Any, u: np.ndarray | None = None) -> bool:
        """Whether ``g > 0`` (any entry, for a vector ``g``)."""
        return bool(np.any(np.asarray(self.value(state, u)) > 0.0))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"


class KeepOutCone(Constraint):
    """A body axis that must stay out of a cone about an inertial direction: a star
    tracker's boresight and the Sun, say.

    ``g = cos θ − cos α`` with ``cos θ = s · R(q) b`` (``b`` the unit body axis, ``s`` the
    unit inertial direction, ``R(q)`` body to inertial: :func:`attitude_envs.quaternion.to_matrix`)
    and α = ``half_angle_deg``: ``g > 0`` exactly when the axis is inside the cone (θ < α).
    ``g`` is smooth in ``q`` (a cosine, not an angle) for solvers and barrier functions;
    :meth:`margin_deg` gives ``θ − α`` in degrees.
    """

    units = "—"

    def __init__(self, body_axis, inertial_direction, half_angle_deg: float, name: str = "keep_out") -> None:
        self.body_axis = _unit("body_axis", body_axis)
        self.inertial_direction = _unit("inertial_direction", inertial_direction)
        a = float(half_angle_deg)
        if not (math.isfinite(a) and 0.0 < a < 90.0):
            raise ValueError(f"half_angle_deg must be in (0, 90), got {half_angle_deg!r}")
        self.half_angle_deg = a
        self.cos_half_angle = math.cos(math.radians(a))
        self.name = str(name)

    def cos_angle(self, state: Any, rotation: np.ndarray | None = None) -> float:
        """``cos θ = s · R(q) b``, the cosine of the angle between the axis and the direction
        (``rotation``: ``R(q)`` when the caller has it already)."""
        if rotation is None:
            rotation = quaternion.to_matrix(split_state(state)[0])
        return float(self.inertial_direction @ (rotation @ self.body_axis))

    def value(self, state: Any, u: np.ndarray | None = None) -> float:
        return self.cos_angle(state) - self.cos_half_angle

    def angle_deg(self, state: Any) -> float:
        """θ, the angle between the body axis (in inertial axes) and the direction, deg in [0, 180]."""
        return self.angle_deg_of(self.cos_angle(state))

    @staticmethod
    def angle_deg_of(cos_angle: float) -> float:
        """θ in degrees, [0, 180], from its cosine (clipped to [−1, 1])."""
        return math.degrees(math.acos(min(1.0, max(-1.0, cos_angle))))

    def margin_deg(self, state: Any) -> float:
        """``θ − α`` in degrees: positive outside the cone, negative inside."""
        return self.angle_deg(state) - self.half_angle_deg

    def direction_in_body(self, state: Any) -> np.ndarray:
        """The inertial direction in body axes, ``R(q)ᵀ s`` (what a sensor on board sees)."""
        q = split_state(state)[0]
        return quaternion.to_matrix(q).T @ self.inertial_direction


class WheelSpeedLimit(Constraint):
    """Wheel speeds within ``limit_rad_s``: ``g = max_i |Ω_i| − limit`` (rad/s), or the
    vector ``|Ω_i| − limit`` with ``per_wheel=True``."""

    units = "rad/s"

    def __init__(self, limit_rad_s: float, per_wheel: bool = False, name: str = "wheel_speed") -> None:
        self.limit_rad_s = _positive_limit("limit_rad_s", limit_rad_s)
        self.per_wheel = bool(per_wheel)
        self.name = str(name)

    def value(self, state: Any, u: np.ndarray | None = None) -> float | np.ndarray:
        speeds = np.abs(split_state(state)[2])
        if self.per_wheel:
            return speeds - self.limit_rad_s
        return float(speeds.max(initial=0.0)) - self.limit_rad_s


class BodyRateLimit(Constraint):
    """Body rate within ``limit_rad_s`` on every body axis: ``g = max_k |ω_k| − limit``
    (rad/s; the largest component, as the envs' tumbling limit measures it)."""

    units = "rad/s"

    def __init__(self, limit_rad_s: float, name: str = "body_rate") -> None:
        self.limit_rad_s = _positive_limit("limit_rad_s", limit_rad_s)
        self.name = str(name)

    def value(self, state: Any, u: np.ndarray | None = None) -> float:
        return float(np.abs(split_state(state)[1]).max()) - self.limit_rad_s


def episode_summary(infos: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """An episode's constraint outcome from its infos (the reset's first, then every step's) where
    the env reports constraints (``info["violations"]``, ConstrainedSlew-v0's; else ``{}``):
    ``violations`` (the steps that violated any constraint), ``violations_<name>`` per constraint,
    and ``min_margin_deg``, the least keep-out cone margin over the episode's decision times (deg,
    negative inside a cone; NaN without cones)."""
    if not infos or "violations" not in infos[-1]:
        return {}
    last = infos[-1]
    margins = [m for info in infos for m in info.get("constraint_margins_deg", {}).values()]
    out = {"violations": int(last["violations"])}
    out |= {f"violations_{name}": int(n) for name, n in last.get("violations_by_constraint", {}).items()}
    out["min_margin_deg"] = float(min(margins)) if margins else float("nan")
    return out
