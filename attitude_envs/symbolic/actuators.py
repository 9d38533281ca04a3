"""The actuator fault layer (:class:`attitude_envs.faults.ActuatorFaults`) as a CasADi
expression of the step's start time: the episode's realized faults are known (an oracle).

Mirrors :meth:`~attitude_envs.faults.ActuatorFaults.apply` operation by operation (the faults
in their list order, each active for ``onset_s <= t < onset_s + duration_s``, then the clip
at the possibly reduced limit), so the symbolic command equals the env's to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi
import numpy as np

from attitude_envs.actuator_dynamics import define_chain
from attitude_envs.faults import KIND_CODES, define_effect
from attitude_envs.symbolic.ops import CASADI

_effect = define_effect(CASADI)
#: the actuator chain's stages (:func:`attitude_envs.actuator_dynamics.define_chain`) on CasADi scalars
_STAGES = define_chain(CASADI)

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


# ---------------------------------------------------------------- flight actuator chain
#: the smoothing speed ε (rad/s) of the wheel's Coulomb friction in the oracle's problem:
#: ``sign(Ω)`` is replaced by ``tanh(Ω/ε)`` (the env keeps the sign; J* is the env's replay).
#: The first, smoothed solve only seeds the fixed-sign passes; measured on AirBearing-v0's
#: default flight episode (2000 steps, seed 0): ε = 0.05 took 122 IPOPT iterations (339 s),
#: 0.5 took 9 (and the fixed-sign pass 12; 82 s in all) for the same J* (to 1e-11, the NLP
#: within 1e-9 of the replay); 2.0 took 9 + 25
FRICTION_EPS_RAD_S = 0.5


@dataclass(frozen=True)
class ChainSpec:
    """What the J* oracle knows of an env's flight actuator chain
    (:mod:`attitude_envs.actuator_dynamics`; one entry per actuator, in its own units), and
    the chain's extra state in the symbolic model: ``delay_steps · N`` queued commands (oldest
    first), then ``N`` rate-limiter outputs (when a rate limit is finite), then ``N`` lag
    states (when a lag is on).

    ``gain``: this episode's drawn scale factors times the duty cycle (the env's
    ``gain · duty``); ``has_model``: the actuator dynamics are on (without them only the
    delay and the gain act, the gain after the faults as the env's ``_with_gain`` does);
    ``mean_weight``/``decay``: the lag's ``φ`` and ``e^{−Δt/τ}`` (the env's own numbers);
    ``rate_step``: ``rate_limit · Δt`` (inf: none); ``coulomb``, ``viscous``: wheel friction;
    ``resolution``: the command's quantum, relaxed (not modelled); ``friction_eps``: the
    smoothing speed of ``sign(Ω)``."""

    n: int
    delay_steps: int = 0
    has_model: bool = False
    gain: np.ndarray | None = None
    lag: np.ndarray | None = None
    mean_weight: np.ndarray | None = None
    decay: np.ndarray | None = None
    rate_step: np.ndarray | None = None
    coulomb: np.ndarray | None = None
    viscous: np.ndarray | None = None
    resolution: np.ndarray | None = None
    friction_eps: float = FRICTION_EPS_RAD_S
    #: the Coulomb term's sign(Ω) is a per-step input of the step (fixed from a first solve)
    fixed_signs: bool = False
    #: the rate limit as a path constraint on the queued command (needs ``delay_steps >= 1``;
    #: :func:`rate_limit_rows`) in place of the env's clip: the step stays smooth
    rate_constrained: bool = False

    @property
    def has_rate(self) -> bool:
        return self.rate_step is not None and bool(np.isfinite(self.rate_step).any())

    @property
    def has_lag(self) -> bool:
        return self.lag is not None and bool(np.any(self.lag > 0))

    @property
    def has_friction(self) -> bool:
        return self.has_model and bool(np.any(self.coulomb != 0) or np.any(self.viscous != 0))

    @property
    def n_state(self) -> int:
        """Extra state entries the chain adds to the plant's."""
        return self.n * (self.delay_steps + int(self.has_rate) + int(self.has_lag))

    @property
    def is_identity(self) -> bool:
        """Nothing between the fault layer's output and the plant (the lab's graph)."""
        gain_one = self.gain is None or bool(np.all(self.gain == 1.0))
        return self.delay_steps == 0 and not self.has_model and gain_one

    def notes(self) -> list[str]:
        """How each stage enters the optimal-control problem (exact or relaxed)."""
        out = []
        if self.delay_steps:
            out.append(
                f"delay of {self.delay_steps} period(s) exact: a queue of past commands in the state (zeros at the "
                "start), the decision variables stay the commands"
            )
        if self.has_model:
            if self.resolution is not None and np.any(self.resolution > 0):
                out.append("command resolution relaxed: the oracle's command is continuous (the env quantizes it)")
            if self.has_rate and self.rate_constrained:
                out.append(
                    "rate limit exact: the delayed command held within rate_limit * dt of the limiter's previous "
                    "output (a state) by a path constraint on the queue, so the env's clip never acts (no loss: a "
                    "clipped command delivers what the clipped value commanded does)"
                )
            elif self.has_rate:
                out.append("rate limit exact: the env's clip about the limiter's previous output, a state (non-smooth)")
            if self.has_lag:
                out.append(
                    "first-order lag exact: its state in the problem, the period mean c + (y0 - c) phi delivered"
                )
            out.append("gain times duty cycle exact")
            if self.has_friction and self.fixed_signs:
                out.append(
                    "wheel friction at the period-start speed: viscous exact, Coulomb sign(Omega) fixed per step "
                    "from the previous solve (exact where the optimum keeps those signs)"
                )
            elif self.has_friction:
                out.append(
                    f"wheel friction at the period-start speed: viscous exact, Coulomb sign(Omega) relaxed to "
                    f"tanh(Omega / {self.friction_eps:g} rad/s)"
                )
        elif self.gain is not None and np.any(self.gain != 1.0):
            out.append("actuator scale-factor gains exact")
        return out

    @classmethod
    def from_env(cls, env, n: int) -> ChainSpec:
        """The chain of ``env`` (an unwrapped env, just reset) for ``n`` actuators."""
        chain = getattr(env, "_actuator_chain", None)
        drawn = env.drawn_parameters() if hasattr(env, "drawn_parameters") else {}
        gain = drawn.get("actuator_gain")
        gain = None if gain is None else np.asarray(gain, dtype=float)
        if chain is None:
            return cls(n, gain=gain)
        m = chain.model
        if m is None:
            return cls(n, delay_steps=int(chain.delay_steps), gain=gain)
        mean_weight, decay = chain.lag_weights
        return cls(
            n,
            delay_steps=int(chain.delay_steps),
            has_model=True,
            gain=np.asarray(chain.gain, dtype=float) * m.duty,  # the env's gain · duty, in its order
            lag=np.asarray(m.lag_s, dtype=float),
            mean_weight=mean_weight,
            decay=decay,
            rate_step=np.asarray(m.rate_limit, dtype=float) * float(chain.dt_s),
            coulomb=np.asarray(m.coulomb, dtype=float),
            viscous=np.asarray(m.viscous, dtype=float),
            resolution=np.asarray(m.resolution, dtype=float),
        )


