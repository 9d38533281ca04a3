"""FuelSlosh-v0: planar spacecraft burn with two-pendulum fuel slosh (spec 004)."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.faults import ActuatorFaults
from attitude_envs.integrators import substeps
from attitude_envs.plants import slosh
from attitude_envs.plants import slosh_kernels as kernels
from attitude_envs.plants.slosh_model import PAPER_Q, PAPER_R, REDUCED_INDEX, FuelSloshModel, reduced_state
from attitude_envs.sensors import Channel, SensorSuite

# Spec 004 Table 4 (READ): [v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2] in m/s, rad, rad/s.
PAPER_INITIAL_STATE = np.array(
    [3000.0, 100.0, math.radians(2.0), 0.0, math.radians(30.0), 0.0, math.radians(-30.0), 0.0]
)
_INITIAL_ORDER = (slosh.IVX, slosh.IVZ, slosh.ITH, slosh.IOM, slosh.IPSI1, slosh.IDPSI1, slosh.IPSI2, slosh.IDPSI2)
_OPTION_KEYS = {"state", "faults"}
# full-state indices of the observation [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2, v_x], or [v_z, θ, Ω, v_x]
OBS_INDEX = np.append(REDUCED_INDEX, slosh.IVX)
OBS_INDEX_NO_SLOSH = OBS_INDEX[[0, 1, 2, 7]]


class FuelSloshEnv(gym.Env):
    """Stabilize pitch, transverse velocity and fuel slosh during a constant-thrust burn.

    Plant: the full 5-DOF nonlinear model of :mod:`attitude_envs.plants.slosh` (body
    translation v_x, v_z, pitch θ, two damped slosh pendulums ψ1, ψ2; spec 004 §2.5) in
    mass-matrix form, integrated by fixed-step RK4 with ``integrator_dt_s`` sub-steps in
    one compiled call per step (:func:`attitude_envs.plants.slosh_kernels.control_step`).
    Step-size choice: with the input held over a control period the plant is *not* stiff
    (its fastest modes are the slosh pendulums at ≈ 1–1.5 rad/s; RK4 at 0.05 s has
    |λh| ≤ 0.08, per-step error ~1e-8). The stiffness the spec warns about (§3.2: LQR
    closed-loop pole at −448 rad/s) belongs to the continuous-time paper controller; here
    the controller is sampled every ``control_dt_s``, so a policy must be designed for
    that period (the LQR baseline uses the exact ZOH discretization), and the reproduction
    simulates the continuous paper LQR with scipy's stiff LSODA.

    ================  ==========================================================  ==========
    Quantity          Meaning                                                     Units
    ================  ==========================================================  ==========
    State (truth)     X, Z (inertial position of the tank centre), θ, ψ1, ψ2,    m, rad,
                      v_x, v_z (tank-centre velocity, body axes), Ω, ψ̇1, ψ̇2       m/s, rad/s
    Observation       float32 ``[v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2, v_x]``;             m/s, rad,
                      with ``observe_slosh=False`` only ``[v_z, θ, Ω, v_x]``      rad/s
    Action            2 in [-1, 1] (clipped): gimbal δ = a0·``max_gimbal_deg``,   deg,
                      pitch moment M_c = a1·``max_moment_nm``; thrust F constant  N·m, N
    Reward            −∫ (xᵀQx + u_cᵀRu_c) dt over the step (RK4, augmented       (cost)
                      state); x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2], u_c = realized
                      new inputs [a_z, Ω̇] (spec §2.7); Q, R default to the paper's
                      LQR weights (§3.2)
    Start state       the paper's (Table 4): v_x 3000 m/s, v_z 100 m/s, θ 2°,     m/s, deg
                      ψ1 30°, ψ2 −30°, rates 0; ``randomize_initial_state``
                      draws v_z, θ, ψ_i uniformly within ± those magnitudes
    Termination       non-finite state, |ψ_i| > ``max_slosh_angle_deg``,          deg,
                      |θ| > ``max_pitch_angle_deg`` or |Ω| > ``max_pitch_rate_    rad/s
                      rad_s``
    Truncation        simulated time reaches ``episode_duration_s``               s
    ================  ==========================================================  ==========

    Parameters: ``fill_preset`` (``"i"`` default, ``"ii"``, ``"iii"``, ``"iv"``: the
    spec's length mappings, §2.2), ``params`` (a full :class:`SloshParams`, overrides the
    preset), ``max_gimbal_deg`` (default 30°, OURS: the paper gives no limit; the paper's
    PD needs 17.5°), ``max_moment_nm`` (default 2000 N·m, OURS), ``control_dt_s`` (0.1),
    ``integrator_dt_s`` (0.05), ``episode_duration_s`` (1500, spec §4.2), ``Q``, ``R``,
    ``observe_slosh``, ``initial_state`` (8 values, order as PAPER_INITIAL_STATE),
    ``randomize_initial_state``, ``max_slosh_angle_deg`` (90), ``max_pitch_rate_rad_s``
    (0.5), ``max_pitch_angle_deg`` (90), ``design_v_x_m_s`` (3000, the nominal linear model's axial speed).
    ``faults`` (actuator 0 = gimbal δ in rad, 1 = pitch moment in N·m; see
    :mod:`attitude_envs.faults`; ``"target": "sensor"`` entries hit the ``state`` sensor),
    ``sensors`` (``{"state": {...}}``, see :mod:`attitude_envs.sensors`: the observation is
    then measured), ``fault_hint`` (append 3 active-fault flags: 2 actuators, the sensor). ``reset(options={"state": 8 values, "faults": [...]})``
    pins the start state and the episode's faults.

    ``env.unwrapped.model`` is the nominal :class:`FuelSloshModel` (reduced model,
    linearizations, input inversion). ``info``: ``state`` (full truth, named), ``x``
    (reduced state, float64), ``applied`` ([δ rad, M_c N·m] after clipping and faults),
    ``commanded`` (same, before clipping), ``new_inputs`` (step-mean [a_z, Ω̇]), ``cost``,
    ``time_s``, ``faults`` (ground truth).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        fill_preset: str = "i",
        params: slosh.SloshParams | None = None,
        max_gimbal_deg: float = 30.0,
        max_moment_nm: float = 2000.0,
        control_dt_s: float = 0.1,
        integrator_dt_s: float = 0.05,
        episode_duration_s: float = 1500.0,
        Q=None,
        R=None,
        observe_slosh: bool = True,
        initial_state=None,
        randomize_initial_state: bool = False,
        max_slosh_angle_deg: float = 90.0,
        max_pitch_rate_rad_s: float = 0.5,
        max_pitch_angle_deg: float = 90.0,
        design_v_x_m_s: float = 3000.0,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
    ) -> None:
        if params is None:
            params = slosh.SloshParams.from_fill_preset(fill_preset)
        elif not isinstance(params, slosh.SloshParams):
            raise ValueError(f"params must be a SloshParams, got {type(params).__name__}")
        gimbal = validation.positive("max_gimbal_deg", max_gimbal_deg)
        if gimbal > 90.0:
            raise ValueError(f"max_gimbal_deg must be in (0, 90], got {max_gimbal_deg!r}")
        self.control_dt_s = validation.positive("control_dt_s", control_dt_s)
        self.integrator_dt_s = validation.positive("integrator_dt_s", integrator_dt_s)
        self._substeps = substeps(self.control_dt_s, self.integrator_dt_s)
        self.episode_duration_s = validation.positive("episode_duration_s", episode_duration_s)
        cost = QuadraticCost.build(PAPER_Q if Q is None else Q, PAPER_R if R is None else R, 7, 2)
        self.model = FuelSloshModel(
            params,
            cost,
            math.radians(gimbal),
            validation.positive("max_moment_nm", max_moment_nm),
            float(validation.finite_array("design_v_x_m_s", design_v_x_m_s, ())),
            self.control_dt_s,
        )
        self.observe_slosh = bool(observe_slosh)
        self._initial = (
            PAPER_INITIAL_STATE.copy()
            if initial_state is None
            else validation.finite_array("initial_state", initial_state, (8,))
        )
        self.randomize_initial_state = bool(randomize_initial_state)
        self.max_slosh_angle_rad = math.radians(validation.positive("max_slosh_angle_deg", max_slosh_angle_deg))
        self.max_pitch_rate_rad_s = validation.positive("max_pitch_rate_rad_s", max_pitch_rate_rad_s)

        self.max_pitch_angle_rad = math.radians(validation.positive("max_pitch_angle_deg", max_pitch_angle_deg))
        # Bounds: speeds stay below |v(0)| + a_x t ≤ 1e4 m/s on any sensible burn; angles and
        # rates within twice their termination limits; slosh rates within 50 rad/s.
        high = np.array([1e4, 2 * self.max_pitch_angle_rad, 2 * self.max_pitch_rate_rad_s])
        slosh_high = np.array([2 * self.max_slosh_angle_rad, 50.0] * 2)
        high = np.concatenate([high, slosh_high, [1e4]]) if self.observe_slosh else np.append(high, 1e4)
        self.observation_space = spaces.Box(-high.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        # actuator 0: gimbal angle (rad), actuator 1: pitch moment (N·m)
        self._faults = ActuatorFaults(
            faults, 2, [self.model.max_gimbal_rad, self.model.max_moment_nm], other_targets={"sensor"}
        )
        self._sensors = SensorSuite(sensors, [Channel("state", len(high))], faults)
        self.fault_hint = bool(fault_hint)
        if self.fault_hint:  # 2 actuator flags + 1 sensor flag in [0, 1]
            low = np.concatenate([-high, np.zeros(3)]).astype(np.float32)
            self.observation_space = spaces.Box(
                low, np.concatenate([high, np.ones(3)]).astype(np.float32), dtype=np.float32
            )
        self._y = np.zeros(slosh.N_STATE)
        self._t = 0.0
        self._steps = 0
        self._limits = np.array([self.model.max_gimbal_rad, self.model.max_moment_nm])
        self._obs_index = OBS_INDEX if self.observe_slosh else OBS_INDEX_NO_SLOSH
        self._work = np.empty(kernels.WORK_SIZE)
        self._constants = kernels.step_constants(
            self.model.params.packed,
            self.integrator_dt_s,
            self._substeps,
            self.control_dt_s,
            self.model.cost.Q,
            self.model.cost.R,
        )

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        init = self._initial.copy()
        if self.randomize_initial_state:
            scale = np.abs(PAPER_INITIAL_STATE)
            for k in (1, 2, 4, 6):
                init[k] = self.np_random.uniform(-scale[k], scale[k])
        if "state" in options:
            init = validation.finite_array("options['state']", options["state"], (8,))
        self._y = np.zeros(slosh.N_STATE)
        self._y[list(_INITIAL_ORDER)] = init
        self._t = 0.0
        self._steps = 0
        self._sensors.reset(self.np_random, options.get("faults"))  # own spawned generator
        self._faults.reset(self.np_random, options.get("faults"))
        zero = np.zeros(2)
        return self._observation(), self._info(zero, zero, zero, 0.0)

    def step(self, action):
        a0, a1 = validation.action(action, 2).tolist()  # Python floats: cheaper than tiny arrays
        gimbal, moment = self.model.max_gimbal_rad, self.model.max_moment_nm
        commanded = np.array([a0 * gimbal, a1 * moment])
        applied = np.array([min(max(a0, -1.0), 1.0) * gimbal, min(max(a1, -1.0), 1.0) * moment])
        applied = self._faults.apply(applied, self._t)
        new_inputs = np.empty(2)  # step-mean [a_z, Ω̇]
        cost = kernels.control_step(self._y, applied, self._constants, new_inputs, self._work)
        self._steps += 1
        self._t = self._steps * self.control_dt_s  # from the step count: no drift of onsets/time limit
        y = self._y.tolist()
        # a finite sum proves every entry finite; only a non-finite one needs the exact check
        finite = math.isfinite(cost + sum(y) + float(new_inputs.sum())) or (
            math.isfinite(cost) and all(map(math.isfinite, y)) and bool(np.isfinite(new_inputs).all())
        )
        terminated = not finite or (
            max(abs(y[slosh.IPSI1]), abs(y[slosh.IPSI2])) > self.max_slosh_angle_rad
            or abs(y[slosh.IOM]) > self.max_pitch_rate_rad_s
            or abs(y[slosh.ITH]) > self.max_pitch_angle_rad
        )
        truncated = bool(self._t >= self.episode_duration_s - 1e-9 * self.control_dt_s) and not terminated
        obs = self._observation() if finite else np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, self._info(applied, commanded, new_inputs, cost)

    def batch_termination(self, states: np.ndarray) -> np.ndarray:
        """The limits :meth:`step` terminates on (slosh angle, pitch rate, pitch angle) for
        rows of full states ``y`` (E × 10); the batched env's hook (it checks finiteness)."""
        slosh_angle = np.maximum(np.abs(states[:, slosh.IPSI1]), np.abs(states[:, slosh.IPSI2]))
        return (
            (slosh_angle > self.max_slosh_angle_rad)
            | (np.abs(states[:, slosh.IOM]) > self.max_pitch_rate_rad_s)
            | (np.abs(states[:, slosh.ITH]) > self.max_pitch_angle_rad)
        )

    # ------------------------------------------------------------------ internals
    def _observation(self) -> np.ndarray:
        obs = self._y[self._obs_index]
        if self._sensors.enabled:
            obs = self._sensors.measure({"state": obs}, self._t)["state"]
        if self.fault_hint:
            obs = np.concatenate([obs, self._faults.active_flags(self._t), self._sensors.active_flags(self._t)])
        return obs.astype(np.float32)

    @property
    def state(self) -> np.ndarray:
        """The full true state ``y`` (10 entries, see :mod:`attitude_envs.plants.slosh`)."""
        return self._y.copy()

    def _info(self, applied, commanded, new_inputs, cost: float) -> dict:
        # New arrays every call (gymnasium's checker): one copy of the state, whose slices
        # are views of it.
        y = self._y.copy()
        th, vx, vz, om = y[[slosh.ITH, slosh.IVX, slosh.IVZ, slosh.IOM]].tolist()
        return {
            "state": {
                "position_m": y[slosh.IX : slosh.IZ + 1],
                "theta_rad": th,
                "slosh_angle_rad": y[slosh.IPSI1 : slosh.IPSI2 + 1],
                "v_x_m_s": vx,
                "v_z_m_s": vz,
                "pitch_rate_rad_s": om,
                "slosh_rate_rad_s": y[slosh.IDPSI1 :],
            },
            "full_state": y,
            "x": reduced_state(y),
            "applied": applied,
            "commanded": commanded,
            "new_inputs": new_inputs,
            "cost": cost,
            "time_s": self._t,
            "faults": self._faults.info(self._t) + self._sensors.info(self._t),
        }
