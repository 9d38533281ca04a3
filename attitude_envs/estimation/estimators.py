"""Estimators that stand between an env's sensors and an analytic controller.

Each estimator is built from an env (its *nominal* model and the nominal sensor specs of
its sensor layer, ``env.unwrapped.sensor_layer.parameters(name)``: never the episode's
drawn truth) and turns each step's ``(obs, info)`` into the controller's view: the
observation rebuilt from the estimate and a shallow copy of ``info`` whose ``measured``
entry is the estimate (``info["estimate"]`` adds the filter's own quantities). The env's
``info`` is not modified.

=======================  ==================  =================================================
class                    envs                filter
=======================  ==================  =================================================
:class:`GyrostatMEKF`    ReactionWheel-v0,   attitude + gyro-bias MEKF (:class:`AttitudeMEKF`)
                         AirBearing-v0       on ``gyro`` and ``star_tracker``
:class:`MagnetorquerMEKF`  Magnetorquer-v0   the same MEKF on the orbital-frame attitude, plus
                                             the ``magnetometer`` against the field model in
                                             ``info["magnetic_field_orbital_t"]``
:class:`LinearKF`        LinearSystem-v0     ``filterpy`` Kalman filter on the env's (A, B)
:class:`SloshKF`         FuelSlosh-v0        ``filterpy`` Kalman filter on the full plant's
                                             linearization in the physical inputs (δ, M_c) at
                                             the design axial speed, plus an input-disturbance
                                             state on each input (thruster bias)
=======================  ==================  =================================================

Interface: ``reset(obs, info)`` with the episode's first observation, then
``update(obs, info)`` with every later one; both return the controller's
``(obs, info)``. :func:`estimator_for` builds the one of an env by name (``"mekf"``,
``"kf"``).

**Slow sensors.** A sensor with ``period_s`` longer than the control period repeats its
last sample between samples (:mod:`attitude_envs.sensors`), and the sample time is not
in ``info``. The filters detect a new sample by a *change of value*: a repeated reading
is no new information and is not fed to the filter again (an exactly repeated noisy
reading has probability zero; a stuck or held sensor then also stops updating the
filter, which then coasts on the gyro or the model). This holds for a sensor sampled at
every step too: an outage that holds its last sample must not be fused again and again.

**Delay.** The Kalman filters propagate with the input that acted over the step: the
command ``info["commanded"]`` of ``delay_steps`` steps earlier, ``delay_steps`` being the
env's nominal computation delay (``env.unwrapped.conditions.delay_steps``; zeros before
the first command arrives). The MEKFs propagate on the gyro and need no input.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.linalg import expm

from attitude_envs import quaternion, validation
from attitude_envs.estimation.mekf import AttitudeMEKF, NISFaultDetector
from attitude_envs.info import MEASURED

__all__ = [
    "ESTIMATORS",
    "GyrostatMEKF",
    "LinearKF",
    "MagnetorquerMEKF",
    "SampleGate",
    "SloshKF",
    "estimator_for",
]

_MIN_VAR = 1e-18  # floor of a noise variance (a noise-free channel), keeps S invertible


class SampleGate:
    """Tells whether a sensor's reading is a new sample: when it differs from the previous
    one, whatever the sensor's period (see the module docstring). A sensor held by a
    dropout repeats its last sample exactly, so a filter coasts through the outage instead
    of re-fusing a stale reading; NaN readings are never new."""

    def __init__(self) -> None:
        self._last: np.ndarray | None = None

    def reset(self, reading: np.ndarray) -> None:
        self._last = np.array(reading, dtype=float, copy=True)

    def is_new(self, reading: np.ndarray) -> bool:
        r = np.asarray(reading, dtype=float)
        if not np.all(np.isfinite(r)):
            return False
        new = self._last is None or not np.array_equal(r, self._last)
        self._last = r.copy()
        return new


def _sensor_layer(env, channels: tuple[str, ...], who: str):
    base = env.unwrapped
    layer = getattr(base, "sensor_layer", None)
    if layer is None or any(c not in layer.channels for c in channels):
        raise ValueError(f"{who} needs an env with sensor channels {list(channels)}")
    if not layer.enabled:
        raise ValueError(f"{who} needs sensors on: conditions='flight', conditions={{'sensors': True}} or sensors=")
    return layer


def _scalar(std) -> float:
    """A channel's standard deviation as one number (the largest axis's when per axis)."""
    return float(np.max(std))


def _per_axis(std, axes: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(std, dtype=float), (axes,)).copy()


def _mekf_params(layer, filter_params: dict | None) -> dict:
    gyro, star = layer.parameters("gyro"), layer.parameters("star_tracker")
    params = {
        "gyro_noise_std": _scalar(gyro["noise_std"]),
        "bias_walk_std": _scalar(gyro["bias_walk_std"]),
        "star_noise_std": _scalar(star["noise_std"]),
        "initial_bias_std": _scalar(gyro["initial_bias_std"]),
        "initial_bias": gyro["initial_bias"],
    }
    unknown = set(filter_params or {}) - set(params)
    if unknown:
        raise ValueError(f"filter_params has unknown keys {sorted(unknown)}; accepted: {sorted(params)}")
    params.update(filter_params or {})
    # a star-tracker bias (a mounting error) is not estimated: its spread counts as noise
    return params


class GyrostatMEKF:
    """MEKF (attitude, gyro bias) for ReactionWheel-v0 and AirBearing-v0: the gyro at every
    step, the star tracker when it delivers a new sample. The observation's first six
    entries become the nominal model's error state of the estimate (``q̂``, ``ω_m − b̂``);
    later entries (wheel momentum, hints) pass through as measured. ``info["measured"]``:
    ``attitude`` q̂, ``rate_rad_s`` ω̂, the wheel speeds and target as measured.

    **Fault detection** (``fault_detection``, default on): a χ² test of each new
    star-tracker sample's innovation (:class:`~attitude_envs.estimation.mekf.NISFaultDetector`);
    ``fault_confirm`` consecutive samples above the ``1 − fault_false_alarm`` quantile
    declare a gyro fault and re-inflate the bias covariance (``fault_bias_std``, rad/s;
    ``None``: the jump the innovation implies), so the bias re-converges after a jump.
    Read back: :attr:`detections` (times, s), :attr:`fault_detected_at_s` (the first, or
    ``None``) and ``info["estimate"]``'s ``fault_detected`` and ``nis``."""

    name = "mekf"

    def __init__(
        self,
        env,
        filter_params: dict | None = None,
        fault_detection: bool = True,
        fault_false_alarm: float = 1e-3,
        fault_confirm: int = 2,
        fault_bias_std: float | None = None,
        fault_window_s: float = 1.0,
    ) -> None:
        layer = _sensor_layer(env, ("gyro", "star_tracker"), type(self).__name__)
        self.model = env.unwrapped.model
        # built (and its settings validated) even when off, so a bad setting is refused either way
        detector = NISFaultDetector(fault_false_alarm, fault_confirm, fault_bias_std, fault_window_s)
        self.detector = detector if validation.flag("fault_detection", fault_detection) else None
        self.filter = AttitudeMEKF(**_mekf_params(layer, filter_params), detector=self.detector)
        self.star_gate = SampleGate()
        self._t = 0.0
        self.updates = 0  # star-tracker updates this episode

    def reset(self, obs: np.ndarray, info: dict[str, Any]):
        s = info["sensors"]
        self.filter.reset(s["star_tracker"], s["gyro"], float(info["time_s"]))
        self.star_gate.reset(s["star_tracker"])
        self._reset_gates(s)
        self._t = float(info["time_s"])
        self.updates = 0
        return self._view(obs, info)

    def update(self, obs: np.ndarray, info: dict[str, Any]):
        s = info.get("sensors")
        if s is not None:
            star = s["star_tracker"] if self.star_gate.is_new(s["star_tracker"]) else None
            self.updates += star is not None
            self.filter.step(s["gyro"], star, float(info["time_s"]) - self._t, **self._step_extras(s, info))
        self._t = float(info["time_s"])
        return self._view(obs, info)

    @property
    def detections(self) -> list[float]:
        """Times (s, env time) of the gyro faults declared this episode (empty without a detector)."""
        return [] if self.detector is None else list(self.detector.detections)

    @property
    def fault_detected_at_s(self) -> float | None:
        """Time (s) of this episode's first declared gyro fault, ``None`` if none."""
        d = self.detections
        return d[0] if d else None

    def _fault_estimate(self) -> dict:
        """``info["estimate"]``'s fault entries: ``fault_detected`` (so far this episode) and
        the latest star sample's ``nis`` (NaN before the first or without a detector)."""
        det = self.detector
        return {"fault_detected": bool(det and det.detections), "nis": det.nis if det else float("nan")}

    def _reset_gates(self, sensors: dict) -> None:
        """Reset the gates of the other sensors (none here)."""

    def _step_extras(self, sensors: dict, info: dict[str, Any]) -> dict:
        """More keywords of :meth:`AttitudeMEKF.step` at this step (none here)."""
        return {}

    def _view(self, obs, info):
        f = self.filter
        measured = info[MEASURED]
        rate = f.rate
        wheels = np.zeros(self.model.params.n_wheels)
        x = self.model.error_state(f.attitude, rate, wheels, np.asarray(measured["target_attitude"], dtype=float))
        out = np.array(obs, dtype=np.float32)
        out[:6] = x[:6]
        estimate = {
            "attitude": f.attitude.copy(),
            "gyro_bias_rad_s": f.bias.copy(),
            "rate_rad_s": rate.copy(),
            "covariance": f.covariance.copy(),
            **self._fault_estimate(),
        }
        view = dict(info, estimate=estimate)
        view[MEASURED] = dict(measured, attitude=f.attitude.copy(), rate_rad_s=rate.copy())
        return out, view


