"""The suite's sensor models (:mod:`attitude_envs.sensors`) as arrays, for the JAX plants:
white noise, a bias drawn at reset, its random walk, and a sample period with
sample-and-hold between samples (a star tracker slower than the control loop), for vector
channels (additive errors) and attitude channels (``q_m = q ⊗ exp(e)``, ``e`` a body rotation
vector). Sensor faults are not modeled here.

:meth:`attitude_envs.sensors.SensorSuite.measure`'s law, step for step: a channel samples at
the observation times; one with a ``period_s`` repeats its last sample until
``period_s · (1 − 10⁻⁹)`` has passed since its previous one (the first at reset); at a sample
the bias walks by ``bias_walk_std · √Δt · N(0, 1)`` over the time since the channel's previous
sample (since the previous observation without a period), then the noise is drawn. In
float32 the sample test allows the rounding of the times (16 ulp of ``t``): a period that is a
multiple of the control period samples on the numba env's (float64) steps. The draws
come from JAX keys: the same law as the numba layer's numpy generator, not the same numbers.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.jax import quaternion as jq

#: the relative margin of the sample-period test (:meth:`SensorSuite.measure`'s)
_PERIOD_MARGIN = 1.0 - 1e-9
#: folded into a plant's reset and step keys for its sensors' draws (the plant's other draws
#: unchanged, so turning the sensors on changes no start, fault or process noise)
SENSOR_STREAM = 0x534E53


@struct.dataclass
class ChannelParams:
    """One channel's model (one entry per axis): ``noise_std``, ``bias_walk_std`` (per √s),
    ``initial_bias``, ``initial_bias_std``; ``period_s`` (0: a sample at every observation)."""

    noise_std: jax.Array
    bias_walk_std: jax.Array
    initial_bias: jax.Array
    initial_bias_std: jax.Array
    period_s: jax.Array


@struct.dataclass
class ChannelState:
    """One channel's runtime state: its ``bias``, ``last`` sample (the channel's size: 4 for an
    attitude), the time of its last sample ``sampled`` (s) and ``has_sampled``."""

    bias: jax.Array
    last: jax.Array
    sampled: jax.Array
    has_sampled: jax.Array


def params_of(config: dict, axes: int, dtype) -> ChannelParams:
    """A channel's :class:`ChannelParams` from its validated ``SensorSuite.config`` entry."""

    def f(key):
        return jnp.asarray(np.broadcast_to(np.asarray(config[key], dtype=float), (axes,)), dtype=dtype)

    return ChannelParams(
        noise_std=f("noise_std"),
        bias_walk_std=f("bias_walk_std"),
        initial_bias=f("initial_bias"),
        initial_bias_std=f("initial_bias_std"),
        period_s=jnp.asarray(float(config["period_s"]), dtype=dtype),
    )


def initial_state(key: jax.Array, p: ChannelParams, truth: jax.Array) -> ChannelState:
    """A channel at reset, before its first sample: its bias drawn, no sample yet."""
    bias = p.initial_bias + p.initial_bias_std * jax.random.normal(key, p.noise_std.shape, p.noise_std.dtype)
    zero = jnp.zeros((), dtype=truth.dtype)
    return ChannelState(bias=bias, last=truth, sampled=zero, has_sampled=jnp.asarray(False))


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
    err = bias + p.noise_std * noise
    m = jq.multiply(truth, jq.from_rotvec(err)) if attitude else truth + err
    sample = jnp.logical_not(hold)
    return jnp.where(hold, s.last, m), ChannelState(
        bias=jnp.where(hold, s.bias, bias),
        last=jnp.where(hold, s.last, m),
        sampled=jnp.where(periodic & sample, t_s, s.sampled),
        has_sampled=s.has_sampled | (periodic & sample),
    )


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


def suite_params(config: dict, axes: dict[str, int], dtype) -> SuiteParams | None:
    """The :class:`SuiteParams` of a validated ``SensorSuite.config`` (None: no sensors);
    ``axes``: each channel's error axes."""
    if not config:
        return None
    return SuiteParams(**{name: params_of(c, axes[name], dtype) for name, c in config.items()})


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


@struct.dataclass
class StateSensor:
    """A plant's one ``state`` sensor channel (LinearSystem's, FuelSlosh's) at runtime: the
    ``channel``'s state and ``t_last``, the last observation's time (s)."""

    channel: ChannelState
    t_last: jax.Array


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
    "ChannelParams",
    "ChannelState",
    "initial_state",
    "measure",
    "params_of",
]
