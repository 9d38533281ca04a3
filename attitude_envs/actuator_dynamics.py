"""Flight actuators: the computation delay and the actuator dynamics between a command and
the output the plant receives (:mod:`attitude_envs.conditions`; off in the lab).

One control period of one actuator, in this order:

1. **delay**: the command acts ``delay_steps`` periods after it is given; until then the
   actuator receives the zero command (the flight computer's output before the episode);
2. **resolution**: rounded to the nearest multiple of ``resolution`` (the command's
   least significant bit), within the actuator's limit;
3. **rate limit**: the output may change by at most ``rate_limit · Δt`` per period (a
   gimbal's slew rate);
4. **faults** (:mod:`attitude_envs.faults`, the env's fault layer);
5. **lag**: a first-order lag of time constant ``lag_s`` (motor current or torque loop).
   The plant holds its input over the period, so the output it receives is the mean of
   the lag's exact response to the held command, ``c + (y₀ − c) φ`` with
   ``φ = (τ/Δt)(1 − e^{−Δt/τ})``; the lag's state then moves to ``c + (y₀ − c) e^{−Δt/τ}``.
   The impulse delivered over the period is exact; its shape inside the period is not
   (it is held);
6. **gain**: times this episode's scale-factor error (drawn with the parameters) and the
   duty cycle (the fraction of the period the actuator is on: magnetorquers are off while
   the magnetometer samples);
7. **friction** (wheels): minus ``coulomb · sign(Ω) + viscous · Ω`` at the wheel speed Ω
   (rad/s) at the start of the period, held over it. Ω is the speed in the sense a positive
   output spins the wheel up: the gyrostats' output is the motor torque on the wheel (Ω is
   the wheel speed); an env whose output is the torque on the body passes −Ω.

The delay is in the env's control periods (its decision period: ``-v1`` envs decide more
slowly, so their delay is longer in seconds).

Every quantity is per actuator in the actuator's own units (N·m, A·m², rad); a zero
coefficient (an infinite rate limit, a unit gain) leaves that stage out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from attitude_envs import validation


@dataclass(frozen=True)
class ActuatorModel:
    """The dynamics of an env's actuators, one entry per actuator (see the module docstring)."""

    limits: np.ndarray
    lag_s: np.ndarray
    resolution: np.ndarray
    rate_limit: np.ndarray
    duty: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray

    @classmethod
    def build(cls, limits, **entries) -> ActuatorModel:
        """From per-actuator values (a number applies to every actuator); absent entries are
        off. ``limits`` are the actuators' own limits (the quantized command stays within)."""
        lim = np.broadcast_to(np.asarray(limits, dtype=float), np.shape(limits) or (1,)).copy()
        n = lim.shape[0]
        defaults = {
            "lag_s": 0.0,
            "resolution": 0.0,
            "rate_limit": math.inf,
            "duty": 1.0,
            "coulomb": 0.0,
            "viscous": 0.0,
        }
        unknown = set(entries) - set(defaults)
        if unknown:
            raise ValueError(f"actuator model has unknown entries {sorted(unknown)} (accepted: {sorted(defaults)})")
        values = {}
        for key, default in defaults.items():
            v = np.asarray(entries.get(key, default), dtype=float)
            v = np.broadcast_to(v, (n,)).copy() if v.ndim == 0 else v
            if v.shape != (n,) or np.isnan(v).any() or (v < 0).any():
                raise ValueError(f"actuator {key} must be a number >= 0 or {n} of them, got {v.tolist()}")
            values[key] = v
        if ((values["duty"] <= 0) | (values["duty"] > 1)).any():
            raise ValueError(f"actuator duty must be in (0, 1], got {values['duty'].tolist()}")
        if (values["rate_limit"] == 0).any():
            raise ValueError("actuator rate_limit must be > 0 (inf: none)")
        return cls(lim, **values)


@dataclass
class ActuatorChain:
    """The delay and the actuator dynamics of one env (runtime state: the delay line, the
    lag's and the rate limiter's outputs, this episode's gains)."""

    model: ActuatorModel | None
    delay_steps: int
    dt_s: float
    gain: np.ndarray = field(init=False)
    _queue: list = field(init=False, default_factory=list)
    _last: np.ndarray = field(init=False)
    _lagged: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.delay_steps = validation.integer("delay_steps", self.delay_steps, 0)
        self.dt_s = validation.positive("control_dt_s", self.dt_s)
        n = 0 if self.model is None else self.model.limits.shape[0]
        self.gain = np.ones(n)
        if self.model is not None:
            lag = self.model.lag_s
            with np.errstate(divide="ignore", invalid="ignore"):
                decay = np.where(lag > 0, np.exp(-self.dt_s / np.where(lag > 0, lag, 1.0)), 0.0)
                self._mean_weight = np.where(lag > 0, lag / self.dt_s * (1.0 - decay), 0.0)
            self._decay = decay
        self.reset(None)

    @property
    def lag_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(φ, e^{−Δt/τ})`` per actuator (copies; zeros where there is no lag, and for a
        chain without a model): the period-mean weight and the decay of the lag stage, the
        very numbers :meth:`output` uses (read-only, for tools such as the J* oracle)."""
        if self.model is None:
            return np.zeros(0), np.zeros(0)
        return self._mean_weight.copy(), self._decay.copy()

    def reset(self, n: int | None, gain: np.ndarray | None = None) -> None:
        """Start an episode: empty delay line (``n`` actuators), outputs at rest, ``gain``
        (the scale-factor errors; ones when None)."""
        if gain is not None:
            self.gain = np.asarray(gain, dtype=float).copy()
        size = n if n is not None else (0 if self.model is None else self.model.limits.shape[0])
        self._queue = [np.zeros(size) for _ in range(self.delay_steps)]
        self._last = np.zeros(size)
        self._lagged = np.zeros(size)

    def command(self, commanded: np.ndarray) -> np.ndarray:
        """Stages 1–3: the command the actuator acts on this period."""
        c = np.asarray(commanded, dtype=float)
        if self.delay_steps:
            self._queue.append(c.copy())
            c = self._queue.pop(0)
        m = self.model
        if m is None:
            return c
        if m.resolution.any():
            q = np.where(m.resolution > 0, m.resolution, 1.0)
            c = np.where(m.resolution > 0, np.clip(np.round(c / q) * q, -m.limits, m.limits), c)
        if np.isfinite(m.rate_limit).any():
            step = m.rate_limit * self.dt_s
            c = np.clip(c, self._last - step, self._last + step)
            self._last = c.copy()
        return c

    def output(self, faulted: np.ndarray, speeds: np.ndarray | None = None) -> np.ndarray:
        """Stages 5–7: the output held over the period, from the faulted command and the
        wheel speeds (rad/s, one per actuator; None: no friction)."""
        m = self.model
        if m is None:
            return faulted
        y = faulted
        if m.lag_s.any():
            y0 = self._lagged
            y = np.where(m.lag_s > 0, faulted + (y0 - faulted) * self._mean_weight, faulted)
            self._lagged = np.where(m.lag_s > 0, faulted + (y0 - faulted) * self._decay, faulted)
        y = y * (self.gain * m.duty)
        if speeds is not None and (m.coulomb.any() or m.viscous.any()):
            y = y - m.coulomb * np.sign(speeds) - m.viscous * speeds
        return y

    def deliver(
        self, commanded: np.ndarray, faults: Callable[[np.ndarray], np.ndarray], speeds: np.ndarray | None = None
    ) -> np.ndarray:
        """All seven stages: ``faults`` applies the env's fault layer at this period."""
        return self.output(faults(self.command(commanded)), speeds)
