"""Sensor models and sensor faults, shared by every env (off by default: truth observed).

An env declares its sensor *channels* (name, size, kind) and takes ``sensors={...}``:
one entry per channel to model, each a dict of

=====================  ==============================================================
key                    meaning (units are the channel's, see below)
=====================  ==============================================================
``noise_std``          white measurement noise, standard deviation per sample
                       (number or one per axis)
``bias_walk_std``      bias random walk: ``b ← b + bias_walk_std · √Δt · N(0, 1)``
                       per sample (units per √s; number or one per axis)
``initial_bias``       bias at reset (number or one per axis), default 0
``initial_bias_std``   plus a draw ``N(0, initial_bias_std²)`` per axis at reset
                       (number or one per axis)
``period_s``           sample period, s (default 0: a new sample at every observation);
                       a slower sensor repeats its last sample between samples (a star
                       tracker at 2 Hz under a 10 Hz control loop), the first at reset
=====================  ==============================================================

Channels of the suite: ``gyro`` (body rate, rad/s), ``star_tracker`` (attitude; its
noise and bias are a small body-frame rotation vector in rad: ``q_m = q ⊗ exp(e)``),
``tachometer`` (wheel speeds, rad/s), ``magnetometer`` (body-frame field, T, in envs with
a field) and ``state`` (the state vector of LinearSystem-v0 and FuelSlosh-v0, whose
entries have different units: give their noise one per axis). A channel left out of
``sensors`` measures the truth, but still takes faults.

Sensor faults use the actuator faults' dict format (:mod:`attitude_envs.faults`) with
``"target": "sensor"`` and a ``"sensor"`` field::

    {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 1, "value": 0.01,
     "onset_s": 20.0, "duration_s": None}

=================  ==========================================================  ==============
kind               effect on axis ``index`` of the measurement from onset on    value
=================  ==========================================================  ==============
bias               ``+ value``                                                  channel units
drift              ``+ value · (t − onset)``                                    units per s
stuck              frozen at the value measured at onset, or at ``value``      channel units
                   (star tracker: whole attitude frozen, ``index: "all"``)
dropout            ``NaN`` (``"mode": "nan"``, default) or the last delivered   —
                   sample (``"mode": "hold"``); star tracker: ``index: "all"``
noise_increase     white noise standard deviation multiplied by ``value``      factor ≥ 1
=================  ==========================================================  ==============

``index`` is an axis, ``"random"`` or ``"all"``; ``value``, ``onset_s`` and
``duration_s`` take ``{"uniform": [a, b]}`` draws. All sensor randomness (noise, bias
walk, draws) comes from a generator spawned from the env's RNG at reset, so turning
sensors on does not change the plant's random stream, and same seed gives same noise.
Sensors are sampled at the observation times (reset and the end of each control step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.faults import _draw

SENSOR_KINDS = ("bias", "drift", "stuck", "dropout", "noise_increase")
_FAULT_KEYS = {"kind", "target", "sensor", "index", "value", "onset_s", "duration_s"}
_NEEDS_VALUE = {"bias", "drift", "noise_increase"}
_CHANNEL_KEYS = {"noise_std", "bias_walk_std", "initial_bias", "initial_bias_std", "period_s"}
_WHOLE_SENSOR = {"stuck", "dropout"}  # on an attitude channel these act on the whole quaternion


@dataclass(frozen=True)
class Channel:
    """One sensor of an env: ``kind`` is ``"vector"`` (``size`` axes, additive errors) or
    ``"attitude"`` (a quaternion, errors are a 3-axis body rotation vector)."""

    name: str
    size: int
    kind: str = "vector"
    units: str = ""

    @property
    def axes(self) -> int:
        return 3 if self.kind == "attitude" else self.size


@dataclass
class RealizedSensorFault:
    """One sensor fault of one episode with every draw made (ground truth)."""

    kind: str
    sensor: str
    index: int | str  # an axis, or "all" for whole-attitude stuck/dropout
    value: float | None
    onset_s: float
    duration_s: float | None
    mode: str = "nan"
    held: np.ndarray | None = field(default=None, repr=False)  # the stuck reading once latched (runtime state)

    def active(self, t_s: float) -> bool:
        end = np.inf if self.duration_s is None else self.onset_s + self.duration_s
        return self.onset_s <= t_s < end

    def as_dict(self) -> dict:
        d = {"kind": self.kind, "target": "sensor", "sensor": self.sensor, "index": self.index, "value": self.value}
        d.update({"onset_s": self.onset_s, "duration_s": self.duration_s})
        if self.kind == "dropout":
            d["mode"] = self.mode
        return d


def _std(name: str, value, axes: int) -> float | np.ndarray:
    """A standard deviation of a channel: a number ≥ 0 (kept a float: the estimators read
    the gyro's as scalars) or one per axis (a read-only array of ``axes`` numbers ≥ 0)."""
    if np.ndim(value) == 0:
        return validation.nonnegative(name, value)
    arr = validation.finite_array(name, value)
    if arr.shape != (axes,) or np.any(arr < 0):
        raise ValueError(f"{name} must be a number >= 0 or {axes} of them (one per axis), got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def fault_axes(config: dict, channel: Channel) -> list[int | str]:
    """The axes a validated sensor fault dict ``config`` acts on in ``channel``, as an episode
    realizes them: ``["all"]`` (a stuck or dropped attitude: the whole reading), every axis
    (``index: "all"`` otherwise), ``["random"]`` (one axis, drawn per episode) or the one given."""
    index = config.get("index", "random")
    if index == "all" and channel.kind == "attitude" and config["kind"] in _WHOLE_SENSOR:
        return ["all"]
    if index == "all":
        return list(range(channel.axes))
    return ["random"] if index == "random" else [int(index)]


def sensor_faults_of(configs: list[dict] | None) -> list[tuple[int, dict]]:
    """The ``(position, dict)`` entries of a fault list that target a sensor."""
    if configs is None:
        return []
    if not isinstance(configs, (list, tuple)):
        raise ValueError(f"faults must be a list of fault dicts, got {configs!r}")
    return [(i, c) for i, c in enumerate(configs) if isinstance(c, dict) and c.get("target") == "sensor"]


class SensorSuite:
    """Measures an env's truth through noisy, biased, possibly faulty sensors.

    ``enabled`` is False when neither ``config`` nor any sensor fault is given: the env
    then observes the truth and this object draws nothing.
    """

    def __init__(self, config: dict | None, channels: list[Channel], faults: list[dict] | None = None) -> None:
        self.channels = {c.name: c for c in channels}
        self.config = self._validated_config(config)
        self.fault_configs = self._validated_faults(faults)
        self.enabled = bool(self.config) or bool(self.fault_configs)
        self.realized: list[RealizedSensorFault] = []
        self.bias: dict[str, np.ndarray] = {}
        self._last: dict[str, np.ndarray] = {}
        self._t_last = 0.0
        self._t_sampled: dict[str, float] = {}
        self._rng = np.random.default_rng(0)

    # ------------------------------------------------------------------ config
    def _validated_config(self, config) -> dict[str, dict]:
        if config is None:
            return {}
        if not isinstance(config, dict):
            raise ValueError(f"sensors must be a dict of sensor name -> parameters, got {config!r}")
        out = {}
        for name, params in config.items():
            validation.choice("sensors", name, set(self.channels))
            if not isinstance(params, dict):
                raise ValueError(f"sensors[{name!r}] must be a dict with keys {sorted(_CHANNEL_KEYS)}, got {params!r}")
            validation.known_keys(f"sensors[{name!r}]", params, _CHANNEL_KEYS)
            axes = self.channels[name].axes
            p = {}
            for key in ("noise_std", "bias_walk_std", "initial_bias_std"):
                p[key] = _std(f"sensors[{name!r}].{key}", params.get(key, 0.0), axes)
            bias0 = validation.finite_array(f"sensors[{name!r}].initial_bias", params.get("initial_bias", 0.0))
            if bias0.ndim == 0:
                bias0 = np.full(axes, float(bias0))
            if bias0.shape != (axes,):
                raise ValueError(f"sensors[{name!r}].initial_bias must be a number or have {axes} entries")
            p["initial_bias"] = bias0
            p["period_s"] = validation.nonnegative(f"sensors[{name!r}].period_s", params.get("period_s", 0.0))
            out[name] = p
        return out

    def _validated_faults(self, configs) -> list[dict]:
        entries = sensor_faults_of(configs)
        for i, c in entries:
            self._validate_fault(c, f"faults[{i}]")
        return [dict(c) for _, c in entries]

    def _validate_fault(self, c: dict, where: str) -> None:
        kind = validation.choice(f"{where}.kind", c.get("kind"), SENSOR_KINDS)
        name = validation.choice(f"{where}.sensor", c.get("sensor"), set(self.channels))
        extra = {"mode"} if kind == "dropout" else set()
        validation.known_keys(f"{where} ({kind})", c, _FAULT_KEYS | extra)
        channel = self.channels[name]
        index = c.get("index", "random")
        if isinstance(index, str):
            validation.choice(f"{where}.index", index, {"random", "all"})
        elif not (isinstance(index, (int, np.integer)) and 0 <= int(index) < channel.axes):
            raise ValueError(
                f"{where}.index must be an integer in [0, {channel.axes - 1}], 'random' or 'all', got {index!r}"
            )
        if channel.kind == "attitude" and kind in _WHOLE_SENSOR and index != "all":
            raise ValueError(f"{where}.index must be 'all' for {kind} of the attitude sensor {name!r}, got {index!r}")
        value = c.get("value")
        if kind in _NEEDS_VALUE and value is None:
            raise ValueError(f"{where}.value is required for kind {kind!r}")
        if kind == "dropout" and value is not None:
            raise ValueError(f"{where}.value must be null for dropout (use 'mode'), got {value!r}")
        if kind == "stuck" and channel.kind == "attitude" and value is not None:
            raise ValueError(f"{where}.value must be null for stuck of the attitude sensor (held at onset)")
        if value is not None:
            _draw(f"{where}.value", value, None, 1.0 if kind == "noise_increase" else None, None)
        if kind == "noise_increase" and not np.any(self.config.get(name, {}).get("noise_std", 0.0)):
            raise ValueError(f"{where}: noise_increase needs sensors[{name!r}].noise_std > 0 (it scales that noise)")
        if kind == "dropout":
            validation.choice(f"{where}.mode", c.get("mode", "nan"), {"nan", "hold"})
        _draw(f"{where}.onset_s", c.get("onset_s", 0.0), None, 0.0, None)
        if c.get("duration_s") is not None:
            _draw(f"{where}.duration_s", c["duration_s"], None, 0.0, None)

    # ------------------------------------------------------------------ episode
    def reset(self, rng: np.random.Generator, faults: list[dict] | None = None) -> None:
        """Start an episode: spawn the sensors' generator from ``rng`` (without advancing
        it), draw initial biases and the episode's sensor faults (``faults`` replaces the
        construction-time list; its non-sensor entries are ignored here)."""
        chosen = self.fault_configs if faults is None else self._validated_faults(faults)
        self.enabled = bool(self.config) or bool(chosen)
        self.realized, self.bias, self._last = [], {}, {}
        self._t_last = 0.0
        self._t_sampled = {}
        if not self.enabled:
            return
        self._rng = rng.spawn(1)[0]
        rng_s = self._rng
        for name, p in self.config.items():
            self.bias[name] = p["initial_bias"] + p["initial_bias_std"] * rng_s.normal(size=self.channels[name].axes)
        for i, c in enumerate(chosen):
            where = f"faults[{i}]"
            kind, name = c["kind"], c["sensor"]
            channel = self.channels[name]
            indices = fault_axes(c, channel)
            if indices == ["random"]:
                indices = [int(rng_s.integers(channel.axes))]
            onset = _draw(f"{where}.onset_s", c.get("onset_s", 0.0), rng_s, 0.0)
            duration = (
                None if c.get("duration_s") is None else _draw(f"{where}.duration_s", c["duration_s"], rng_s, 0.0)
            )
            low = 1.0 if kind == "noise_increase" else None
            for idx in indices:
                value = None if c.get("value") is None else _draw(f"{where}.value", c["value"], rng_s, low)
                self.realized.append(RealizedSensorFault(kind, name, idx, value, onset, duration, c.get("mode", "nan")))

    def measure(self, truth: dict[str, np.ndarray], t_s: float) -> dict[str, np.ndarray]:
        """The measurements of every channel at time ``t_s`` (s) given the ``truth``
        (vectors; the attitude as a scalar-last quaternion). Advances the bias walks and
        draws the noise (one normal per axis per configured channel, every call); a channel
        with a ``period_s`` between its samples repeats its last sample and draws nothing."""
        dt_all = max(0.0, t_s - self._t_last)
        self._t_last = t_s
        out = {}
        for name, channel in self.channels.items():
            if name not in truth:
                continue
            p = self.config.get(name)
            dt = dt_all
            if p is not None and p["period_s"] > 0:
                sampled = self._t_sampled.get(name)
                if sampled is not None and t_s < sampled + p["period_s"] * (1.0 - 1e-9):
                    out[name] = self._last[name].copy()  # between samples: the last one again
                    continue
                dt = 0.0 if sampled is None else t_s - sampled
                self._t_sampled[name] = t_s
            err = np.zeros(channel.axes)
            noise_scale = np.ones(channel.axes)
            if p is not None:
                if np.any(p["bias_walk_std"] > 0) and dt > 0:
                    self.bias[name] = self.bias[name] + p["bias_walk_std"] * np.sqrt(dt) * self._rng.normal(
                        size=channel.axes
                    )
                noise = self._rng.normal(size=channel.axes)
                err = err + self.bias[name]
            faults = [f for f in self.realized if f.sensor == name and f.active(t_s)]
            for f in self.realized:
                if f.sensor == name and not f.active(t_s):
                    f.held = None
            for f in faults:
                if f.kind == "bias":
                    err[f.index] += f.value
                elif f.kind == "drift":
                    err[f.index] += f.value * (t_s - f.onset_s)
                elif f.kind == "noise_increase":
                    noise_scale[f.index] *= f.value
            if p is not None:
                err = err + p["noise_std"] * noise_scale * noise
            if channel.kind == "attitude":
                m = quaternion.multiply(np.asarray(truth[name], dtype=float), quaternion.from_rotvec(err))
            else:
                m = np.asarray(truth[name], dtype=float) + err
            for f in faults:
                if f.kind not in _WHOLE_SENSOR:
                    continue
                sel = slice(None) if f.index == "all" else f.index
                if f.kind == "stuck":
                    if f.held is None:
                        f.held = np.array(m[sel], dtype=float) if f.value is None else np.array(f.value)
                    m[sel] = f.held
                elif f.mode == "nan":
                    m[sel] = np.nan
                else:  # hold the last delivered sample (the current one if there is none yet)
                    m[sel] = self._last.get(name, m)[sel]
            self._last[name] = m.copy()
            out[name] = m
        return out

    def parameters(self, name: str) -> dict:
        """The configured (nominal) noise parameters of channel ``name`` (zeros if unmodelled;
        each standard deviation a float, or an array where it was given one per axis)."""
        validation.choice("sensor", name, set(self.channels))
        axes = self.channels[name].axes
        zero = {
            "noise_std": 0.0,
            "bias_walk_std": 0.0,
            "initial_bias_std": 0.0,
            "initial_bias": np.zeros(axes),
            "period_s": 0.0,
        }
        return dict(self.config.get(name, zero))

    def active_flags(self, t_s: float) -> np.ndarray:
        """1.0 per channel (in declaration order) with an active fault at ``t_s``, else 0.0."""
        active = {f.sensor for f in self.realized if f.active(t_s)}
        return np.array([1.0 if name in active else 0.0 for name in self.channels])

    def info(self, t_s: float) -> list[dict]:
        """Ground truth of the episode's sensor faults for ``info["faults"]``."""
        return [dict(f.as_dict(), active=bool(f.active(t_s))) for f in self.realized]
