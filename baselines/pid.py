"""Per-axis PID on 3-2-1 Euler-angle errors, fixed or state-dependent gains, from the air-bearing
GA-tuned PID paper (Ahangarani Farahani, Adami & Arefkhani; year unknown).

Control law (eq. 18), one channel per Euler angle ``i ∈ (φ, θ, ψ)``::

    T_c,i = Kp_i e_i + Kd_i ė_i + KI_i ∫ e_i dt,    e = r − y,  ė = ṙ − ẏ

with ``y`` the 3-2-1 Euler angles of the attitude *relative to the target* (``q_e = q_T* ⊗ q``,
so ``r = 0``; equal to the paper's angles for its target 0), ``ẏ`` their rates from the body
rate by eq. 14 (target at rest), errors in **rad** and gains in SI (N·m/rad, N·m·s/rad,
N·m/(rad·s)) — assumed: the paper gives no units. ``T_c`` is the body-torque command
(assumed), mapped to the
env's wheels by :class:`baselines.allocation.WheelAllocator` (default ``saturation="clip"``
for one wheel per body axis: each of the air bearing's three orthogonal wheels saturates on its
own axis, as in the paper; ``"scale"`` for other wheel sets, e.g. ReactionWheel-v0's pyramid). The
integral is a forward-Euler sum over control periods, without anti-windup (assumed), and the
yaw error is wrapped to (−180°, 180°] by the Euler extraction (assumed).

State-dependent gains (eq. 23–24): ``K = k1 + k2·y_i + k3·ẏ_i`` per gain and channel, with
``y_i, ẏ_i`` in rad and rad/s (``units="rad"``, default) or deg and deg/s (``units="deg"``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.euler import euler_321_rad, euler_321_rad_batch, euler_321_rates, euler_321_rates_batch
from attitude_envs.info import MEASURED
from baselines.allocation import WheelAllocator

UNITS = ("rad", "deg")
GAIN_NAMES = ("kp", "kd", "ki")
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class PIDGains:
    """Fixed gains per channel (roll, pitch, yaw): ``kp`` N·m/rad, ``kd`` N·m·s/rad, ``ki`` N·m/(rad·s)."""

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray

    def __post_init__(self) -> None:
        for name in GAIN_NAMES:
            object.__setattr__(self, name, validation.finite_array(name, getattr(self, name), (3,)).copy())

    @classmethod
    def from_vector(cls, genes) -> PIDGains:
        """From ``[Kp, Kd, KI] × (roll, pitch, yaw)`` = ``[Kpφ, Kdφ, KIφ, Kpθ, ..., KIψ]`` (9)."""
        g = validation.finite_array("genes", genes, (9,)).reshape(3, 3)
        return cls(g[:, 0], g[:, 1], g[:, 2])

    def as_vector(self) -> np.ndarray:
        return np.column_stack([self.kp, self.kd, self.ki]).ravel()

    def at(self, angle_rad, rate_rad_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.kp, self.kd, self.ki

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "fixed", "kp": self.kp.tolist(), "kd": self.kd.tolist(), "ki": self.ki.tolist()}


@dataclass(frozen=True)
class GainSchedule:
    """State-dependent gains of eq. 23: ``coefficients[g, i] = (k1, k2, k3)`` for gain
    ``g ∈ (Kp, Kd, KI)`` and channel ``i ∈ (roll, pitch, yaw)``; ``K = k1 + k2 y_i + k3 ẏ_i``
    with ``y_i, ẏ_i`` in ``units`` ("rad": rad, rad/s; "deg": deg, deg/s). ``k1`` carries the
    gain's SI unit, ``k2`` that unit per angle unit, ``k3`` per angle-rate unit."""

    coefficients: np.ndarray
    units: str = "rad"

    def __post_init__(self) -> None:
        c = validation.finite_array("coefficients", self.coefficients, (3, 3, 3)).copy()
        object.__setattr__(self, "coefficients", c)
        object.__setattr__(self, "units", validation.choice("units", self.units, set(UNITS)))

    def at(self, angle_rad, rate_rad_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Kp, Kd, KI)`` (3 each) at the channels' angles (rad) and angle rates (rad/s), eq. 23;
        for a batch (E, 3) of angles and rates, each gain is E × 3."""
        scale = 1.0 if self.units == "rad" else 180.0 / math.pi
        y = np.asarray(angle_rad, dtype=float)[..., None, :] * scale
        y_dot = np.asarray(rate_rad_s, dtype=float)[..., None, :] * scale
        c = self.coefficients
        k = c[:, :, 0] + c[:, :, 1] * y + c[:, :, 2] * y_dot
        return k[..., 0, :], k[..., 1, :], k[..., 2, :]

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "schedule",
            "units": self.units,
            "coefficients": {
                g: {a: self.coefficients[gi, ai].tolist() for ai, a in enumerate(AXES)}
                for gi, g in enumerate(GAIN_NAMES)
            },
        }


#: The air-bearing PID paper's Table 3: the GA-tuned fixed gains (a PD: KI = 0).
PAPER_FIXED = PIDGains(kp=[2.625, 3.812, 2.2378], kd=[4.14, 12.38, 10.124], ki=[0.0, 0.0, 0.0])

#: The air-bearing PID paper's eq. 24 as printed: [gain][axis] = (k1, k2, k3); Kp_ψ's k3 sign
#: is lost in the source, assumed +0.03 (``paper_schedule(kp_yaw_rate_sign=-1)`` for the other
#: reading).
_EQ24 = np.array(
    [
        [[4.07, 0.023, 0.13], [3.32, 0.12, 0.074], [1.83, -0.03, 0.03]],  # Kp
        [[5.08, 0.04, 0.09], [4.22, 0.4, -0.2], [2.8, -0.0314, 0.158]],  # Kd
        [[0.17, 0.0134, -0.023], [0.1, -0.01, -0.022], [0.05, 0.01, -0.037]],  # KI
    ]
)


def paper_schedule(units: str = "rad", kp_yaw_rate_sign: float = 1.0) -> GainSchedule:
    """The state-dependent gains of eq. 24, schedule arguments in ``units`` ("rad" or "deg")."""
    if kp_yaw_rate_sign not in (1.0, -1.0):
        raise ValueError(f"kp_yaw_rate_sign must be +1 or -1, got {kp_yaw_rate_sign!r}")
    c = _EQ24.copy()
    c[0, 2, 2] *= kp_yaw_rate_sign
    return GainSchedule(c, units)


def gains_from_dict(doc: dict[str, Any]) -> PIDGains | GainSchedule:
    """Inverse of ``to_dict`` (the gains file written by ``tune-pid``)."""
    kind = validation.choice("gains kind", doc.get("kind"), {"fixed", "schedule"})
    if kind == "fixed":
        return PIDGains(doc["kp"], doc["kd"], doc["ki"])
    coeffs = doc["coefficients"]
    c = np.array([[coeffs[g][a] for a in AXES] for g in GAIN_NAMES], dtype=float)
    return GainSchedule(c, doc.get("units", "rad"))


def load_gains(path: str | Path) -> PIDGains | GainSchedule:
    """Gains from a JSON file written by ``tune-pid`` (the ``"gains"`` entry, or the whole file)."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    return gains_from_dict(doc.get("gains", doc))


