"""Actuator fault detection and isolation (FDI) with a filterpy IMM bank.

Hypotheses: ``H0`` healthy, and ``H(i, e)`` (i = 0..N−1, e in ``degraded_effectiveness``,
default ``(0.5,)``) "actuator i delivers only the fraction e of its command". Each hypothesis is a filterpy
:class:`~filterpy.kalman.KalmanFilter` on the rate/wheel-speed dynamics of the nominal
gyrostat (``attitude_envs.plants.gyrostat``) over one control step,

    x = [ω (3, rad/s), Ω (N, rad/s)],   x' = x + B E_h u + d,
    B = Δt [−I_eff⁻¹ A ; J_s⁻¹ I + Aᵀ I_eff⁻¹ A],   d = Δt [I_eff⁻¹ g ; −Aᵀ I_eff⁻¹ g],

with ``u`` the *commanded* motor torques (N·m, known to the FDI), ``E_h`` the hypothesis'
effectiveness, and the gyroscopic torque ``g = −ω × (I ω + J_s A Ω)`` (plus a known external
torque, when given) evaluated at the latest estimate and held over the step. Measurements: gyro (and tachometers unless
``use_tachometer=False``). An :class:`filterpy.kalman.IMMEstimator` mixes the bank with a
Markov switching matrix (healthy → each fault ``p_fault / (N L)`` per step for L levels,
fault → healthy ``p_recover``); its mode probabilities are computed from the filters' log-likelihoods
(filterpy multiplies raw likelihoods, which underflow to equality for the large
innovations of a real fault), floored at 1e-12 so that no hypothesis is locked out.

Decision: with ``μ_i`` the summed probability of actuator i's hypotheses, actuator i is
*isolated* when ``μ_i ≥ threshold`` for ``confirm_steps``
consecutive steps; the first isolation is latched with its time (``detection``).
A loss of effectiveness is only observable while the actuator is commanded: with zero
command every hypothesis predicts the same.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from filterpy.kalman import IMMEstimator, KalmanFilter

from attitude_envs import validation
from attitude_envs.info import policy_view

_MU_FLOOR = 1e-12


class _LogIMM(IMMEstimator):
    """filterpy's IMM with mode probabilities updated in the log domain."""

    def update(self, z):
        for f in self.filters:
            f.update(z)
        log_l = np.array([f.log_likelihood for f in self.filters])
        w = np.log(np.maximum(self.cbar, 1e-300)) + log_l
        mu = np.exp(w - np.max(w))
        self.likelihood = np.exp(log_l - np.max(log_l))
        # floor: no hypothesis is ever ruled out for good (and filterpy's mixing never divides by 0)
        mu = np.maximum(mu / np.sum(mu), _MU_FLOOR)
        self.mu = mu / np.sum(mu)
        self._compute_mixing_probabilities()
        self._compute_state_estimate()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()


