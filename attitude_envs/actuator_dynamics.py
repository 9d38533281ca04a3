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
from attitude_envs.plants.ops import NUMPY


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


@dataclass(frozen=True)
class ActuatorLayout:
    """The static shape of an actuator chain: ``delay_steps`` (control periods), ``model``
    (actuator dynamics on) and, with a model, which of its stages act (``resolution``,
    ``rate``, ``lag``, ``friction``; a stage none of whose actuators has it is skipped).
    ``gain``: the output is multiplied by the episode's scale-factor gains even without a
    model (drawn parameters). A compiled JAX program is fixed by it."""

    delay_steps: int = 0
    model: bool = False
    resolution: bool = False
    rate: bool = False
    lag: bool = False
    friction: bool = False
    gain: bool = False


def layout_of(model: ActuatorModel | None, delay_steps: int, gain: bool) -> ActuatorLayout:
    """The static layout of a chain of ``model`` (None: no actuator dynamics) and ``delay_steps``."""
    if model is None:
        return ActuatorLayout(delay_steps=int(delay_steps), gain=bool(gain))
    return ActuatorLayout(
        delay_steps=int(delay_steps),
        model=True,
        resolution=bool(model.resolution.any()),
        rate=bool(np.isfinite(model.rate_limit).any()),
        lag=bool(model.lag_s.any()),
        friction=bool(model.coulomb.any() or model.viscous.any()),
        gain=bool(gain),
    )


@dataclass(frozen=True)
class ChainNumbers:
    """The numbers of an actuator chain at its control period, one entry per actuator:
    ``limits`` (own units), ``resolution`` (0: none), ``rate_step`` (``rate_limit · Δt``; inf:
    none), ``lag_on``, ``mean_weight`` (φ), ``decay`` (``e^{−Δt/τ}``), ``duty``, ``coulomb``,
    ``viscous`` (the fields of the JAX twin's ``ActuatorParams``)."""

    limits: np.ndarray
    resolution: np.ndarray
    rate_step: np.ndarray
    lag_on: np.ndarray
    mean_weight: np.ndarray
    decay: np.ndarray
    duty: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray


def numbers_of(model: ActuatorModel | None, n: int, dt_s: float) -> ChainNumbers:
    """The numbers of ``model`` (``n`` actuators; None: neutral entries) at the control period
    ``dt_s`` (s): the lag's ``φ = (τ/Δt)(1 − e^{−Δt/τ})`` and ``e^{−Δt/τ}`` (zeros without a lag)."""
    if model is None:
        model = ActuatorModel.build(np.ones(n))
    lag = model.lag_s
    with np.errstate(divide="ignore", invalid="ignore"):
        decay = np.where(lag > 0, np.exp(-dt_s / np.where(lag > 0, lag, 1.0)), 0.0)
        mean_weight = np.where(lag > 0, lag / dt_s * (1.0 - decay), 0.0)
    return ChainNumbers(
        limits=model.limits,
        resolution=model.resolution,
        rate_step=model.rate_limit * dt_s,
        lag_on=lag > 0,
        mean_weight=mean_weight,
        decay=decay,
        duty=model.duty,
        coulomb=model.coulomb,
        viscous=model.viscous,
    )


@dataclass(frozen=True)
class ChainStages:
    """The chain's stages written once against an operation set
    (:class:`attitude_envs.plants.ops.Ops`), elementwise on one actuator or on arrays of them.

    * ``quantized(c, q, limit)``: ``c`` rounded to the nearest multiple of ``q`` (half to
      even), within ``±limit``;
    * ``rate_limited(c, last, step)``: ``c`` within ``step`` of ``last``;
    * ``toward(c, y0, w)``: ``c + (y0 − c) w``, the lag's period mean (``w = φ``) and its next
      state (``w = e^{−Δt/τ}``);
    * ``with_friction(y, coulomb, sign, viscous, speed)``: ``y − coulomb · sign − viscous · speed``;
    * ``command(layout, p, last, c) -> (c, last)``: stages 2–3 after the delay line, ``p`` a
      :class:`ChainNumbers` or any object with its fields;
    * ``output(layout, p, lagged, faulted, gain, speeds) -> (y, lagged)``: stages 5–7 (``gain``
      None: ones; ``speeds`` None: no friction; without a model only the gain acts).

    The numpy chain (:class:`ActuatorChain`) and the JAX twins run ``command`` and ``output``;
    the J* oracle's CasADi chain (``attitude_envs.symbolic.actuators``), which relaxes the
    resolution and may fix or smooth the friction's sign, runs the stage functions per actuator."""

    quantized: Callable
    rate_limited: Callable
    toward: Callable
    with_friction: Callable
    command: Callable
    output: Callable