class MagnetorquerMEKF(GyrostatMEKF):
    """MEKF for Magnetorquer-v0: attitude relative to the orbital frame and gyro bias. The
    gyro measures the inertial rate ω_bi; the orbital frame turns at ``−ω0 e_y``
    (``info["orbit"]["rate_rad_s"]``) relative to inertial. Updates: the star tracker on
    each new sample and, with ``use_magnetometer`` (default) and a modelled
    ``magnetometer`` channel, the magnetometer on each new sample against the env's field
    model in orbital axes (``info["magnetic_field_orbital_t"]``, the env's field model),
    with the nominal ``magnetometer`` noise of the sensor layer (its bias spread counted as
    white noise: the bias is not estimated); a magnetometer left out of the sensor
    config (it then reads the true field) is not used. Fault detection on the star tracker
    as :class:`GyrostatMEKF` (its keywords).

    The observation's error state ``[q_e,vec, ω_e]`` is rebuilt from the estimate against
    ``info["reference"]`` (``q_e = q_d* ⊗ q̂``, sign with ``q_e,w ≥ 0``, ``ω_e = ω̂_bo −
    C(q_e)ᵀ ω_d``); the wheel speed and field entries pass through as measured.
    ``info["measured"]``: ``attitude`` q̂, ``rate_rad_s`` ω̂_bo, ``inertial_rate_rad_s``
    ω̂_bi, ``wheel_momentum_nms`` from the measured wheel speed and ω̂_bi; the wheel speed
    and the magnetometer's field as measured (the allocation uses the measured field)."""

    name = "mekf"

    def __init__(
        self, env, filter_params: dict | None = None, use_magnetometer: bool = True, **fault_params: Any
    ) -> None:
        super().__init__(env, filter_params, **fault_params)
        layer = env.unwrapped.sensor_layer
        mag = layer.parameters("magnetometer") if "magnetometer" in layer.channels else None
        self.magnetometer_std = None
        if use_magnetometer and mag is not None and "magnetometer" in layer.config:
            self.magnetometer_std = float(np.hypot(_scalar(mag["noise_std"]), _scalar(mag["initial_bias_std"])))
        self.mag_gate = SampleGate()
        self._wheel_inertia = float(self.model.params.wheel_inertia_kg_m2)

    @staticmethod
    def _frame_rate(info) -> np.ndarray:
        return np.array([0.0, -float(info["orbit"]["rate_rad_s"]), 0.0])

    def _reset_gates(self, sensors: dict) -> None:
        self.mag_gate.reset(sensors.get("magnetometer", np.full(3, np.nan)))

    def _step_extras(self, sensors: dict, info: dict[str, Any]) -> dict:
        """The orbital frame's rate and, on a new magnetometer sample, the field measurement."""
        vectors = []
        if self.magnetometer_std is not None and self.mag_gate.is_new(sensors["magnetometer"]):
            vectors.append((sensors["magnetometer"], info["magnetic_field_orbital_t"], self.magnetometer_std))
        return {"frame_rate_rad_s": self._frame_rate(info), "vectors": vectors}

    def _view(self, obs, info):
        f = self.filter
        q = f.attitude.copy()
        w_bi = f.rate
        # ω_bo = ω_bi − A(q) ω_oi, ω_oi = −ω0 e_y in orbital axes
        w_bo = w_bi - quaternion.to_matrix(q).T @ self._frame_rate(info)
        ref = info["reference"]
        x = error_state(q, w_bo, np.asarray(ref["attitude"], dtype=float), np.asarray(ref["rate_rad_s"], dtype=float))
        out = np.array(obs, dtype=np.float32)
        out[:6] = x
        measured = info[MEASURED]
        wheel = np.asarray(measured["wheel_speed_rad_s"], dtype=float)
        estimate = {
            "attitude": q.copy(),
            "gyro_bias_rad_s": f.bias.copy(),
            "rate_rad_s": w_bo.copy(),
            "inertial_rate_rad_s": w_bi.copy(),
            "covariance": f.covariance.copy(),
            **self._fault_estimate(),
        }
        view = dict(info, estimate=estimate)
        view[MEASURED] = dict(
            measured,
            attitude=q,
            rate_rad_s=w_bo,
            inertial_rate_rad_s=w_bi.copy(),
            wheel_momentum_nms=float(self._wheel_inertia * (wheel[0] + w_bi[1])),
        )
        return out, view


