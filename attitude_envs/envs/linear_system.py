"""LinearSystem-v0: a discrete LTI plant with quadratic stage cost, for verifying learners
against the Riccati solution."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.faults import ActuatorFaults
from attitude_envs.linearization import LinearModel
from attitude_envs.plants import linear_kernels
from attitude_envs.sensors import Channel, SensorSuite


def spec001_plant() -> dict:
    """Spec 001 §2.3: forward-Euler discretization (Δt = 0.01 s) of the linearized
    quaternion/rate model with J = diag(1000, 1000, 800) kg·m², Q = I₆, R = I₃, and the
    paper's initial state (scalar-first reading of eq. 74, normalized; §2.4)."""
    dt = 0.01
    inertia = np.array([1000.0, 1000.0, 800.0])
    A = np.eye(6)
    A[:3, 3:] = 0.5 * dt * np.eye(3)
    B = np.zeros((6, 3))
    B[3:, :] = dt * np.diag(1.0 / inertia)
    q0 = np.array([0.4783, 0.3722, -0.4329, 0.6645])
    q0 = q0 / np.linalg.norm(q0)
    x0 = np.concatenate([q0[1:], [0.01, -0.02, 0.01]])
    return {
        "A": A,
        "B": B,
        "Q": np.eye(6),
        "R": np.eye(3),
        "x0_mean": x0,
        "x0_std": 0.0,
        "action_scale": 2.0,
        "dt_s": dt,
    }


_PRESETS = {"spec-001": spec001_plant}