class ActuatorFDI:
    """IMM fault detection and isolation of reaction-wheel actuators.

    Parameters: ``model`` (the env's nominal :class:`ReactionWheelModel`), ``dt_s``
    (control period, s), ``rate_noise_std`` (gyro, rad/s) and ``wheel_noise_std``
    (tachometer, rad/s) — floored at 1e-5 and 1e-2 so a noise-free sensor still leaves
    room for model error — ``degraded_effectiveness`` (a level or a list of levels, each
    in [0, 1)), ``p_fault`` and
    ``p_recover`` (per-step switching probabilities), ``threshold`` in (0.5, 1),
    ``confirm_steps`` ≥ 1, ``rate_process_std`` / ``wheel_process_std`` (model error per
    step, rad/s), ``use_tachometer``, ``known_effectiveness`` (N values in [0, 1], default
    all 1: faults already isolated, part of every hypothesis; actuators below 1 get no
    hypothesis of their own, so a second fault can be isolated after the first).
    """

    def __init__(
        self,
        model,
        dt_s: float,
        rate_noise_std: float = 0.0,
        wheel_noise_std: float = 0.0,
        degraded_effectiveness: float | Sequence[float] = 0.5,
        p_fault: float = 0.01,
        p_recover: float = 0.05,
        threshold: float = 0.95,
        confirm_steps: int = 3,
        rate_process_std: float = 1e-5,
        wheel_process_std: float = 1e-2,
        use_tachometer: bool = True,
        known_effectiveness: Sequence[float] | None = None,
    ) -> None:
        p = model.params
        self.n = p.n_wheels
        self.dt_s = validation.positive("dt_s", dt_s)
        levels = np.atleast_1d(np.asarray(degraded_effectiveness, dtype=float))
        if levels.ndim != 1 or levels.size == 0 or np.any((levels < 0) | (levels >= 1)):
            raise ValueError(
                f"degraded_effectiveness must be in [0, 1) (one or more levels), got {degraded_effectiveness!r}"
            )
        for name, v in (("p_fault", p_fault), ("p_recover", p_recover)):
            if not 0.0 < float(v) < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {v!r}")
        if not 0.5 < float(threshold) < 1.0:
            raise ValueError(f"threshold must be in (0.5, 1), got {threshold!r}")
        if int(confirm_steps) < 1:
            raise ValueError(f"confirm_steps must be >= 1, got {confirm_steps!r}")
        self.threshold, self.confirm_steps = float(threshold), int(confirm_steps)
        self.use_tachometer = bool(use_tachometer)
        self._axes = p.wheel_axes
        self._inertia = p.inertia_kg_m2
        self._js = p.wheel_inertia_kg_m2
        self._ieff_inv = p.inertia_eff_inv
        dim = 3 + self.n
        b = np.zeros((dim, self.n))
        b[:3] = -self._ieff_inv @ self._axes
        b[3:] = np.eye(self.n) / self._js - self._axes.T @ b[:3]
        self._b = self.dt_s * b
        dim_z = dim if self.use_tachometer else 3
        r_rate = max(validation.nonnegative("rate_noise_std", rate_noise_std), 1e-5)
        r_wheel = max(validation.nonnegative("wheel_noise_std", wheel_noise_std), 1e-2)
        self._p_init = np.diag([r_rate**2] * 3 + [r_wheel**2] * self.n)
        q_rate = validation.nonnegative("rate_process_std", rate_process_std)
        q_wheel = validation.nonnegative("wheel_process_std", wheel_process_std)
        known = np.ones(self.n) if known_effectiveness is None else np.asarray(known_effectiveness, dtype=float)
        if known.shape != (self.n,) or np.any((known < 0) | (known > 1)) or np.all(known < 1):
            raise ValueError(
                f"known_effectiveness must be {self.n} values in [0, 1], at least one 1, got {known_effectiveness!r}"
            )
        self.known_effectiveness = known.copy()
        self.effectiveness = [known.copy()]
        owner = [-1]  # actuator of each hypothesis (-1: healthy)
        for i in np.flatnonzero(known == 1.0):
            for e in levels:
                eff = known.copy()
                eff[i] = e
                self.effectiveness.append(eff)
                owner.append(i)
        self._owner = np.array(owner)
        n_h = len(owner)
        self.filters = []
        for _ in self.effectiveness:
            kf = KalmanFilter(dim_x=dim, dim_z=dim_z)
            kf.F = np.eye(dim)
            kf.H = np.eye(dim)[:dim_z]
            kf.R = np.diag([r_rate**2] * 3 + [r_wheel**2] * (dim_z - 3))
            kf.Q = np.diag([q_rate**2] * 3 + [q_wheel**2] * self.n)
            self.filters.append(kf)
        m = np.zeros((n_h, n_h))
        m[0, 0], m[0, 1:] = 1.0 - p_fault, p_fault / (n_h - 1)
        for h in range(1, n_h):
            m[h, 0], m[h, h] = p_recover, 1.0 - p_recover
        self.transition = m
        self._p0 = np.r_[1.0 - p_fault, np.full(n_h - 1, p_fault / (n_h - 1))]
        self.imm: IMMEstimator | None = None
        self.detection: dict[str, Any] | None = None
        self._streak = (None, 0)

    @property
    def probabilities(self) -> np.ndarray:
        """``[P(healthy), P(actuator 0 degraded), ...]`` (levels summed per actuator)."""
        mu = self.imm.mu
        return np.r_[mu[0], np.bincount(self._owner[1:], weights=mu[1:], minlength=self.n)]

    @property
    def hypothesis_probabilities(self) -> list[tuple[int | None, float, float]]:
        """``(actuator or None, effectiveness, probability)`` of every hypothesis."""
        out = []
        for h, (i, mu) in enumerate(zip(self._owner, self.imm.mu, strict=True)):
            out.append((None if i < 0 else int(i), float(self.effectiveness[h][max(i, 0)]), float(mu)))
        return out

    def reset(self, rate_rad_s: np.ndarray, wheel_speed_rad_s: np.ndarray) -> None:
        """Start on the first measurements."""
        x0 = np.r_[rate_rad_s, wheel_speed_rad_s]
        for kf in self.filters:
            kf.x = x0.copy()
            kf.P = self._p_init.copy()
        self.imm = _LogIMM(self.filters, self._p0.copy(), self.transition)
        self.detection = None
        self._streak = (None, 0)

    def update(
        self,
        commanded_nm: np.ndarray,
        rate_rad_s: np.ndarray,
        wheel_speed_rad_s: np.ndarray,
        t_s: float,
        external_torque_nm: np.ndarray | None = None,
    ):
        """One control step: ``commanded_nm`` was held over the step that ended at ``t_s``
        (s) with the given measurements; ``external_torque_nm`` (N·m, body axes; default
        none) is a known external torque over the step, e.g. an air bearing's nominal
        offset torque. Returns the mode probabilities."""
        x = self.imm.x
        w, wheel = x[:3], x[3:]
        g = -np.cross(w, self._inertia @ w + self._js * self._axes @ wheel)
        if external_torque_nm is not None:
            g = g + np.asarray(external_torque_nm, dtype=float)
        w_dot = self._ieff_inv @ g
        d = self.dt_s * np.r_[w_dot, -self._axes.T @ w_dot]
        for kf, eff in zip(self.filters, self.effectiveness, strict=True):
            kf.B = np.column_stack([self._b * eff, d])
        self.imm.predict(np.r_[commanded_nm, 1.0])
        z = np.r_[rate_rad_s, wheel_speed_rad_s] if self.use_tachometer else np.asarray(rate_rad_s, dtype=float)
        if np.all(np.isfinite(z)):
            self.imm.update(z)
        self._decide(t_s)
        return self.probabilities

    def _decide(self, t_s: float) -> None:
        mu = self.probabilities
        best = int(np.argmax(mu))
        leader = best - 1 if best > 0 and mu[best] >= self.threshold else None
        count = self._streak[1] + 1 if leader is not None and leader == self._streak[0] else 1
        self._streak = (leader, count if leader is not None else 0)
        if self.detection is None and leader is not None and count >= self.confirm_steps:
            mine = np.flatnonzero(self._owner == leader)
            level = self.effectiveness[mine[np.argmax(self.imm.mu[mine])]][leader]
            self.detection = {
                "index": leader,
                "time_s": float(t_s),
                "probability": float(mu[best]),
                "effectiveness": float(level),
            }

    @classmethod
    def for_env(cls, env, **kwargs) -> ActuatorFDI:
        """An FDI for a ReactionWheel-v0 env, with its nominal model and sensor noise."""
        base = env.unwrapped
        sensors = base.sensor_layer
        params = {
            "rate_noise_std": sensors.parameters("gyro")["noise_std"],
            "wheel_noise_std": sensors.parameters("tachometer")["noise_std"],
        }
        params.update(kwargs)
        return cls(base.model, base.control_dt_s, **params)