def error_state(q: np.ndarray, rate: np.ndarray, q_d: np.ndarray, w_d: np.ndarray) -> np.ndarray:
    """Magnetorquer-v0's error state ``[q_e,vec, ω_e]``: ``q_e = q_d* ⊗ q`` (sign with
    ``q_e,w ≥ 0``), ``ω_e = ω − C(q_e)ᵀ ω_d`` (``C(q_e)ᵀ`` maps reference-frame vectors to
    the body), as the env's observation."""
    qe = quaternion.multiply(quaternion.conjugate(q_d), q)
    if qe[3] < 0:
        qe = -qe
    return np.concatenate([qe[:3], rate - quaternion.to_matrix(qe).T @ w_d])


def _discretize(a: np.ndarray, b: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold ``(A_d, B_d)`` of ``ẋ = A x + B u`` over ``dt_s``."""
    n, m = b.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = a, b
    e = expm(block * dt_s)
    return e[:n, :n], e[:n, n:]


class _InputKF:
    """A filterpy Kalman filter of ``x' = F x + G u + w``, ``z = H x + v`` whose input is
    the command of ``delay_steps`` steps earlier (``info["commanded"]``), measured by the
    ``state`` channel with new-sample detection. Subclasses call :meth:`_setup` with
    ``F, G, Q``, the measurement noise variance of every channel entry and the prior, then
    :meth:`_start` at reset with the rows of the state each measured entry reads."""

    name = "kf"

    def _setup(self, f, g, q, var, p0, delay_steps: int) -> None:
        self._f, self._g, self._q = f, g, q
        self._var = np.asarray(var, dtype=float)
        self._p0 = p0
        self._m = g.shape[1]
        self.delay_steps = int(delay_steps)
        self.gate = SampleGate()
        self._inputs: deque = deque()
        self.kf: KalmanFilter | None = None
        self._rows: tuple[int, ...] | None = None

    def _start(self, x0: np.ndarray, z0: np.ndarray, rows, entries=None) -> None:
        """Start on prior mean ``x0``: measurement entries ``entries`` (default: all) of
        the channel read state rows ``rows``."""
        rows = tuple(int(r) for r in rows)
        entries = np.arange(len(rows)) if entries is None else np.asarray(entries, dtype=int)
        if self.kf is None or rows != self._rows:
            n = self._f.shape[0]
            kf = KalmanFilter(dim_x=n, dim_z=len(rows), dim_u=self._m)
            kf.F, kf.B, kf.Q = self._f, self._g, self._q
            kf.H = np.zeros((len(rows), n))
            kf.H[np.arange(len(rows)), list(rows)] = 1.0
            kf.R = np.diag(self._var[entries])
            self.kf, self._rows = kf, rows
        self._entries = entries
        self.kf.x = np.asarray(x0, dtype=float).copy()
        self.kf.P = self._p0.copy()
        z = np.asarray(z0, dtype=float)[entries]
        self.gate.reset(z)
        self._inputs = deque([np.zeros(self._m)] * self.delay_steps)
        if np.all(np.isfinite(z)):
            self.kf.update(z)

    def update(self, obs: np.ndarray, info: dict[str, Any]):
        """One step: predict with the command that acts now (the delay's), update on a new
        ``state`` sample; the controller's observation and info (the subclass's ``_view``)."""
        sensors = info.get("sensors")
        if sensors is not None:
            self._advance(sensors["state"], info.get("commanded"))
        return self._view(obs, info)

    def _advance(self, reading: np.ndarray, commanded: np.ndarray | None) -> None:
        self._inputs.append(np.zeros(self._m) if commanded is None else np.asarray(commanded, dtype=float))
        u = self._inputs.popleft()
        self.kf.predict(u=u)
        z = np.asarray(reading, dtype=float)[self._entries]
        if self.gate.is_new(z):
            self.kf.update(z)


class LinearKF(_InputKF):
    """Kalman filter for LinearSystem-v0 on the env's nominal discrete model of its decision
    period (``decision_model``, else ``model``: ``x' = A x + B u``), the physical input
    ``u = info["commanded"]``. Process noise: the env's ``process_noise_std`` per plant step
    (summed over the plant steps of a decision), plus ``process_noise_floor`` (default 1e-6,
    per entry) for the nominal model's own errors; measurement noise: the ``state``
    channel's ``noise_std`` (a bias spread counts as noise). Prior: the measurement.
    The observation and ``info["measured"]`` become the estimate ``x̂``."""

    def __init__(self, env, process_noise_floor: float = 1e-6, initial_std: float | None = None) -> None:
        base = env.unwrapped
        layer = _sensor_layer(env, ("state",), type(self).__name__)
        model = getattr(base, "decision_model", None) or base.model
        a, b = np.asarray(model.A, dtype=float), np.asarray(model.B, dtype=float)
        n = a.shape[0]
        k = int(getattr(base, "decision_steps", 1))
        a1 = np.asarray(base.model.A, dtype=float)
        q_step = (float(getattr(base, "process_noise_std", 0.0)) ** 2) * np.eye(n)
        q = np.zeros((n, n))
        power = np.eye(n)
        for _ in range(k):
            q = q + power @ q_step @ power.T
            power = a1 @ power
        q = q + process_noise_floor**2 * np.eye(n)
        p = layer.parameters("state")
        var = np.maximum(_per_axis(p["noise_std"], n) ** 2 + _per_axis(p["initial_bias_std"], n) ** 2, _MIN_VAR)
        p0 = np.diag(var) if initial_std is None else initial_std**2 * np.eye(n)
        self._setup(a, b, q, var, p0, base.conditions.delay_steps)

    def reset(self, obs: np.ndarray, info: dict[str, Any]):
        z = np.asarray(info["sensors"]["state"], dtype=float)
        self._start(np.where(np.isfinite(z), z, 0.0), z, range(z.size))
        return self._view(obs, info)

    def _view(self, obs, info):
        x = self.kf.x.copy()
        out = np.array(obs, dtype=np.float32)
        out[: x.size] = x
        view = dict(info, estimate={"state": x.copy(), "covariance": self.kf.P.copy()})
        view[MEASURED] = x
        return out, view


class SloshKF(_InputKF):
    """Kalman filter for FuelSlosh-v0 on the full plant's linearization in the physical
    inputs (``model.full_linear()``: ``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]``, ``u = [δ, M_c]``
    at the design axial speed), discretized by zero-order hold over the control period,
    augmented with a constant input disturbance ``d`` (2: a gimbal offset in rad and a
    moment bias in N·m, e.g. a thruster fault) acting as ``u + d``, random walk of
    ``disturbance_walk_std`` (per √s). The axial speed v_x is measured directly (passed
    through as measured).

    Measured entries: v_z, θ, Ω and, when ``info["measured"]`` has them at reset, the
    slosh angles and rates (the flight sensors do not measure the slosh, reported as 0 in
    the observation: the filter then reconstructs it from the rigid-body response, from a
    prior of zero with ``initial_slosh_std`` = (angle rad, rate rad/s)). Process noise on
    x: ``process_noise_std`` (per √s, one per state; the default is of the size of the
    linearization's one-step prediction error after the transient from the paper's
    initial condition). ``unmeasured_slosh``: what the controller sees of unmeasured slosh
    states, ``"measured"`` (default: zeros, as the sensors report them; the filter's
    reconstruction is in ``info["estimate"]["state"]``) or ``"estimate"`` (the
    reconstruction: weakly observable, it raised J in our measurements). Measurement noise: the ``state`` channel's ``noise_std`` (its bias
    spread counted as noise). The observation (``[x, v_x]``, or ``[v_z, θ, Ω, v_x]`` with
    ``observe_slosh=False``) and ``info["measured"]`` hold the estimate;
    ``info["estimate"]`` adds ``input_disturbance`` (δ rad, M_c N·m)."""

    def __init__(
        self,
        env,
        process_noise_std=(0.16, 3e-5, 3e-4, 3e-5, 3e-4, 3e-5, 3e-4),
        disturbance_walk_std=(1e-3, 10.0),
        initial_disturbance_std=(1e-2, 100.0),
        initial_slosh_std=(0.3, 0.1),
        unmeasured_slosh: str = "measured",
    ) -> None:
        if unmeasured_slosh not in ("measured", "estimate"):
            raise ValueError(f"unmeasured_slosh must be 'measured' or 'estimate', got {unmeasured_slosh!r}")
        self.unmeasured_slosh = unmeasured_slosh
        self._slosh_measured = True
        base = env.unwrapped
        layer = _sensor_layer(env, ("state",), type(self).__name__)
        model = base.model
        a, b = model.full_linear()
        dt = float(base.control_dt_s)
        ad, bd = _discretize(np.asarray(a, dtype=float), np.asarray(b, dtype=float), dt)
        n, m = bd.shape
        f = np.eye(n + m)
        f[:n, :n], f[:n, n:] = ad, bd
        g = np.zeros((n + m, m))
        g[:n] = bd
        q = np.zeros((n + m, n + m))
        q[:n, :n] = np.diag(_per_axis(process_noise_std, n) ** 2) * dt
        q[n:, n:] = np.diag(np.square(disturbance_walk_std)) * dt
        p = layer.parameters("state")
        size = layer.channels["state"].size
        var = np.maximum(_per_axis(p["noise_std"], size) ** 2 + _per_axis(p["initial_bias_std"], size) ** 2, _MIN_VAR)
        # the channel's entries are the observation's: [x (7), v_x] or [v_z, θ, Ω, v_x]
        self._obs_rows = np.arange(n) if size == n + 1 else np.arange(3)
        prior = np.full(n, np.inf)
        prior[self._obs_rows] = var[: self._obs_rows.size]
        slosh_prior = np.square([initial_slosh_std[0], initial_slosh_std[1]] * 2)
        prior[3:] = np.where(np.isinf(prior[3:]), slosh_prior, prior[3:])
        self._slosh_prior = slosh_prior
        p0 = np.diag(np.concatenate([prior, np.square(initial_disturbance_std)]))
        self._n = n
        self._setup(f, g, q, var, p0, base.conditions.delay_steps)

    def reset(self, obs: np.ndarray, info: dict[str, Any]):
        z = np.asarray(info["sensors"]["state"], dtype=float)
        rows = self._obs_rows
        if "slosh_angle_rad" not in info[MEASURED]:
            rows = rows[rows < 3]
            self._slosh_measured = False
            self._p0[3 : self._n, 3 : self._n] = np.diag(self._slosh_prior)
        x0 = np.zeros(self._n + self._m)
        x0[rows] = np.where(np.isfinite(z[rows]), z[rows], 0.0)
        self._start(x0, z, rows, entries=rows)
        return self._view(obs, info)

    def _view(self, obs, info):
        n = self._n
        x = self.kf.x[:n].copy()
        out = np.array(obs, dtype=np.float32)
        rows = self._obs_rows
        shown = x.copy()
        if not self._slosh_measured and self.unmeasured_slosh == "measured":
            shown[3:] = 0.0  # as the sensors report them (the estimate stays in info["estimate"])
        out[: rows.size] = shown[rows]
        view = dict(
            info,
            estimate={"state": x.copy(), "input_disturbance": self.kf.x[n:].copy(), "covariance": self.kf.P.copy()},
        )
        names = ("v_z_m_s", "theta_rad", "pitch_rate_rad_s")
        measured = dict(info[MEASURED], **{k: float(x[i]) for i, k in enumerate(names)})
        if rows.size == n and (self._slosh_measured or self.unmeasured_slosh == "estimate"):
            measured["slosh_angle_rad"] = x[[3, 5]].copy()
            measured["slosh_rate_rad_s"] = x[[4, 6]].copy()
        view[MEASURED] = measured
        return out, view


#: env name → estimator class, by estimator name
ESTIMATORS: dict[str, dict[str, type]] = {
    "mekf": {"ReactionWheel": GyrostatMEKF, "AirBearing": GyrostatMEKF, "Magnetorquer": MagnetorquerMEKF},
    "kf": {"LinearSystem": LinearKF, "FuelSlosh": SloshKF},
}


def estimator_for(env, name: str | None = None, **params):
    """The estimator ``name`` (``"mekf"``, ``"kf"``; None: the one the env has) built from
    ``env`` with keyword ``params``."""
    env_name = str(env.unwrapped.env_name).rsplit("-v", 1)[0]
    names = [k for k, v in ESTIMATORS.items() if env_name in v]
    if not names:
        raise ValueError(f"no estimator for {env_name}; estimators: {ESTIMATORS}")
    if name is None:
        name = names[0]
    if name not in ESTIMATORS or env_name not in ESTIMATORS[name]:
        raise ValueError(f"estimator {name!r} does not apply to {env_name} (it has {names})")
    return ESTIMATORS[name][env_name](env, **params)
