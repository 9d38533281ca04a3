"""The suite's sensor models (:mod:`attitude_envs.sensors`) as arrays, for the JAX plants:
white noise, a bias drawn at reset, its random walk, and a sample period with
sample-and-hold between samples (a star tracker slower than the control loop), for vector
channels (additive errors) and attitude channels (``q_m = q ⊗ exp(e)``, ``e`` a body rotation
vector), and the sensor faults of :mod:`attitude_envs.sensors` (every kind: bias, drift, stuck,
dropout, noise increase; an axis, value, onset or duration given as a draw is drawn at each
reset, :func:`realize`).

:meth:`attitude_envs.sensors.SensorSuite.measure`'s law, step for step: a channel samples at
the observation times; one with a ``period_s`` repeats its last sample until
``period_s · (1 − 10⁻⁹)`` has passed since its previous one (the first at reset); at a sample
the bias walks by ``bias_walk_std · √Δt · N(0, 1)`` over the time since the channel's previous
sample (since the previous observation without a period), then the noise is drawn. In
float32 the sample test allows the rounding of the times (16 ulp of ``t``): a period that is a
multiple of the control period samples on the numba env's (float64) steps. A sensor fault
is active for ``onset_s ≤ t < onset_s + duration_s`` at the float times, as the actuator faults
(:mod:`attitude_envs.jax.faults`): in float32 an onset that is not a whole multiple of the
control period may switch one decision away from the numba env's (x64: the numba test as is;
the flight cells' onsets are whole seconds). The draws come from JAX keys: the same law as
the numba layer's numpy generator, not the same numbers.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.jax import quaternion as jq
from attitude_envs.sensors import fault_axes

#: the relative margin of the sample-period test (:meth:`SensorSuite.measure`'s)
_PERIOD_MARGIN = 1.0 - 1e-9
#: folded into a plant's reset and step keys for its sensors' draws (the plant's other draws
#: unchanged, so turning the sensors on changes no start, fault or process noise)
SENSOR_STREAM = 0x534E53


#: the sensor fault kinds (:data:`attitude_envs.sensors.SENSOR_KINDS`) as codes
FAULT_CODES = {"bias": 1, "drift": 2, "stuck": 3, "dropout": 4, "noise_increase": 5}


@struct.dataclass
class ChannelFaults:
    """A channel's sensor faults, in the numba layer's order (its ``realized`` list), one entry
    per fault: ``kind`` (:data:`FAULT_CODES`), ``index`` (an axis; −1: the whole reading),
    ``value`` (channel units; NaN: a stuck reading holds the measurement at onset), ``onset_s``
    and ``end_s`` (s; active for ``onset_s ≤ t < end_s``, inf: no end) and ``hold`` (a dropout
    repeats the last delivered sample, else reads NaN); ``draws`` (:class:`FaultDraws`; None:
    every fault fixed, the same in every episode) redraws the axis, value, onset and end of
    each episode's faults at its reset, into the channel's state."""

    kind: jax.Array
    index: jax.Array
    value: jax.Array
    onset_s: jax.Array
    end_s: jax.Array
    hold: jax.Array
    draws: FaultDraws | None = None


@struct.dataclass
class FaultDraws:
    """How a channel's sensor faults are drawn at each reset (:meth:`SensorSuite.reset`'s law),
    one entry per fault: uniform ``value_low``/``value_high`` (NaN: no value),
    ``onset_low``/``onset_high`` and ``duration_low``/``duration_high`` (s; ``has_end`` False:
    no end), ``random_index`` (the axis uniform over the channel's ``axes``) and ``group`` (the
    fault dict it came from, within the channel: one index, onset and duration per dict, one
    value per entry). Equal bounds give the number itself."""

    value_low: jax.Array
    value_high: jax.Array
    onset_low: jax.Array
    onset_high: jax.Array
    duration_low: jax.Array
    duration_high: jax.Array
    has_end: jax.Array
    random_index: jax.Array
    axes: jax.Array
    group: jax.Array


@struct.dataclass
class ChannelParams:
    """One channel's model (one entry per axis): ``noise_std``, ``bias_walk_std`` (per √s),
    ``initial_bias``, ``initial_bias_std``; ``period_s`` (0: a sample at every observation);
    its sensor ``faults`` (None: none, and the compiled measurement is the fault-free one)."""

    noise_std: jax.Array
    bias_walk_std: jax.Array
    initial_bias: jax.Array
    initial_bias_std: jax.Array
    period_s: jax.Array
    faults: ChannelFaults | None = None


@struct.dataclass
class ChannelState:
    """One channel's runtime state: its ``bias``, ``last`` sample (the channel's size: 4 for an
    attitude), the time of its last sample ``sampled`` (s) and ``has_sampled``; with faults
    the stuck faults' ``held`` readings (faults × size) and ``latched`` flags, and whether a
    sample was ``delivered`` yet (a dropout's hold repeats it); the episode's ``faults`` where
    they are drawn per episode (None: the params' own)."""

    bias: jax.Array
    last: jax.Array
    sampled: jax.Array
    has_sampled: jax.Array
    held: jax.Array | None = None
    latched: jax.Array | None = None
    delivered: jax.Array | None = None
    faults: ChannelFaults | None = None


def params_of(config: dict, axes: int, dtype, faults: ChannelFaults | None = None) -> ChannelParams:
    """A channel's :class:`ChannelParams` from its validated ``SensorSuite.config`` entry and
    its ``faults`` (:func:`channel_faults`)."""

    def f(key):
        return jnp.asarray(np.broadcast_to(np.asarray(config[key], dtype=float), (axes,)), dtype=dtype)

    return ChannelParams(
        noise_std=f("noise_std"),
        bias_walk_std=f("bias_walk_std"),
        initial_bias=f("initial_bias"),
        initial_bias_std=f("initial_bias_std"),
        period_s=jnp.asarray(float(config["period_s"]), dtype=dtype),
        faults=faults,
    )


def _bounds(spec) -> tuple[float, float]:
    """``(low, high)`` of a validated number or ``{"uniform": [low, high]}`` (NaN, NaN: None)."""
    if spec is None:
        return math.nan, math.nan
    if isinstance(spec, dict):
        return float(spec["uniform"][0]), float(spec["uniform"][1])
    return float(spec), float(spec)


def channel_faults(suite: Any, dtype, where: str) -> dict[str, ChannelFaults]:
    """Each faulted channel's :class:`ChannelFaults` of a numba :class:`attitude_envs.sensors.SensorSuite`
    ``suite``: its validated sensor fault dicts expanded as its ``reset`` expands them (``index:
    "all"`` one entry per axis, or one whole-reading entry for a stuck or dropped attitude), with
    :class:`FaultDraws` where an axis, value, onset or duration is drawn per episode. A
    ``ValueError`` naming ``where`` (the plant) for a fault on a channel without a sensor model."""
    entries: dict[str, list[dict]] = {}
    for i, c in enumerate(suite.fault_configs):
        name, kind = c["sensor"], c["kind"]
        if name not in suite.config:
            raise ValueError(
                f"{where}: sensor fault {i} ({kind}) is on {name!r}, which has no sensor model here "
                "(the flight conditions' sensors model every channel)"
            )
        channel = suite.channels[name]
        axes = fault_axes(c, channel)
        group = len({e["group"] for e in entries.get(name, [])})
        onset, duration = _bounds(c.get("onset_s", 0.0)), _bounds(c.get("duration_s"))
        for axis in axes:
            entries.setdefault(name, []).append(
                {
                    "kind": FAULT_CODES[kind],
                    "index": {"all": -1, "random": 0}.get(axis, axis),
                    "value": _bounds(c.get("value")),
                    "onset": onset,
                    "duration": duration,
                    "random_index": axis == "random",
                    "axes": channel.axes,
                    "group": group,
                    "hold": kind == "dropout" and c.get("mode", "nan") == "hold",
                }
            )
    return {name: _as_arrays(faults, dtype) for name, faults in entries.items()}


def _same(bounds: tuple[float, float]) -> bool:
    """A fixed number (equal bounds, or both NaN: none)."""
    low, high = bounds
    return low == high or (math.isnan(low) and math.isnan(high))


def _as_arrays(faults: list[dict], dtype) -> ChannelFaults:
    """One channel's expanded fault entries (:func:`channel_faults`) as arrays; the end of a
    fixed window summed in float64 as the numba layer sums it, then cast."""

    def f(key, part):
        return jnp.asarray(np.asarray([e[key][part] for e in faults], dtype=float), dtype=dtype)

    def col(key, dt):
        return jnp.asarray([e[key] for e in faults], dt)

    fixed = not any(
        e["random_index"] or not (_same(e["value"]) and _same(e["onset"]) and _same(e["duration"])) for e in faults
    )
    duration = np.asarray([e["duration"][0] for e in faults], dtype=float)
    end = np.asarray([e["onset"][0] for e in faults], dtype=float) + np.where(np.isnan(duration), np.inf, duration)
    draws = None
    if not fixed:
        draws = FaultDraws(
            value_low=f("value", 0),
            value_high=f("value", 1),
            onset_low=f("onset", 0),
            onset_high=f("onset", 1),
            duration_low=jnp.asarray(np.nan_to_num(duration), dtype=dtype),
            duration_high=jnp.nan_to_num(f("duration", 1)),
            has_end=jnp.asarray(~np.isnan(duration)),
            random_index=col("random_index", bool),
            axes=col("axes", jnp.int32),
            group=col("group", jnp.int32),
        )
    return ChannelFaults(
        kind=col("kind", jnp.int32),
        index=col("index", jnp.int32),
        value=f("value", 0),
        onset_s=f("onset", 0),
        end_s=jnp.asarray(end, dtype=dtype),
        hold=col("hold", bool),
        draws=draws,
    )


def realize(key: jax.Array, f: ChannelFaults) -> ChannelFaults:
    """An episode's faults of ``f`` drawn from ``key`` (:class:`FaultDraws`; the numba layer's
    law, not its draws): per fault dict one axis ``⌊U·axes⌋`` where drawn, one onset and one
    duration ``low + (high − low)·U``; per fault one value."""
    d = f.draws
    n = f.kind.shape[0]
    dtype = f.value.dtype
    k_group, k_value = jax.random.split(key)
    u = jax.random.uniform(k_group, (n, 3), dtype)[d.group]  # the groups' draws, per fault
    axis = jnp.minimum(jnp.floor(u[:, 0] * d.axes).astype(jnp.int32), d.axes - 1)
    onset = d.onset_low + (d.onset_high - d.onset_low) * u[:, 1]
    duration = d.duration_low + (d.duration_high - d.duration_low) * u[:, 2]
    value = d.value_low + (d.value_high - d.value_low) * jax.random.uniform(k_value, (n,), dtype)
    fixed_window = (d.onset_low == d.onset_high) & (d.duration_low == d.duration_high)
    return f.replace(
        index=jnp.where(d.random_index, axis, f.index),
        value=value,
        onset_s=onset,
        # a fixed window keeps its end summed in float64 (the numba layer's)
        end_s=jnp.where(fixed_window, f.end_s, jnp.where(d.has_end, onset + duration, jnp.inf)),
        draws=None,
    )


def initial_state(key: jax.Array, p: ChannelParams, truth: jax.Array) -> ChannelState:
    """A channel at reset, before its first sample: its bias drawn (and its faults, where they
    are drawn per episode: :func:`realize`, from ``key`` folded with 1), no sample yet."""
    bias = p.initial_bias + p.initial_bias_std * jax.random.normal(key, p.noise_std.shape, p.noise_std.dtype)
    zero = jnp.zeros((), dtype=truth.dtype)
    state = ChannelState(bias=bias, last=truth, sampled=zero, has_sampled=jnp.asarray(False))
    if p.faults is None:
        return state
    n = p.faults.kind.shape[0]
    drawn = None if p.faults.draws is None else realize(jax.random.fold_in(key, 1), p.faults)
    return state.replace(
        held=jnp.zeros((n,) + truth.shape, truth.dtype),
        latched=jnp.zeros(n, bool),
        delivered=jnp.asarray(False),
        faults=drawn,
    )


def _episode_faults(p: ChannelParams, s: ChannelState | None) -> ChannelFaults | None:
    """The channel's faults this episode: drawn at its reset (in the state), else the params'."""
    return p.faults if s is None or s.faults is None else s.faults


def _active(f: ChannelFaults, t_s) -> jax.Array:
    """Per fault: active at ``t_s`` (s), ``onset_s ≤ t < end_s``."""
    return (f.onset_s <= t_s) & (t_s < f.end_s)


def _additive_faults(f: ChannelFaults, active: jax.Array, err: jax.Array, t_s) -> tuple[jax.Array, jax.Array]:
    """The error with each active bias and drift added on its axis, and the noise scale of
    the active noise increases (:meth:`SensorSuite.measure`'s order: the faults in turn)."""
    axis = jnp.arange(err.shape[0])
    scale = jnp.ones_like(err)
    for i in range(f.kind.shape[0]):
        on = active[i] & (axis == f.index[i])
        err = jnp.where(on & (f.kind[i] == FAULT_CODES["bias"]), err + f.value[i], err)
        err = jnp.where(on & (f.kind[i] == FAULT_CODES["drift"]), err + f.value[i] * (t_s - f.onset_s[i]), err)
        scale = jnp.where(on & (f.kind[i] == FAULT_CODES["noise_increase"]), scale * f.value[i], scale)
    return err, scale


def _reading_faults(
    f: ChannelFaults, active: jax.Array, s: ChannelState, m: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The reading ``m`` through the active stuck and dropout faults, in turn; the next held
    readings and latches (a stuck fault latches the reading, or its value, when it becomes
    active, and lets go when inactive)."""
    entry = jnp.arange(m.shape[0])
    held, latched = s.held, s.latched
    for i in range(f.kind.shape[0]):
        on = active[i] & ((entry == f.index[i]) | (f.index[i] < 0))
        stuck = active[i] & (f.kind[i] == FAULT_CODES["stuck"])
        h = jnp.where(latched[i], held[i], jnp.where(jnp.isnan(f.value[i]), m, f.value[i]))
        m = jnp.where(on & stuck, h, m)
        held = held.at[i].set(jnp.where(stuck, h, held[i]))
        latched = latched.at[i].set(stuck)
        dropout = on & (f.kind[i] == FAULT_CODES["dropout"])
        m = jnp.where(dropout, jnp.where(f.hold[i], jnp.where(s.delivered, s.last, m), jnp.nan), m)
    return m, held, latched


def measure(
    key: jax.Array, p: ChannelParams, s: ChannelState, truth: jax.Array, t_s, t_last, attitude: bool
) -> tuple[jax.Array, ChannelState]:
    """The channel's measurement of ``truth`` at ``t_s`` (s; ``t_last``: the previous
    observation's time) and its next state."""
    dtype = truth.dtype
    periodic = p.period_s > 0
    due = s.sampled + p.period_s * _PERIOD_MARGIN
    eps = float(jnp.finfo(dtype).eps)
    if eps > 1e-10:  # float32: times k·Δt carry rounding far above the margin (x64: the numba test as is)
        due = due - 16.0 * eps * jnp.abs(t_s)
    hold = periodic & s.has_sampled & (t_s < due)
    dt = jnp.where(periodic, jnp.where(s.has_sampled, t_s - s.sampled, 0.0), jnp.maximum(0.0, t_s - t_last))
    k_walk, k_noise = jax.random.split(key)
    axes = p.noise_std.shape
    walk = jax.random.normal(k_walk, axes, dtype)
    noise = jax.random.normal(k_noise, axes, dtype)
    bias = jnp.where(dt > 0, s.bias + p.bias_walk_std * jnp.sqrt(jnp.maximum(dt, 0.0)) * walk, s.bias)
    faults = _episode_faults(p, s)
    if faults is None:
        err = bias + p.noise_std * noise
    else:
        active = _active(faults, t_s)
        err, scale = _additive_faults(faults, active, bias, t_s)
        err = err + p.noise_std * scale * noise
    m = jq.multiply(truth, jq.from_rotvec(err)) if attitude else truth + err
    sample = jnp.logical_not(hold)
    state = s.replace(
        bias=jnp.where(hold, s.bias, bias),
        sampled=jnp.where(periodic & sample, t_s, s.sampled),
        has_sampled=s.has_sampled | (periodic & sample),
    )
    if faults is not None:
        m, held, latched = _reading_faults(faults, active, s, m)
        state = state.replace(
            held=jnp.where(hold, s.held, held),
            latched=jnp.where(hold, s.latched, latched),
            delivered=s.delivered | sample,
        )
    return jnp.where(hold, s.last, m), state.replace(last=jnp.where(hold, s.last, m))


def active_flag(p: ChannelParams | None, s: ChannelState | None, t_s, dtype) -> jax.Array:
    """1.0 when a fault of the channel (its episode's, else the params') is active at ``t_s``
    (s), else 0.0: :meth:`SensorSuite.active_flags` of one channel."""
    f = None if p is None else _episode_faults(p, s)
    return jnp.zeros((), dtype) if f is None else jnp.any(_active(f, t_s)).astype(dtype)


@struct.dataclass
class SuiteParams:
    """An attitude plant's modeled sensors: one :class:`ChannelParams` per configured channel
    (None: the channel measures the truth): ``gyro`` (rad/s), ``star_tracker`` (the attitude;
    its errors a body rotation vector, rad), ``tachometer`` (wheel speeds, rad/s) and, on a
    plant with a field, ``magnetometer`` (the body field, T)."""

    gyro: ChannelParams | None = None
    star_tracker: ChannelParams | None = None
    tachometer: ChannelParams | None = None
    magnetometer: ChannelParams | None = None


@struct.dataclass
class SuiteState:
    """The sensors' runtime state: per configured channel its :class:`ChannelState`;
    ``t_last``, the last observation's time (s)."""

    t_last: jax.Array
    gyro: ChannelState | None = None
    star_tracker: ChannelState | None = None
    tachometer: ChannelState | None = None
    magnetometer: ChannelState | None = None


#: the suite's channels in key order (each channel's draws fold its index into the step's key)
SUITE_CHANNELS = ("gyro", "star_tracker", "tachometer", "magnetometer")
#: the channels whose readings are attitudes
_ATTITUDE_CHANNELS = frozenset({"star_tracker"})


def suite_params(
    config: dict, axes: dict[str, int], dtype, faults: dict[str, ChannelFaults] | None = None
) -> SuiteParams | None:
    """The :class:`SuiteParams` of a validated ``SensorSuite.config`` (None: no sensors);
    ``axes``: each channel's error axes; ``faults``: the faulted channels' faults
    (:func:`channel_faults`)."""
    if not config:
        return None
    faults = faults or {}
    return SuiteParams(**{name: params_of(c, axes[name], dtype, faults.get(name)) for name, c in config.items()})


def start_suite(key: jax.Array, p: SuiteParams, truths: dict[str, jax.Array], t_s) -> SuiteState:
    """The sensors at reset, before their first sample: each configured channel's bias drawn
    (:func:`initial_state`) from ``key`` folded with its index, at ``t_s`` (s)."""
    s = SuiteState(t_last=jnp.asarray(t_s))
    for i, name in enumerate(SUITE_CHANNELS):
        cp = getattr(p, name)
        if cp is not None and name in truths:
            s = s.replace(**{name: initial_state(jax.random.fold_in(key, i), cp, truths[name])})
    return s


def measure_suite(
    key: jax.Array, p: SuiteParams, s: SuiteState, truths: dict[str, jax.Array], t_s
) -> tuple[dict[str, jax.Array], SuiteState]:
    """Each channel's reading of ``truths`` (channel name → true value) at ``t_s`` (s) — a
    channel not modeled reads the truth — and the sensors' next state."""
    readings = {}
    for i, name in enumerate(SUITE_CHANNELS):
        if name not in truths:
            continue
        cp = getattr(p, name)
        if cp is None:
            readings[name] = truths[name]
            continue
        k = jax.random.fold_in(key, i)
        readings[name], cs = measure(k, cp, getattr(s, name), truths[name], t_s, s.t_last, name in _ATTITUDE_CHANNELS)
        s = s.replace(**{name: cs})
    return readings, s.replace(t_last=t_s)


def suite_flags(p: SuiteParams | None, s: SuiteState | None, names: tuple[str, ...], t_s, dtype) -> jax.Array:
    """The ``fault_hint`` flags of the channels ``names`` (the numba env's channel order): 1.0
    where a fault of the channel is active at ``t_s`` (s)."""
    return jnp.stack(
        [
            active_flag(None if p is None else getattr(p, n), None if s is None else getattr(s, n), t_s, dtype)
            for n in names
        ]
    )


@struct.dataclass
class StateSensor:
    """A plant's one ``state`` sensor channel (LinearSystem's, FuelSlosh's) at runtime: the
    ``channel``'s state and ``t_last``, the last observation's time (s)."""

    channel: ChannelState
    t_last: jax.Array


def state_flag(p: ChannelParams | None, s: StateSensor | None, t_s, dtype) -> jax.Array:
    """The ``fault_hint`` flag of a plant's ``state`` sensor: 1.0 with a fault active at ``t_s`` (s)."""
    return active_flag(p, None if s is None else s.channel, t_s, dtype)


def start_state_sensor(key: jax.Array, p: ChannelParams, truth: jax.Array) -> tuple[jax.Array, StateSensor]:
    """A ``state`` sensor at reset (:meth:`SensorSuite.reset` and the first sample at
    ``t = 0``): the measurement of ``truth`` and the sensor's state."""
    k_bias, k_measure = jax.random.split(key)
    zero = jnp.zeros((), dtype=truth.dtype)
    start = StateSensor(channel=initial_state(k_bias, p, truth), t_last=zero)
    return measure_state(k_measure, p, start, truth, zero)


def measure_state(
    key: jax.Array, p: ChannelParams, s: StateSensor, truth: jax.Array, t_s
) -> tuple[jax.Array, StateSensor]:
    """The ``state`` sensor's measurement of ``truth`` (a vector channel) at ``t_s`` (s) and
    its next state."""
    m, channel = measure(key, p, s.channel, truth, t_s, s.t_last, False)
    return m, StateSensor(channel=channel, t_last=jnp.asarray(t_s, dtype=truth.dtype))


__all__ = [
    "SENSOR_STREAM",
    "SUITE_CHANNELS",
    "SuiteParams",
    "SuiteState",
    "measure_suite",
    "start_suite",
    "suite_params",
    "StateSensor",
    "measure_state",
    "start_state_sensor",
    "FAULT_CODES",
    "ChannelFaults",
    "ChannelParams",
    "ChannelState",
    "channel_faults",
    "initial_state",
    "measure",
    "active_flag",
    "state_flag",
    "suite_flags",
    "params_of",
]