class PIDPolicy:
    """Per-axis Euler-angle PID (fixed or scheduled gains) on any attitude env whose ``info``
    carries the measured state ``measured`` (attitude, rate, target) and whose model has wheel
    axes and a torque limit (ReactionWheel-v0, AirBearing-v0). Policy interface of
    :mod:`baselines.base`."""

    def __init__(
        self, env, gains: PIDGains | GainSchedule, name: str | None = None, saturation: str | None = None
    ) -> None:
        if not isinstance(gains, PIDGains | GainSchedule):
            raise ValueError(f"gains must be PIDGains or GainSchedule, got {type(gains).__name__}")
        base = env.unwrapped
        self.gains = gains
        self.dt_s = float(base.control_dt_s)
        if saturation is None:  # per-axis clipping on one wheel per body axis (the paper); else keep direction
            axes = base.model.params.wheel_axes
            orthogonal = axes.shape[1] == 3 and np.allclose(np.abs(axes), np.eye(3))
            saturation = "clip" if orthogonal else "scale"
        self.allocator = WheelAllocator.for_env(env, saturation=saturation)
        self.name = name or ("pid-fixed" if isinstance(gains, PIDGains) else f"pid-scheduled-{gains.units}")
        self._integral = np.zeros(3)
        self.last_torque_nm = np.zeros(3)

    @classmethod
    def from_file(cls, env, path: str | Path, **kwargs: Any) -> PIDPolicy:
        return cls(env, load_gains(path), **kwargs)

    def reset(self, seed: int | None = None) -> None:
        self._integral = np.zeros(3)

    def reset_rows(self, mask) -> None:
        """Batched use: zero the integral of the rows in ``mask`` (E booleans; the sub-envs
        that started a new episode)."""
        if self._integral.ndim == 2:
            self._integral[np.asarray(mask, dtype=bool)] = 0.0

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized wheel action for one step (obs (n,), ``info["measured"]`` read) or a batch
        (obs (E, n) → (E, N wheels)): see :meth:`act_batch`."""
        if np.ndim(obs) == 2:
            return self.act_batch(obs, info)
        state = info[MEASURED]
        angle, rate = euler_error(state["attitude"], state["rate_rad_s"], state["target_attitude"])
        return self._control(angle, rate)

    def act_batch(self, obs: np.ndarray, info: dict[str, Any] | None = None) -> np.ndarray:
        """Each row as :meth:`act` on its own (own integral, reset with :meth:`reset` or
        :meth:`reset_rows`). The rows' states come from ``info["measured"]`` when it holds (E, ·)
        arrays, else from the observation's error state ``[q_e,vec, ω]`` (ReactionWheel-v0,
        AirBearing-v0; float32, so the angles carry its rounding): ``q_e = [v, √(1 − |v|²)]``
        relative to the target, ``ω`` the body rate."""
        obs = np.asarray(obs, dtype=float)
        state = (info or {}).get(MEASURED)
        if state is not None:
            q_e = quaternion_error_batch(
                np.asarray(state["attitude"], dtype=float), np.asarray(state["target_attitude"], dtype=float)
            )
            rate = np.asarray(state["rate_rad_s"], dtype=float)
        else:
            v = obs[:, :3]
            q_e = np.concatenate([v, np.sqrt(np.maximum(0.0, 1.0 - np.sum(v * v, axis=1)))[:, None]], axis=1)
            rate = obs[:, 3:6]
        if self._integral.ndim == 1:  # first batched call after reset: one integral per row
            self._integral = np.zeros((len(obs), 3)) + self._integral
        if self._integral.shape != (len(obs), 3):
            raise ValueError(f"obs has {len(obs)} rows but the PID integrates {len(self._integral)}; call reset()")
        angle = euler_321_rad_batch(q_e)
        return self._control(angle, euler_321_rates_batch(angle, rate))

    def _control(self, angle: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """Eq. 18 on the Euler errors (rad) and rates (rad/s), one (3,) or a batch (E, 3)."""
        kp, kd, ki = self.gains.at(angle, rate)
        e = -angle
        torque = kp * e + kd * (-rate) + ki * self._integral
        self._integral = self._integral + e * self.dt_s
        self.last_torque_nm = torque
        return self.allocator.action(torque)


def quaternion_error_batch(q: np.ndarray, q_target: np.ndarray) -> np.ndarray:
    """``q_e = q_T* ⊗ q`` for the rows of ``q`` and ``q_target`` (E × 4, scalar last), the same
    products as :func:`euler_error`."""
    tx, ty, tz, tw = -q_target[:, 0], -q_target[:, 1], -q_target[:, 2], q_target[:, 3]
    qx, qy, qz, qw = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            tw * qx + tx * qw + ty * qz - tz * qy,
            tw * qy - tx * qz + ty * qw + tz * qx,
            tw * qz + tx * qy - ty * qx + tz * qw,
            tw * qw - tx * qx - ty * qy - tz * qz,
        ],
        axis=1,
    )


def euler_error(q, rate_rad_s, q_target) -> tuple[np.ndarray, np.ndarray]:
    """3-2-1 Euler angles (rad) of ``q_e = q_T* ⊗ q`` and their rates (rad/s, eq. 14, target at rest)."""
    tx, ty, tz, tw = -float(q_target[0]), -float(q_target[1]), -float(q_target[2]), float(q_target[3])
    qx, qy, qz, qw = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    e = (
        tw * qx + tx * qw + ty * qz - tz * qy,
        tw * qy - tx * qz + ty * qw + tz * qx,
        tw * qz + tx * qy - ty * qx + tz * qw,
        tw * qw - tx * qx - ty * qy - tz * qz,
    )
    roll, pitch, yaw = euler_321_rad(e)
    return np.array([roll, pitch, yaw]), np.array(euler_321_rates(roll, pitch, rate_rad_s))


def pid_policy(env, gains: str = "paper-fixed", **kwargs: Any) -> PIDPolicy:
    """A :class:`PIDPolicy` by name (the policy registry's ``pid``): ``gains`` is
    ``"paper-fixed"`` (Table 3), ``"paper-schedule-rad"`` / ``"paper-schedule-deg"`` (eq. 24)
    or the path of a gains JSON written by ``attitude-envs tune-pid``."""
    named = {
        "paper-fixed": lambda: PAPER_FIXED,
        "paper-schedule-rad": lambda: paper_schedule("rad"),
        "paper-schedule-deg": lambda: paper_schedule("deg"),
    }
    if gains in named:
        return PIDPolicy(env, named[gains](), **kwargs)
    if not Path(gains).is_file():
        raise ValueError(f"gains must be one of {sorted(named)} or a gains JSON file, got {gains!r}")
    return PIDPolicy.from_file(env, gains, **kwargs)