def measurements(info: dict) -> tuple[np.ndarray, np.ndarray]:
    """(rate, wheel speeds) as the FDI sees them: ``info["measured"]`` (the gyro and
    tachometers when sensors are on, else the truth)."""
    measured = info["measured"]
    return measured["rate_rad_s"], measured["wheel_speed_rad_s"]


def run_fdi_episode(env, policy, fdi: ActuatorFDI, seed: int | None = None, options: dict | None = None) -> dict:
    """One episode with the FDI monitoring it. Returns ``J``, the detection (index, time),
    the first actuator fault of the ground truth (index, onset) and the verdict:
    ``false_alarm`` (isolation while no actuator fault was active), ``correct``
    (the faulty actuator isolated after onset), ``delay_s`` (detection − onset)."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    fdi.reset(*measurements(info))
    total, done = 0.0, False
    alarm_without_fault = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += info["cost"]
        done = terminated or truncated
        had = fdi.detection is not None
        fdi.update(info["commanded"], *measurements(info), info["time_s"])
        if fdi.detection is not None and not had:
            active = [f for f in info["truth"]["faults"] if f["target"] == "actuator" and f["active"]]
            alarm_without_fault = not active
    truth = [f for f in info["truth"]["faults"] if f["target"] == "actuator"]
    fault_index = truth[0]["index"] if truth else None
    onset = truth[0]["onset_s"] if truth else None
    det = fdi.detection
    return {
        "J": total,
        "fault_index": fault_index,
        "onset_s": onset,
        "detected_index": None if det is None else det["index"],
        "detection_time_s": None if det is None else det["time_s"],
        "false_alarm": bool(det is not None and alarm_without_fault),
        "correct": bool(det is not None and not alarm_without_fault and det["index"] == fault_index),
        "delay_s": None if det is None or onset is None or alarm_without_fault else det["time_s"] - onset,
    }