def chain_command(spec: ChainSpec, commanded, extra):
    """Stages 1–3 (delay, resolution relaxed, rate limit) on the ``commanded`` outputs (list of
    N SX) with the chain's state ``extra`` (list of SX): ``(command, new_extra_head)``, the
    command the fault layer receives and the new queue and rate-limiter entries."""
    n, d = spec.n, spec.delay_steps
    c = list(commanded)
    new = []
    if d:
        queue = extra[: d * n]
        new += queue[n:] + c
        c = queue[:n]
    if spec.has_rate and spec.rate_constrained:
        new += c  # held within the rate by rate_limit_rows: the clip is the identity
    elif spec.has_rate:
        last = extra[d * n : d * n + n]
        c = [
            _STAGES.rate_limited(c[i], last[i], float(spec.rate_step[i])) if np.isfinite(spec.rate_step[i]) else c[i]
            for i in range(n)
        ]
        new += c
    return c, new


def chain_output(spec: ChainSpec, faulted, extra, speeds, signs=None):
    """Stages 5–7 (lag, gain · duty, friction at the period-start wheel ``speeds``) on the
    ``faulted`` outputs (list of N SX): ``(output, new_lag_states)``. ``signs`` (list of N
    SX, with ``spec.fixed_signs``): the Coulomb term's ``sign(Ω)``; else ``tanh(Ω/ε)``."""
    n = spec.n
    y = list(faulted)
    new = []
    if not spec.has_model:
        if spec.gain is not None and np.any(spec.gain != 1.0):
            y = [y[i] * float(spec.gain[i]) for i in range(n)]
        return y, new
    if spec.has_lag:
        lag0 = extra[spec.n_state - n :]
        mean, dec = [], []
        for i in range(n):
            if spec.lag[i] > 0:
                mean.append(_STAGES.toward(y[i], lag0[i], float(spec.mean_weight[i])))
                dec.append(_STAGES.toward(y[i], lag0[i], float(spec.decay[i])))
            else:
                mean.append(y[i])
                dec.append(y[i])
        y, new = mean, dec
    y = [y[i] * float(spec.gain[i]) for i in range(n)]
    if spec.has_friction:
        eps = float(spec.friction_eps)
        y = [
            _STAGES.with_friction(
                y[i],
                float(spec.coulomb[i]),
                casadi.tanh(speeds[i] / eps) if signs is None else signs[i],
                float(spec.viscous[i]),
                speeds[i],
            )
            for i in range(n)
        ]
    return y, new


