"""ReactionWheel-v0: rest-to-rest attitude maneuvers of a rigid spacecraft with N wheels."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import quaternion, validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.disturbances import Disturbance
from attitude_envs.faults import ActuatorFaults
from attitude_envs.integrators import substeps
from attitude_envs.plants import gyrostat
from attitude_envs.plants import gyrostat_kernels as kernels
from attitude_envs.plants.gyrostat_model import ReactionWheelModel
from attitude_envs.presets import preset as load_preset
from attitude_envs.sensors import Channel, SensorSuite
from attitude_envs.uncertainty import InertiaUncertainty

_OPTION_KEYS = {"attitude", "rate_rad_s", "wheel_speed_rad_s", "target_attitude", "faults"}


class ReactionWheelEnv(gym.Env):
    """Rigid spacecraft with N reaction wheels driven to a target attitude.

    Plant: the exact gyrostat equations of :mod:`attitude_envs.plants.gyrostat` (no
    small-wheel approximation), scalar-last quaternion kinematics, fixed-step RK4 with
    ``integrator_dt_s`` sub-steps inside each ``control_dt_s`` period, quaternion
    renormalized after every sub-step. Papers: spec 000 (preset ``"spec-000"``, default)
    and spec 001 (preset ``"spec-001"``).

    ================  ==========================================================  ==========
    Quantity          Meaning                                                     Units
    ================  ==========================================================  ==========
    State (truth)     q (scalar last), ω body rate, Ω wheel speeds rel. body     -, rad/s
    Observation       float32 ``x = [q_e,vec (3), ω (3)]`` with q_e = q_T*⊗q,    -, rad/s
                      w ≥ 0; ``+ h_w = J_s Ω (N)`` when wheel momentum is        N·m·s
                      weighted; ``+ Ω / Ω_max (N)`` if ``observe_wheel_speeds``   -
    Action            N normalized motor torques in [-1, 1] (clipped: actuator    -
                      saturation); physical ``u = a · max_wheel_torque_nm``;      N·m
                      positive spins wheel i up about a_i, body gets −a_i u_i.
                      ``action_frame="body"``: 3 normalized body torques        -
                      ``T = a · max_wheel_torque_nm``, allocated ``u = −A⁺T``    N·m
                      (minimum norm), each wheel clipped at its limit
    Reward            −∫ (xᵀQx + u_cᵀRu_c) dt over the step (RK4, augmented        (cost)
                      state); u_c = body torque −A u or wheel torques u
    Start state       q within ``initial_angle_deg`` of identity, ω uniform in    deg, rad/s
                      ±``initial_rate_max_rad_s``, wheels at rest; target within
                      ``target_angle_deg``; all pinned by ``reset(options=...)``
    Termination       non-finite state, or tumbling: ``max|ω| > max_rate_rad_s``  rad/s
                      (default 2π rad/s, one revolution per second)
    Truncation        simulated time reaches ``episode_duration_s``               s
    ================  ==========================================================  ==========

    Parameters (``None`` takes the preset's value): ``inertia_kg_m2`` (3×3, whole
    spacecraft incl. wheel spin inertia), ``wheel_axes`` (3×N unit columns),
    ``wheel_inertia_kg_m2``, ``max_wheel_torque_nm``, ``max_wheel_speed_rad_s`` (motor
    driver blocks torque beyond it), ``control_dt_s``, ``integrator_dt_s``,
    ``episode_duration_s``, ``Q``, ``R``, ``cost_input`` (``"body"``/``"wheel"``),
    ``wheel_momentum_weight`` (adds ``h_w`` to x, weight per (N·m·s)²), ``target_attitude``,
    ``target_angle_deg``, ``initial_attitude``, ``initial_angle_deg``, ``initial_rate_rad_s``,
    ``initial_rate_max_rad_s``, ``inertia_uncertainty`` (see :mod:`attitude_envs.uncertainty`),
    ``disturbance`` (see :mod:`attitude_envs.disturbances`), ``max_rate_rad_s``,
    ``observe_wheel_speeds``, ``action_frame`` (``"wheel"``: one action per wheel;
    ``"body"``: a body-torque demand through the minimum-norm allocation — no action
    reaches the wheels' null space, whose momentum the cost does not see), ``faults`` (list of fault dicts, see :mod:`attitude_envs.faults`;
    also per episode as ``reset(options={"faults": [...]})``; ``"target": "sensor"`` entries
    are sensor faults), ``sensors`` (dict, see :mod:`attitude_envs.sensors`: channels
    ``gyro`` (rad/s), ``star_tracker`` (rad), ``tachometer`` (rad/s); default None: the truth
    is observed), ``fault_hint`` (append N + 3 flags to the observation: 1.0 per actuator,
    then per sensor gyro/star tracker/tachometer, with an active fault).

    With sensors (or sensor faults) the observation is the error state of the *measured*
    attitude, rate and wheel speeds (a dropout in ``"nan"`` mode puts NaN in it, outside
    the observation bounds by design); ``info["sensors"]`` holds the raw measurements
    (``star_tracker`` quaternion, ``gyro``, ``tachometer``) and ``info["sensor_bias"]`` the
    true biases.

    ``env.unwrapped.model`` is the *nominal* :class:`ReactionWheelModel` (inertia,
    wheels, cost, linearization); the true inertia and disturbance stay private, and
    ``info`` carries the truth: ``state`` (``attitude``, ``rate_rad_s``,
    ``wheel_speed_rad_s``, ``target_attitude``), ``applied`` (mean motor torque actually
    delivered over the step, N·m), ``commanded``, ``cost``, ``time_s``,
    ``error_angle_deg``, ``disturbance_torque_nm``, ``true_inertia_kg_m2``, ``faults``
    (ground truth: every fault of the episode with its draws and whether it is active).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(
        self,
        preset: str = "spec-000",
        inertia_kg_m2=None,
        wheel_axes=None,
        wheel_inertia_kg_m2: float | None = None,
        max_wheel_torque_nm: float | None = None,
        max_wheel_speed_rad_s: float | None = None,
        control_dt_s: float | None = None,
        integrator_dt_s: float | None = None,
        episode_duration_s: float | None = None,
        Q=None,
        R=None,
        cost_input: str | None = None,
        wheel_momentum_weight: float = 0.0,
        target_attitude=None,
        target_angle_deg: float | None = None,
        initial_attitude=None,
        initial_angle_deg: float | None = None,
        initial_rate_rad_s=None,
        initial_rate_max_rad_s: float | None = None,
        inertia_uncertainty: dict | None = None,
        disturbance: dict | None = None,
        max_rate_rad_s: float = 2.0 * np.pi,
        observe_wheel_speeds: bool = False,
        action_frame: str = "wheel",
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        render_mode: str | None = None,
    ) -> None:
        cfg = load_preset(preset)
        given = {
            "inertia_kg_m2": inertia_kg_m2,
            "wheel_axes": wheel_axes,
            "wheel_inertia_kg_m2": wheel_inertia_kg_m2,
            "max_wheel_torque_nm": max_wheel_torque_nm,
            "max_wheel_speed_rad_s": max_wheel_speed_rad_s,
            "control_dt_s": control_dt_s,
            "integrator_dt_s": integrator_dt_s,
            "episode_duration_s": episode_duration_s,
            "Q": Q,
            "R": R,
            "cost_input": cost_input,
            "target_attitude": target_attitude,
            "target_angle_deg": target_angle_deg,
            "initial_attitude": initial_attitude,
            "initial_angle_deg": initial_angle_deg,
            "initial_rate_rad_s": initial_rate_rad_s,
            "initial_rate_max_rad_s": initial_rate_max_rad_s,
        }
        cfg.update({k: v for k, v in given.items() if v is not None})
        if (
            control_dt_s is not None
            and integrator_dt_s is None
            and not _divides(cfg["control_dt_s"], cfg["integrator_dt_s"])
        ):
            cfg["integrator_dt_s"] = cfg["control_dt_s"]  # the preset's sub-step does not fit: one sub-step

        params = gyrostat.GyrostatParams(
            cfg["inertia_kg_m2"],
            cfg["wheel_axes"],
            cfg["wheel_inertia_kg_m2"],
            cfg["max_wheel_torque_nm"],
            cfg["max_wheel_speed_rad_s"],
        )
        self.control_dt_s = validation.positive("control_dt_s", cfg["control_dt_s"])
        self.integrator_dt_s = validation.positive("integrator_dt_s", cfg["integrator_dt_s"])
        self._substeps = substeps(self.control_dt_s, self.integrator_dt_s)
        self.episode_duration_s = validation.positive("episode_duration_s", cfg["episode_duration_s"])
        cost_in = validation.choice("cost_input", cfg["cost_input"], {"body", "wheel"})
        wmw = validation.nonnegative("wheel_momentum_weight", wheel_momentum_weight)
        n_w = params.n_wheels
        include_h = wmw > 0
        n_x = 6 + (n_w if include_h else 0)
        m_c = 3 if cost_in == "body" else n_w
        q_mat = validation.psd_matrix("Q", cfg["Q"], 6) if not include_h else None
        if include_h:
            q6 = validation.psd_matrix("Q", cfg["Q"], 6)
            q_mat = np.zeros((n_x, n_x))
            q_mat[:6, :6] = q6
            q_mat[6:, 6:] = wmw * np.eye(n_w)
        cost = QuadraticCost(q_mat, validation.psd_matrix("R", cfg["R"], m_c, definite=True))
        self.model = ReactionWheelModel(params, cost, cost_in, include_h, self.control_dt_s)

        self._target_fixed = _optional_quaternion("target_attitude", cfg.get("target_attitude"))
        self._initial_fixed = _optional_quaternion("initial_attitude", cfg.get("initial_attitude"))
        self._target_angle = _angle("target_angle_deg", cfg["target_angle_deg"])
        self._initial_angle = _angle("initial_angle_deg", cfg["initial_angle_deg"])
        rate = cfg.get("initial_rate_rad_s")
        self._rate_fixed = None if rate is None else validation.finite_array("initial_rate_rad_s", rate, (3,))
        self._rate_max = validation.nonnegative("initial_rate_max_rad_s", cfg["initial_rate_max_rad_s"])
        self._uncertainty = InertiaUncertainty.from_config(inertia_uncertainty)
        self._disturbance = None if disturbance is None else Disturbance(disturbance)
        self._faults = ActuatorFaults(faults, params.n_wheels, params.max_wheel_torque_nm, other_targets={"sensor"})
        channels = [Channel("gyro", 3, units="rad/s"), Channel("star_tracker", 4, "attitude", "rad")]
        self._sensors = SensorSuite(sensors, [*channels, Channel("tachometer", n_w, units="rad/s")], faults)
        self._meas: dict[str, np.ndarray] = {}
        self.fault_hint = bool(fault_hint)
        self.max_rate_rad_s = validation.positive("max_rate_rad_s", max_rate_rad_s)
        self.observe_wheel_speeds = bool(observe_wheel_speeds)
        if self.observe_wheel_speeds and not np.isfinite(params.max_wheel_speed_rad_s):
            raise ValueError("observe_wheel_speeds needs a finite max_wheel_speed_rad_s to normalize by")
        if render_mode is not None:
            validation.choice("render_mode", render_mode, set(self.metadata["render_modes"]))
        self.render_mode = render_mode

        # Observation bounds: |q_e,vec| <= 1; rates within 2 × max_rate_rad_s (the episode
        # terminates beyond max_rate_rad_s); wheel momentum within 1.5 × J_s Ω_max.
        rate_bound = 2.0 * self.max_rate_rad_s
        obs_high = np.concatenate([np.ones(3), np.full(3, rate_bound)])
        if include_h:
            h_bound = 1.5 * params.wheel_inertia_kg_m2 * params.max_wheel_speed_rad_s
            obs_high = np.concatenate([obs_high, np.full(n_w, h_bound if np.isfinite(h_bound) else 1e6)])
        if self.observe_wheel_speeds:
            obs_high = np.concatenate([obs_high, np.full(n_w, 1.5)])
        obs_low = -obs_high
        if self.fault_hint:
            obs_high = np.concatenate([obs_high, np.ones(n_w + 3)])
            obs_low = np.concatenate([obs_low, np.zeros(n_w + 3)])
        self.observation_space = spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32)
        self.action_frame = validation.choice("action_frame", action_frame, {"wheel", "body"})
        # body frame: a normalized body-torque demand, allocated like the analytic baselines do
        # (minimum-norm u = −A⁺T, then each wheel clipped at its limit)
        self._action_map = self.model.allocation * params.max_wheel_torque_nm if self.action_frame == "body" else None
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3 if self._action_map is not None else n_w,), dtype=np.float32)

        self._plant = params
        self._tilt_limit_rad = np.inf  # no roll/pitch stop (AirBearing-v0 has one)
        # State, target and outputs as one-column struct-of-arrays views for the compiled
        # step (the batched env's kernel with one lane; updated in place).
        self._y = np.zeros(7 + n_w)
        self._y[3] = 1.0
        self._target = np.array([0.0, 0.0, 0.0, 1.0])
        self._t = 0.0
        self._steps = 0
        self._renderer = None
        self._ext_stages = np.zeros((self._substeps, 3, 3))
        self._bind_views()
        self._pack_kernel_arguments()
        self._work = np.zeros(kernels.work_size(n_w, 1, include_h, self.model.cost_input == "body"))
        self._step_count = np.zeros(1, dtype=np.int64)
        self._out_time = np.zeros(1)
        self._out_applied = np.zeros((1, n_w))
        self._out_cost = np.zeros(1)
        self._out_reward = np.zeros(1)
        self._out_obs = np.zeros((1, n_x + (n_w if self.observe_wheel_speeds else 0)), dtype=np.float32)
        self._out_qe_w = np.ones(1)
        self._out_terminated = np.zeros(1, dtype=bool)
        self._out_truncated = np.zeros(1, dtype=bool)
        self._x_col = np.empty((n_x, 1))
        self._qe_w = 1.0

    def _bind_views(self) -> None:
        """The kernel's views of the state, target and disturbance arrays (rebuilt after
        unpickling, which would turn views into copies)."""
        self._y_col, self._target_col = self._y.reshape(-1, 1), self._target.reshape(-1, 1)
        self._y_block, self._target_block = self._y.reshape(1, -1, 1), self._target.reshape(1, -1, 1)
        self._ext_rows = self._ext_stages.reshape(1, -1, 1) if self._disturbance is not None else np.zeros((1, 0, 1))

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._bind_views()

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._reset_state(seed, options)
        self._measure()
        obs = self._observation()
        n_w = self._plant.n_wheels
        info = self._info(np.zeros(n_w), np.zeros(n_w), 0.0)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _reset_state(self, seed: int | None, options: dict[str, Any] | None) -> None:
        """Seed, draw and set the start state, target, plant, faults and disturbance (all of
        ``reset`` but the observation and info; the batched env's reset of a sub-env)."""
        gym.Env.reset(self, seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        rng = self.np_random
        n_w = self._plant.n_wheels
        if self._uncertainty is not None:
            self._plant = self.model.params.with_inertia(self._uncertainty.draw(self.model.params.inertia_kg_m2, rng))
            self._pack_matrices()
        q0 = self._draw_attitude(self._initial_fixed, self._initial_angle)
        target = self._draw_attitude(self._target_fixed, self._target_angle)
        rate = self._rate_fixed if self._rate_fixed is not None else rng.uniform(-self._rate_max, self._rate_max, 3)
        wheel = np.zeros(n_w)
        if "attitude" in options:
            q0 = validation.unit_quaternion("options['attitude']", options["attitude"])
        if "target_attitude" in options:
            target = validation.unit_quaternion("options['target_attitude']", options["target_attitude"])
        if "rate_rad_s" in options:
            rate = validation.finite_array("options['rate_rad_s']", options["rate_rad_s"], (3,))
        if "wheel_speed_rad_s" in options:
            wheel = validation.finite_array("options['wheel_speed_rad_s']", options["wheel_speed_rad_s"], (n_w,))
        self._y[:4], self._y[4:7], self._y[7:] = q0, rate, wheel
        self._target[:] = target
        self._t = 0.0
        self._steps = 0
        self._step_count[0] = 0
        if self._disturbance is not None:
            self._disturbance.reset(rng)
        self._sensors.reset(rng, options.get("faults"))  # spawns its own generator: rng's stream is unchanged
        self._faults.reset(rng, options.get("faults"))

    def step(self, action):
        commanded = self.commanded_torques(validation.action(action, self.action_space.shape[0]))
        delivered = self._faults.apply(commanded, self._t)
        if self._disturbance is not None:
            self._disturbance.advance(self.np_random, self.control_dt_s)
            self._fill_disturbance_stages()
        self._kernel(
            self._y_block,
            delivered.reshape(1, -1),
            False,
            self._ext_rows,
            self._mats,
            self._target_block,
            self._constants,
            self._substeps,
            self._step_count,
            self._out_time,
            self._out_applied,
            self._out_cost,
            self._out_reward,
            self._out_obs,
            self._out_qe_w,
            self._out_terminated,
            self._out_truncated,
            self.observe_wheel_speeds,
            self._work,
        )
        cost = float(self._out_cost[0])
        applied = self._out_applied[0].copy()
        # time from the step count, so that onsets and the time limit do not drift
        self._steps += 1
        self._t = self._steps * self.control_dt_s
        terminated = bool(self._out_terminated[0])  # non-finite, or tumbling beyond max_rate_rad_s
        truncated = bool(self._out_truncated[0])
        finite = not terminated or (bool(np.isfinite(self._y).all()) and np.isfinite(cost))
        if finite:
            self._measure()
            self._qe_w = float(self._out_qe_w[0])
        if not finite:
            obs = np.zeros(self.observation_space.shape, np.float32)
        elif self._sensors.enabled or self.fault_hint:
            obs = self._observation()
        else:
            obs = self._out_obs[0].copy()  # the kernel's observation of the true state
        info = self._info(applied, commanded, cost)
        if self.render_mode == "human":
            self.render()
        return obs, -cost, terminated, truncated, info

    def commanded_torques(self, actions: np.ndarray) -> np.ndarray:
        """Motor torques (N·m) commanded by normalized ``actions`` (one, or rows of a batch):
        clipped to [-1, 1] and scaled; in the body frame the minimum-norm allocation of the
        body torque, each wheel clipped at its limit. Sums in a fixed order (no BLAS), so the
        batched env's rows are bitwise the single env's."""
        a = np.minimum(np.maximum(actions, -1.0), 1.0)
        limit = self._plant.max_wheel_torque_nm
        if self._action_map is None:
            return a * limit
        m = self._action_map
        torque = a[..., 0:1] * m[:, 0] + a[..., 1:2] * m[:, 1] + a[..., 2:3] * m[:, 2]
        return np.minimum(np.maximum(torque, -limit), limit)

    def _pack_kernel_arguments(self) -> None:
        """The compiled step, its constants and the plant's matrices (after a parameter change)."""
        p = self._plant
        self._kernel = kernels.kernel_for(self.model, 1)
        self._pack_matrices()
        self._constants = kernels.pack_constants(
            p.wheel_axes,
            self.model.cost.Q,
            self.model.cost.R,
            p.wheel_inertia_kg_m2,
            p.max_wheel_torque_nm,
            p.max_wheel_speed_rad_s,
            self.integrator_dt_s,
            p.offset_torque_nm,
            self.max_rate_rad_s,
            self.control_dt_s,
            self.episode_duration_s,
            self._tilt_limit_rad,
        )

    def _pack_matrices(self) -> None:
        p = self._plant
        self._mats = kernels.pack_matrices(p.inertia_kg_m2, p.inertia_eff_inv).reshape(1, -1, 1)

    def _fill_disturbance_stages(self) -> None:
        """External torque at each sub-step's RK4 stage times (t, t + h/2, t + h)."""
        h = self.integrator_dt_s
        for j in range(self._substeps):
            t = self._t + j * h
            for k, dt in enumerate((0.0, 0.5 * h, h)):
                self._ext_stages[j, k] = self._disturbance.torque_nm_at(t + dt)

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self._renderer is None:
            from attitude_envs.rendering import AttitudeRenderer

            self._renderer = AttitudeRenderer(human=self.render_mode == "human")
        p = self._plant
        return self._renderer.draw(
            self._y[:4], self._target, self._y[7:], p.max_wheel_speed_rad_s, self._t, self._y[4:7]
        )

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ internals
    def _draw_attitude(self, fixed, max_angle_deg: float) -> np.ndarray:
        if fixed is not None:
            return fixed.copy()
        return quaternion.random_within_angle(self.np_random, max_angle_deg)

    def error_state(self) -> np.ndarray:
        """The true error state ``x`` (float64) of the current state."""
        return self.model.error_state(self._y[:4], self._y[4:7], self._y[7:], self._target)

    def _measure(self) -> None:
        """Sample the sensors at the current time (no-op when sensors are off)."""
        if self._sensors.enabled:
            truth = {"gyro": self._y[4:7], "star_tracker": self._y[:4], "tachometer": self._y[7:]}
            self._meas = self._sensors.measure(truth, self._t)

    def _observation(self) -> np.ndarray:
        qe_w = self._out_qe_w  # the true error state (also gives info's true error angle)
        kernels.error_state_columns(
            self._y_col,
            self._target_col,
            self._plant.wheel_inertia_kg_m2,
            self.model.include_wheel_momentum,
            self._x_col,
            qe_w,
        )
        self._qe_w = float(qe_w[0])
        x = self._x_col[:, 0]
        wheel = self._y[7:]
        if self._sensors.enabled:
            m = self._meas
            x = self.model.error_state(m["star_tracker"], m["gyro"], m["tachometer"], self._target)
            wheel = m["tachometer"]
        if self.observe_wheel_speeds:
            x = np.concatenate([x, wheel / self._plant.max_wheel_speed_rad_s])
        if self.fault_hint:
            x = np.concatenate([x, self._faults.active_flags(self._t), self._sensors.active_flags(self._t)])
        return x.astype(np.float32)

    def _info(self, applied: np.ndarray, commanded: np.ndarray, cost: float) -> dict:
        # Info holds new arrays every call (gymnasium's checker): one copy of the state and
        # target, whose slices are views of it.
        y = np.concatenate([self._y, self._target])
        n = y.shape[0] - 4
        return {
            "state": {
                "attitude": y[:4],
                "rate_rad_s": y[4:7],
                "wheel_speed_rad_s": y[7:n],
                "target_attitude": y[n:],
            },
            "applied": applied,
            "commanded": commanded,
            "cost": cost,
            "time_s": self._t,
            "error_angle_deg": float(np.degrees(2.0 * np.arccos(min(1.0, self._qe_w)))),
            "disturbance_torque_nm": np.zeros(3)
            if self._disturbance is None
            else np.array(self._disturbance.torque_nm_at(self._t)),
            "true_inertia_kg_m2": self._plant.inertia_kg_m2.copy(),
            "faults": self._faults.info(self._t) + self._sensors.info(self._t),
        } | self._sensor_info()

    def _sensor_info(self) -> dict:
        if not self._sensors.enabled:
            return {}
        meas = {k: v.copy() for k, v in self._meas.items()}
        return {"sensors": meas, "sensor_bias": {k: v.copy() for k, v in self._sensors.bias.items()}}


def _divides(control_dt_s: float, integrator_dt_s: float) -> bool:
    try:
        substeps(control_dt_s, integrator_dt_s)
    except ValueError:
        return False
    return True


def _optional_quaternion(name: str, value) -> np.ndarray | None:
    return None if value is None else validation.unit_quaternion(name, value)


def _angle(name: str, value: float) -> float:
    v = float(value)
    if not 0.0 <= v <= 180.0:
        raise ValueError(f"{name} must be in [0, 180], got {value!r}")
    return v