def define_chain(ops) -> ChainStages:
    """The chain's stages (:class:`ChainStages`) on the executor ``ops``."""
    fmin, fmax, rnd, where, sign = ops.fmin, ops.fmax, ops.round, ops.where, ops.sign  # names numba can type

    @ops.compile
    def clip(v, lo, hi):
        return fmin(fmax(v, lo), hi)

    @ops.compile
    def quantized(c, q, limit):
        return clip(rnd(c / q) * q, -limit, limit)

    @ops.compile
    def rate_limited(c, last, step):
        return clip(c, last - step, last + step)

    @ops.compile
    def toward(c, y0, w):
        return c + (y0 - c) * w

    @ops.compile
    def with_friction(y, coulomb, sign, viscous, speed):
        return y - coulomb * sign - viscous * speed

    def command(layout: ActuatorLayout, p, last, c):
        if layout.model and layout.resolution:
            on = p.resolution > 0
            c = where(on, quantized(c, where(on, p.resolution, 1.0), p.limits), c)
        if layout.model and layout.rate:
            c = rate_limited(c, last, p.rate_step)
            last = c
        return c, last

    def output(layout: ActuatorLayout, p, lagged, faulted, gain, speeds):
        y = faulted
        if layout.model:
            if layout.lag:
                y = where(p.lag_on, toward(faulted, lagged, p.mean_weight), faulted)
                lagged = where(p.lag_on, toward(faulted, lagged, p.decay), faulted)
            y = y * (p.duty if gain is None else gain * p.duty)
            if layout.friction and speeds is not None:
                y = with_friction(y, p.coulomb, sign(speeds), p.viscous, speeds)
        elif gain is not None:
            y = y * gain
        return y, lagged

    return ChainStages(quantized, rate_limited, toward, with_friction, command, output)


_NUMPY_CHAIN = define_chain(NUMPY)


@dataclass
class ActuatorChain:
    """The delay and the actuator dynamics of one env (runtime state: the delay line, the
    lag's and the rate limiter's outputs, this episode's gains), in numpy: the delay line,
    then :func:`define_chain`'s ``command`` and ``output``."""

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
        self._layout = layout_of(self.model, self.delay_steps, False)
        self._numbers = None if self.model is None else numbers_of(self.model, n, self.dt_s)
        self.reset(None)

    @property
    def lag_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(φ, e^{−Δt/τ})`` per actuator (copies; zeros where there is no lag, and for a
        chain without a model): the period-mean weight and the decay of the lag stage, the
        very numbers :meth:`output` uses (read-only, for tools such as the J* oracle)."""
        if self._numbers is None:
            return np.zeros(0), np.zeros(0)
        return self._numbers.mean_weight.copy(), self._numbers.decay.copy()

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
        c, last = _NUMPY_CHAIN.command(self._layout, self._numbers, self._last, c)
        if last is not self._last:  # the rate limiter acted: keep its output apart from the command
            self._last = last.copy()
        return c

    def output(self, faulted: np.ndarray, speeds: np.ndarray | None = None) -> np.ndarray:
        """Stages 5–7: the output held over the period, from the faulted command and the
        wheel speeds (rad/s, one per actuator; None: no friction)."""
        if self.model is None:
            return faulted
        y, self._lagged = _NUMPY_CHAIN.output(self._layout, self._numbers, self._lagged, faulted, self.gain, speeds)
        return y

    def deliver(
        self, commanded: np.ndarray, faults: Callable[[np.ndarray], np.ndarray], speeds: np.ndarray | None = None
    ) -> np.ndarray:
        """All seven stages: ``faults`` applies the env's fault layer at this period."""
        return self.output(faults(self.command(commanded)), speeds)