def through_chain(spec: ChainSpec | None, commanded, t, realized, limits, extra=(), speeds=None, signs=None):
    """All seven stages for a plant's builder: ``(output, new_extra)`` of the ``commanded``
    outputs (SX column, physical units, already clipped to the limits) at the step's start
    time ``t`` with the realized faults ``realized``, the actuators' ``limits`` and the
    chain's state ``extra`` (list of SX, the layout of :class:`ChainSpec`); ``speeds``:
    the period-start speeds the wheel friction acts against (list of N SX, the env's
    convention: an env whose output is the torque on the body passes −Ω), ``signs``: the
    Coulomb signs when fixed (:func:`chain_output`). ``spec`` None or
    :attr:`ChainSpec.is_identity`: the lab's graph, the fault layer alone (bit-identical)."""
    if spec is None or spec.is_identity:
        out = delivered(commanded, t, realized, limits)
        return [out[i] for i in range(out.shape[0])], []
    n = spec.n
    c, new = chain_command(spec, [commanded[i] for i in range(n)], list(extra))
    faulted = delivered(casadi.vertcat(*c), t, realized, limits)
    y, lag = chain_output(spec, [faulted[i] for i in range(n)], list(extra), speeds, signs)
    return y, new + lag


def rate_limit_rows(spec: ChainSpec, extra) -> list:
    """The rate limit of a chain with ``rate_constrained`` as path-constraint rows ``<= 0`` on
    its state ``extra`` (list of SX): for each rate-limited actuator, the oldest queued command
    (the one the limiter receives next period) within ``rate_limit · Δt`` of the limiter's last
    output, two linear rows normalized by that step. Imposed on every state x_1 … x_N, it
    holds each command that acts within the episode inside the env's clip band."""
    if not (spec.has_rate and spec.rate_constrained):
        return []
    if spec.delay_steps < 1:
        raise ValueError("a rate limit as a path constraint needs a delay of at least one period")
    n, d = spec.n, spec.delay_steps
    oldest, last = extra[:n], extra[d * n : d * n + n]
    rows = []
    for i in range(n):
        r = float(spec.rate_step[i])
        if np.isfinite(r):
            rows += [(oldest[i] - last[i]) / r - 1.0, (last[i] - oldest[i]) / r - 1.0]
    return rows