class LinearSystemEnv(gym.Env):
    """Discrete linear plant ``x⁺ = A x + B u + w`` with stage cost ``xᵀQx + uᵀRu``.

    ================  ========================================================  ==========
    Quantity          Meaning                                                   Units
    ================  ========================================================  ==========
    State / obs       ``x`` (n), float32 observation of the float64 state       plant's
    Action            m values in [-1, 1] (clipped: saturation); physical        -
                      ``u = action_scale · a``
    Reward            ``−(xᵀQx + uᵀRu)`` of the step (x before the step)        (cost)
    Start state       ``x0 ~ N(x0_mean, diag(x0_std²))``, or ``options["state"]``
    Termination       ``‖x‖∞ > divergence_threshold`` or non-finite state
                      (observation bounds follow from it)
    Truncation        after ``episode_steps`` steps
    Noise             ``w ~ N(0, process_noise_std²)`` per component, from the
                      env's RNG
    ================  ========================================================  ==========

    Parameters: ``preset`` (``"spec-001"``, default: spec 001 §2.3's Euler-discretized
    satellite, Δt = 0.01 s) or ``A`` (n×n), ``B`` (n×m), ``Q``, ``R``, ``x0_mean``,
    ``x0_std``, ``process_noise_std``, ``action_scale`` (scalar or m-vector, > 0),
    ``episode_steps``, ``divergence_threshold``, ``faults`` (see :mod:`attitude_envs.faults`,
    time = steps × ``dt_s``; ``"target": "sensor"`` entries are faults of the ``state``
    sensor), ``sensors`` (``{"state": {...}}``, see :mod:`attitude_envs.sensors`; the
    observation is then the measured state, ``info["sensors"]["state"]``), ``fault_hint``
    (append m + 1 active-fault flags: actuators, then the state sensor), ``dt_s`` (the period the matrices
    represent, for reporting). ``env.unwrapped.model`` is the :class:`LinearModel`
    (A, B, Q, R, dt). ``info`` holds ``state`` (x before the step), ``next_state``,
    ``applied`` (physical u after saturation) and ``cost``.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        preset: str | None = "spec-001",
        A=None,
        B=None,
        Q=None,
        R=None,
        x0_mean=None,
        x0_std=None,
        process_noise_std: float = 0.0,
        action_scale=None,
        episode_steps: int = 1000,
        divergence_threshold: float = 1e6,
        dt_s: float | None = None,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        render_mode: str | None = None,
    ) -> None:
        cfg: dict = {}
        if preset is not None:
            if preset not in _PRESETS:
                raise ValueError(f"preset must be one of {sorted(_PRESETS)} or None, got {preset!r}")
            cfg = _PRESETS[preset]()
        given = {"A": A, "B": B, "Q": Q, "R": R, "x0_mean": x0_mean, "x0_std": x0_std}
        given.update({"action_scale": action_scale, "dt_s": dt_s})
        cfg.update({k: v for k, v in given.items() if v is not None})
        for key in ("A", "B"):
            if key not in cfg:
                raise ValueError(f"{key} is required when preset is None")
        a_mat = validation.finite_array("A", cfg["A"])
        if a_mat.ndim != 2 or a_mat.shape[0] != a_mat.shape[1] or a_mat.shape[0] == 0:
            raise ValueError(f"A must be a square n x n matrix, got shape {a_mat.shape}")
        n = a_mat.shape[0]
        b_mat = validation.finite_array("B", cfg["B"])
        if b_mat.ndim != 2 or b_mat.shape[0] != n or b_mat.shape[1] == 0:
            raise ValueError(f"B must be an n x m matrix with n = {n}, got shape {b_mat.shape}")
        m = b_mat.shape[1]
        cost = QuadraticCost.build(cfg.get("Q", np.eye(n)), cfg.get("R", np.eye(m)), n, m)
        self.model = LinearModel(a_mat, b_mat, cost.Q, cost.R, np.zeros((n, m)), cfg.get("dt_s", 1.0))
        self.cost = cost
        self._x0_mean = validation.finite_array("x0_mean", cfg.get("x0_mean", np.zeros(n)), (n,))
        std = validation.finite_array("x0_std", cfg.get("x0_std", 1.0))
        self._x0_std = (
            np.broadcast_to(std, (n,)).copy() if std.ndim == 0 else validation.finite_array("x0_std", std, (n,))
        )
        if np.any(self._x0_std < 0):
            raise ValueError(f"x0_std must be >= 0, got {self._x0_std.tolist()}")
        self._noise_std = validation.nonnegative("process_noise_std", process_noise_std)
        scale = validation.finite_array("action_scale", cfg.get("action_scale", 1.0))
        self.action_scale = np.broadcast_to(scale, (m,)).copy() if scale.ndim == 0 else scale
        if self.action_scale.shape != (m,) or np.any(self.action_scale <= 0):
            raise ValueError(f"action_scale must be > 0, a scalar or length {m}, got {scale.tolist()}")
        self._faults = ActuatorFaults(faults, m, self.action_scale, other_targets={"sensor"})
        self._sensors = SensorSuite(sensors, [Channel("state", n)], faults)
        self.fault_hint = bool(fault_hint)
        if int(episode_steps) < 1:
            raise ValueError(f"episode_steps must be >= 1, got {episode_steps!r}")
        self.episode_steps = int(episode_steps)
        self.divergence_threshold = validation.positive("divergence_threshold", divergence_threshold)
        if render_mode is not None:
            raise ValueError(f"render_mode must be None for LinearSystem-v0, got {render_mode!r}")
        self.render_mode = None
        # |x⁺|∞ <= ‖A‖∞ |x|∞ + ‖B‖∞ |u|∞ (+ noise, 10σ margin) while |x|∞ <= divergence_threshold.
        bound = (
            self.divergence_threshold * max(1.0, np.linalg.norm(a_mat, np.inf))
            + np.linalg.norm(b_mat, np.inf) * float(np.max(self.action_scale))
            + 10.0 * self._noise_std
        )
        low, high = np.full(n, -bound), np.full(n, bound)
        if self.fault_hint:
            low, high = np.concatenate([low, np.zeros(m + 1)]), np.concatenate([high, np.ones(m + 1)])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(m,), dtype=np.float32)
        self._x = self._x0_mean.copy()
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, {"state", "faults"})
        n = self.model.n
        if "state" in options:
            self._x = validation.finite_array("options['state']", options["state"], (n,)).copy()
        else:
            self._x = self._x0_mean + self._x0_std * self.np_random.normal(size=n)
        self._steps = 0
        self._sensors.reset(self.np_random, options.get("faults"))  # own spawned generator
        self._faults.reset(self.np_random, options.get("faults"))
        info = {"state": self._x.copy(), "faults": self._faults.info(0.0) + self._sensors.info(0.0)}
        return self._observe(self._x, 0.0, info), info

    def step(self, action):
        a = np.clip(validation.action(action, self.model.m), -1.0, 1.0)
        t_s = self._steps * self.model.dt_s
        u = self._faults.apply(self.action_scale * a, t_s)
        x = self._x
        x_next = np.empty_like(x)
        cost = linear_kernels.linear_step(x, u, self.model.A, self.model.B, self.cost.Q, self.cost.R, x_next)
        if self._noise_std > 0:
            x_next = x_next + self._noise_std * self.np_random.normal(size=self.model.n)
        self._x = x_next
        self._steps += 1
        terminated = bool(not np.all(np.isfinite(x_next)) or np.max(np.abs(x_next)) > self.divergence_threshold)
        truncated = self._steps >= self.episode_steps and not terminated
        info = {"state": x.copy(), "next_state": x_next.copy(), "applied": u, "cost": cost}
        # actuator faults as applied over this step, sensor faults at the observation time
        info["faults"] = self._faults.info(t_s) + self._sensors.info(self._steps * self.model.dt_s)
        if np.all(np.isfinite(x_next)):
            obs = self._observe(x_next, self._steps * self.model.dt_s, info)
        else:
            obs = np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, info

    def _observe(self, x: np.ndarray, t_s: float, info: dict) -> np.ndarray:
        """The observation of state ``x`` at time ``t_s`` (measured when sensors are on)."""
        if self._sensors.enabled:
            info["sensors"] = self._sensors.measure({"state": x}, t_s)
            info["sensor_bias"] = {k: v.copy() for k, v in self._sensors.bias.items()}
            x = info["sensors"]["state"]
        if self.fault_hint:
            x = np.concatenate([x, self._faults.active_flags(t_s), self._sensors.active_flags(t_s)])
        return x.astype(np.float32)
