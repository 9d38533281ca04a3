"""ReactionWheel-v0: rest-to-rest attitude maneuvers of a rigid spacecraft with N wheels."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import presets, quaternion, validation
from attitude_envs.conditions import Conditions
from attitude_envs.cost import QuadraticCost
from attitude_envs.envs.base import TERMINATION_COSTS, AttitudeEnv, Layers, build_layers, constructor_keywords
from attitude_envs.evaluation.success import FINAL_ERROR_DEG
from attitude_envs.integrators import substeps
from attitude_envs.plants import gyrostat
from attitude_envs.plants import gyrostat_kernels as kernels
from attitude_envs.plants.gyrostat_model import ReactionWheelModel
from attitude_envs.presets import flight
from attitude_envs.sensors import Channel
from attitude_envs.uncertainty import InertiaUncertainty

_TWO_RAD_TO_DEG = 2.0 * (180.0 / np.pi)  # np.degrees(2 a) = a · 2(180/π) bit for bit (times 2 is exact)
_OPTION_KEYS = {"attitude", "rate_rad_s", "wheel_speed_rad_s", "target_attitude", "faults"}
# Values of the keywords that neither the preset nor the caller set (the physical ones,
# _REQUIRED, must come from one of them).
_DEFAULTS = {
    "cost_input": "body",
    "target_angle_deg": 0.0,
    "initial_angle_deg": 0.0,
    "initial_rate_max_rad_s": 0.0,
    "wheel_momentum_weight": 0.0,
    "max_rate_rad_s": 2.0 * np.pi,
    "observe_wheel_speeds": False,
    "action_frame": "wheel",
    "fault_hint": False,
    "termination_cost": "hold",
}
_REQUIRED = (
    "inertia_kg_m2",
    "wheel_axes",
    "wheel_inertia_kg_m2",
    "max_wheel_torque_nm",
    "max_wheel_speed_rad_s",
    "control_dt_s",
    "integrator_dt_s",
    "episode_duration_s",
    "Q",
    "R",
)


class ReactionWheelEnv(AttitudeEnv):
    """Rigid spacecraft with N reaction wheels driven to a target attitude (rest-to-rest maneuvers).

    **Description.** The plant is the exact gyrostat of :mod:`attitude_envs.plants.gyrostat`,
    ``(I − Σ J_s aᵢaᵢᵀ) ω̇ = −ω × (Iω + Σ J_s Ωᵢ aᵢ) − Σ uᵢ aᵢ + T_ext`` and
    ``J_s (Ω̇ᵢ + aᵢ·ω̇) = uᵢ`` (the papers' ``ω̇ = I⁻¹[−ω × (Iω + h_w) + T_c]`` is its
    small-wheel special case), with scalar-last quaternion kinematics (body to inertial, as
    scipy's ``Rotation``). ``inertia_kg_m2`` is the whole spacecraft's inertia *including*
    the wheels' spin inertia; wheel speeds are relative to the body (tachometer). Fixed-step
    RK4 with ``integrator_dt_s`` sub-steps inside each ``control_dt_s`` period, the stage
    cost integrated as an extra state, the quaternion renormalized after every sub-step; each
    step is one compiled call (:mod:`attitude_envs.plants.gyrostat_kernels`), the same source
    as the batched env's, so single and batched trajectories are bitwise identical. The
    default preset is the feedback-linearization paper's 4 kg·m² spacecraft with a pyramid of
    four wheels; AirBearing-v0 (:mod:`attitude_envs.envs.air_bearing`) is this env with the
    air-bearing platform's preset. Bad input (an inertia that is not symmetric, positive
    definite or violates the triangle inequality, a rank-deficient wheel matrix, negative
    limits, non-unit quaternions, wrong-shaped or non-finite actions) raises a
    ``ValueError`` naming the parameter and the accepted range.

    **Action space.** ``Box(-1, 1, (N,), float32)``, clipped (the actuator's saturation):
    motor torques ``u = a · max_wheel_torque_nm`` (N·m). Positive ``uᵢ`` spins wheel i up
    about its axis ``aᵢ``; the body receives ``−aᵢ uᵢ``. A wheel at
    ``max_wheel_speed_rad_s`` gets no further torque outwards (motor driver speed limit).
    With ``action_frame="body"`` the action is ``Box(-1, 1, (3,), float32)``: a body-torque
    demand ``T = a · max_wheel_torque_nm`` that the env allocates like the analytic
    baselines do (minimum norm ``u = −A⁺T``, each wheel clipped). Use the body frame for
    reinforcement learning: with one action per wheel, exploration noise drives momentum
    into the wheels' null space, which the cost does not see, until a wheel saturates.

    **Observation space.** ``Box(float32)`` of the error state ``x = [q_e,vec (3),
    ω (3, rad/s)]`` with ``q_e = q_T* ⊗ q`` (w ≥ 0); plus the wheel momentum
    ``h_w = J_s Ω`` (N, N·m·s) when ``wheel_momentum_weight > 0``; plus ``Ω / Ω_max`` (N)
    with ``observe_wheel_speeds``; plus N + 3 fault flags with ``fault_hint`` (1.0 per
    actuator, then per sensor gyro, star tracker, tachometer, with an active fault).
    Bounds: ``|q_e,vec| ≤ 1``, rates within 2 × ``max_rate_rad_s``; the step that crosses a
    limit observes its measurement clipped to the bounds
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`; ``info["truth"]`` holds
    the true state). With sensors (or sensor
    faults) the observation is the error state of the *measured* attitude, rate and wheel
    speeds (a dropout in ``"nan"`` mode puts NaN in it, outside the bounds by design).

    **Reward.** ``−∫ (xᵀQx + u_cᵀRu_c) dt`` over the step, integrated by the same RK4 as the
    plant; ``u_c`` is the body torque ``−A u`` (``cost_input="body"``, the papers' presets)
    or the motor torques ``u`` (``"wheel"``). ``info["cost"]`` is the positive step cost.

    **Starting state.** Attitude uniformly random within ``initial_angle_deg`` of identity,
    body rate uniform in ±``initial_rate_max_rad_s`` per axis, wheels at rest; target
    uniformly random within ``target_angle_deg`` of identity. ``initial_attitude``,
    ``initial_rate_rad_s`` and ``target_attitude`` fix them; ``reset(options=...)`` pins
    ``attitude``, ``rate_rad_s``, ``wheel_speed_rad_s``, ``target_attitude`` and this
    episode's ``faults``.

    **Episode end.** Terminated on a non-finite state, on tumbling (``max|ω| >
    max_rate_rad_s``, default 2π rad/s: one revolution per second) and, when
    ``tilt_limit_deg`` is set, on roll or pitch beyond it. Truncated when the simulated
    time reaches ``episode_duration_s`` (inside the env: no ``TimeLimit`` wrapper, so the
    limit does not depend on ``control_dt_s``).
    A step that crosses a limit (with a finite state) is charged, on top of its running
    cost, the terminal error state's running cost held over the rest of the episode,
    ``(episode_duration_s − t) xᵀQx`` (``termination_cost="hold"``; ``"none"``: nothing
    more), so ending an episode early never lowers J.

    **Arguments.** ``None`` (the default of every physical keyword) takes the preset's
    value; where the preset sets none, the default named here. "preset" in the default
    column: the keyword must come from the preset or the caller.

    ==========================  ==========  ================  ==========  ==================================================
    name                        type        default           unit        description
    ==========================  ==========  ================  ==========  ==================================================
    ``preset``                  str         "pyramid-4wheel"  —           parameter set or alias (see Presets); None: the
                                                                          env's default preset
    ``inertia_kg_m2``           3×3         preset            kg·m²       whole spacecraft, wheels' spin inertia included
                                                                          (symmetric, positive definite, triangle
                                                                          inequality)
    ``wheel_axes``              3×N         preset            —           unit spin axes as columns (rank 3)
    ``wheel_inertia_kg_m2``     float       preset            kg·m²       spin inertia J_s of each wheel
    ``max_wheel_torque_nm``     float       preset            N·m         motor torque limit (the action's scale)
    ``max_wheel_speed_rad_s``   float       preset            rad/s       speed limit: the motor driver blocks torque that
                                                                          would spin a wheel beyond it
    ``control_dt_s``            float       preset            s           control period (zero-order hold)
    ``integrator_dt_s``         float       preset            s           RK4 sub-step; must divide ``control_dt_s`` (one
                                                                          sub-step when only ``control_dt_s`` is given and
                                                                          the preset's does not divide it)
    ``episode_duration_s``      float       preset            s           simulated time limit (truncation)
    ``Q``, ``R``                6×6, 3×3    preset            —           cost weights on x and on u_c (R is N×N with
                                                                          ``cost_input="wheel"``)
    ``cost_input``              str         "body"            —           ``"body"``: u_c is the body torque −A u;
                                                                          ``"wheel"``: the motor torques u
    ``wheel_momentum_weight``   float ≥ 0   0                 1/(N·m·s)²  > 0 appends the wheel momentum h_w to x (and the
                                                                          observation) with this weight
    ``target_attitude``         4 floats    preset / None     —           fixed target quaternion (scalar last); None: drawn
    ``target_angle_deg``        float       preset / 0        deg         random target within this angle of identity
    ``initial_attitude``        4 floats    None              —           fixed start quaternion; None: drawn
    ``initial_angle_deg``       float       preset / 0        deg         random start within this angle of identity
    ``initial_rate_rad_s``      3 floats    None              rad/s       fixed start body rate; None: drawn
    ``initial_rate_max_rad_s``  float       preset / 0        rad/s       start rate uniform in ± this per axis
    ``offset_torque_nm``        3 floats    None              N·m         m g r_s of a centre-of-mass offset about an air
                                                                          bearing's centre of rotation (body axes; torque p
                                                                          × K(q), see
                                                                          :func:`~attitude_envs.plants.gyrostat.gravity_torque_nm`);
                                                                          the nominal model's
    ``true_offset_torque_nm``   3 floats    None              N·m         the true plant's offset torque where it differs
                                                                          from the nominal ``offset_torque_nm`` that
                                                                          ``env.unwrapped.model`` carries; None: the same
    ``tilt_limit_deg``          float       None              deg         roll/pitch stop in (0, 90) that ends the episode;
                                                                          None: no stop
    ``inertia_uncertainty``     dict        None              —           true inertia drawn per episode
                                                                          (:mod:`attitude_envs.uncertainty`)
    ``disturbance``             dict        None              N·m         external torque
                                                                          (:mod:`attitude_envs.disturbances`), e.g.
                                                                          ``{"kind": "constant", "torque_nm": [1e-3, 0,
                                                                          0]}``
    ``max_rate_rad_s``          float       2π                rad/s       tumbling limit (terminates)
    ``observe_wheel_speeds``    bool        False             —           append Ω / Ω_max to the observation
    ``action_frame``            str         "wheel"           —           ``"wheel"``: one action per wheel; ``"body"``: a
                                                                          body-torque demand through the minimum-norm
                                                                          allocation
    ``faults``                  list[dict]  None              —           actuator and sensor faults
                                                                          (:mod:`attitude_envs.faults`); also per episode in
                                                                          ``reset(options={"faults": [...]})``
    ``sensors``                 dict        None              —           sensor models (:mod:`attitude_envs.sensors`):
                                                                          ``gyro``, ``star_tracker``, ``tachometer``; None:
                                                                          the truth is observed
    ``fault_hint``              bool        False             —           append N + 3 active-fault flags to the observation
    ``termination_cost``        str         "hold"            —           ``"hold"``: a limit crossing is charged the
                                                                          terminal running cost over the rest (see Episode
                                                                          end); ``"episode"`` (v1): ``T·xᵀQx``; ``"none"``: no charge
    ``conditions``              str / dict  "lab"             —           ``"lab"``: the papers' world; ``"flight"``: cited
                                                                          sensors, actuator dynamics, a one-period delay and
                                                                          per-episode plant draws; a dict: features one at a
                                                                          time (:mod:`attitude_envs.conditions`)
    ``render_mode``             str         None              —           ``"rgb_array"`` or ``"human"`` (matplotlib)
    ==========================  ==========  ================  ==========  ==================================================


    **Presets.** ``"pyramid-4wheel"`` (default): the feedback-linearization paper's 4 kg·m²
    spacecraft with four wheels in a pyramid, rest-to-rest maneuvers to random targets
    within 60°. ``"heravi-2017"``: Heravi & Novinzadeh (2017)'s 1000 kg·m² satellite with
    four wheels tilted 20°, regulation from the paper's initial state. AirBearing-v0's
    ``"air-bearing-85kg"`` is a preset of the subclass.

    **Faults and sensors.** Actuator i is wheel i (motor torque, N·m; also with
    ``action_frame="body"``). Faults (:mod:`attitude_envs.faults`) act on the commanded
    motor torques; ``"target": "sensor"`` entries act on the sensors. Sensor channels
    (:mod:`attitude_envs.sensors`): ``gyro`` (body rate, rad/s), ``star_tracker``
    (attitude; errors are a body rotation vector, rad) and ``tachometer`` (wheel speeds,
    rad/s). ``inertia_uncertainty`` draws the true inertia per episode and ``disturbance``
    adds an external torque; the controllers' model ``env.unwrapped.model`` stays nominal.

    **Flight conditions** (``conditions=``, :mod:`attitude_envs.conditions`; values and sources
    in :mod:`attitude_envs.presets.flight_gyrostat`). Sensors: a tactical gyro with bias and bias
    walk, a star tracker slower than the control loop (held between its samples), tachometers.
    Actuators (:mod:`attitude_envs.actuator_dynamics`): the command acts one period late, at the
    torque resolution, through a first-order motor lag, times a per-episode scale-factor error,
    minus Coulomb and viscous wheel friction. The true plant per episode: inertia moments and
    principal axes, each wheel axis tilted within the mounting tolerance and, on an air bearing,
    the offset torque; ``info["truth"]["drawn_parameters"]`` holds the draws. They come from a
    generator spawned from the env's, so a flight episode starts where the lab episode of the
    same seed starts.

    **Info** (:mod:`attitude_envs.info`). ``info["truth"]`` holds ``state``
    (``attitude``, ``rate_rad_s``, ``wheel_speed_rad_s``, ``target_attitude``),
    ``applied`` (mean motor torque actually delivered over the step, N·m), ``faults``
    (every fault of the episode with its draws and whether it is active),
    ``error_angle_deg``, ``disturbance_torque_nm``, ``true_inertia_kg_m2``,
    ``sensor_bias`` (with sensors) and ``tilt_limit_hit`` (with a tilt limit);
    ``info["measured"]`` has the keys of ``truth["state"]`` from the star tracker, gyro and
    tachometer readings (when sensors are off it is ``truth["state"]`` itself;
    ``target_attitude`` is the commanded target; replace its entries, do not modify them in
    place: they are shared with ``truth`` or ``sensors``). Top level: ``cost``, ``time_s``,
    ``commanded`` (motor torques the action asked for, N·m) and, with sensors, ``sensors``
    (raw ``star_tracker`` quaternion, ``gyro``, ``tachometer``).

    **Model.** ``env.unwrapped.model`` is the *nominal* :class:`ReactionWheelModel`
    (inertia, wheels, cost, allocation, linearization and the exact zero-order-hold
    discretization ``discrete()``); the true inertia, offset torque and disturbance stay in
    the env.

    **Public extension interface.** Batched envs and tools use the public members
    :attr:`kernel_constants`, :attr:`kernel_matrices`, :attr:`n_substeps`,
    :attr:`state_row`, :attr:`target_attitude`, :attr:`observation_size`,
    :meth:`disturbance_stages`, :meth:`commanded_torques`, :meth:`reset_episode` and the
    base's ``fault_layer``, ``sensor_layer`` and ``disturbance``.

    **Success** (:mod:`attitude_envs.evaluation.success`): ``success_metric`` is
    ``FINAL_ERROR_DEG``, the final attitude error angle (deg, default threshold 2°);
    ``wheel_trace`` is True (episodes record as an ``EpisodeTrace``).

    **Version history.** v1 (``attitude_envs/ReactionWheel-v1``, 2026-11-27): a limit crossing charged ``T·xᵀQx`` (``termination_cost="episode"``: at least what holding the state costs a learner that bootstraps at the time limit); everything else v0's. v0: a limit crossing charged the terminal running cost over the rest of the episode (``termination_cost``, 2026-11); the exact gyrostat with RK4 sub-steps and the integrated
    cost; actuator faults, sensors and ``fault_hint``; one compiled step shared with the
    natively batched env (bitwise identical); ``action_frame="body"``; the air-bearing
    offset torque and tilt stop (for AirBearing-v0), ``true_offset_torque_nm``; presets
    through :mod:`attitude_envs.presets` (``"spec-000"`` and ``"spec-001"`` kept as
    aliases); infos split into ``truth`` and ``measured`` (:mod:`attitude_envs.info`).
    """

    env_name = "ReactionWheel-v0"
    default_preset = "pyramid-4wheel"
    success_metric = FINAL_ERROR_DEG
    wheel_trace = True
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(
        self,
        preset: str | None = None,
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
        wheel_momentum_weight: float | None = None,
        target_attitude=None,
        target_angle_deg: float | None = None,
        initial_attitude=None,
        initial_angle_deg: float | None = None,
        initial_rate_rad_s=None,
        initial_rate_max_rad_s: float | None = None,
        offset_torque_nm=None,
        true_offset_torque_nm=None,
        tilt_limit_deg: float | None = None,
        inertia_uncertainty: dict | None = None,
        disturbance: dict | None = None,
        max_rate_rad_s: float | None = None,
        observe_wheel_speeds: bool | None = None,
        action_frame: str | None = None,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool | None = None,
        termination_cost: str | None = None,
        conditions=None,
        render_mode: str | None = None,
    ) -> None:
        cfg = configure(type(self), preset, locals())
        self.preset = cfg.preset
        params = cfg.model.params
        self.control_dt_s, self.integrator_dt_s = cfg.control_dt_s, cfg.integrator_dt_s
        self._substeps = cfg.n_substeps
        self.episode_duration_s = cfg.episode_duration_s
        self.model = cfg.model
        cost, n_w, include_h = cfg.model.cost, params.n_wheels, cfg.model.include_wheel_momentum
        n_x = cost.Q.shape[0]
        self._target_fixed, self._initial_fixed = cfg.target_attitude, cfg.initial_attitude
        self._target_angle, self._initial_angle = cfg.target_angle_deg, cfg.initial_angle_deg
        self._rate_fixed, self._rate_max = cfg.initial_rate_rad_s, cfg.initial_rate_max_rad_s
        #: roll/pitch stop (deg) that ends the episode, or None
        self.tilt_limit_deg = cfg.tilt_limit_deg
        self._tilt_limit_rad = np.inf if cfg.tilt_limit_deg is None else math.radians(cfg.tilt_limit_deg)
        self._uncertainty = cfg.inertia_uncertainty
        self._use_layers(cfg.layers)
        self._flight_plant = cfg.flight_tolerances
        self._init_termination_cost(cfg.termination_cost, cost.Q, self.episode_duration_s)
        self._meas: dict[str, np.ndarray] = {}
        self.max_rate_rad_s = cfg.max_rate_rad_s
        self.observe_wheel_speeds = cfg.observe_wheel_speeds
        self.render_mode = cfg.render_mode

        # Observation bounds: |q_e,vec| <= 1; rates within 2 × max_rate_rad_s (the episode
        # terminates beyond max_rate_rad_s); wheel momentum within 1.5 × J_s Ω_max.
        rate_bound = 2.0 * self.max_rate_rad_s
        obs_high = np.concatenate([np.ones(3), np.full(3, rate_bound)])
        if include_h:
            h_bound = 1.5 * params.wheel_inertia_kg_m2 * params.max_wheel_speed_rad_s
            obs_high = np.concatenate([obs_high, np.full(n_w, h_bound if np.isfinite(h_bound) else 1e6)])
        if self.observe_wheel_speeds:
            obs_high = np.concatenate([obs_high, np.full(n_w, 1.5)])
        obs_low, obs_high = self._hint_bounds(-obs_high, obs_high)
        self.observation_space = spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32)
        self.action_frame = cfg.action_frame
        # body frame: a normalized body-torque demand, allocated like the analytic baselines do
        # (minimum-norm u = −A⁺T, then each wheel clipped at its limit)
        self._action_map = self.model.allocation * params.max_wheel_torque_nm if self.action_frame == "body" else None
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3 if self._action_map is not None else n_w,), dtype=np.float32)
        # the true plant: the nominal one but for the offset torque (and a drawn inertia, at reset)
        self._true_params = cfg.true_params
        self._plant = self._true_params
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

    # ------------------------------------------------------------------ public interface
    @property
    def kernel_constants(self) -> np.ndarray:
        """The compiled step's constants (:func:`~attitude_envs.plants.gyrostat_kernels.pack_constants`:
        wheel axes, cost weights, limits, step sizes, offset torque, tilt stop); the same for
        every env built with the same keywords. Do not modify."""
        return self._constants

    @property
    def kernel_matrices(self) -> np.ndarray:
        """This episode's true inertia and inverse effective inertia as the compiled step's
        matrix column (:func:`~attitude_envs.plants.gyrostat_kernels.pack_matrices`, a view;
        it changes at reset with ``inertia_uncertainty``). Do not modify."""
        return self._mats[0, :, 0]

    @property
    def true_offset_torque_nm(self) -> np.ndarray:
        """The true plant's offset torque ``m g r_s`` (N·m, body axes; zeros: none), which
        ``true_offset_torque_nm=`` may set apart from the nominal model's (and flight
        conditions draw per episode). Truth, for batched envs and tools: controllers use
        ``model.params.offset_torque_nm``."""
        return self._plant.offset_torque_nm

    @property
    def reset_distribution(self) -> dict[str, Any]:
        """What :meth:`reset_episode` draws the episode from (copies, for tools that draw it
        themselves, e.g. :mod:`attitude_envs.jax`): ``initial_attitude`` and
        ``target_attitude`` (fixed quaternions, or None: drawn within ``initial_angle_deg``
        and ``target_angle_deg``, deg), ``initial_rate_rad_s`` (fixed, rad/s, or None: uniform
        in ± ``initial_rate_max_rad_s``) and ``inertia_uncertainty``
        (:class:`~attitude_envs.uncertainty.InertiaUncertainty`, frozen, or None)."""

        def copy(a):
            return None if a is None else a.copy()

        return {
            "initial_attitude": copy(self._initial_fixed),
            "initial_angle_deg": self._initial_angle,
            "target_attitude": copy(self._target_fixed),
            "target_angle_deg": self._target_angle,
            "initial_rate_rad_s": copy(self._rate_fixed),
            "initial_rate_max_rad_s": self._rate_max,
            "inertia_uncertainty": self._uncertainty,
        }

    @property
    def n_substeps(self) -> int:
        """RK4 sub-steps per control period (``control_dt_s / integrator_dt_s``)."""
        return self._substeps

    @property
    def state_row(self) -> np.ndarray:
        """The true physical state ``[q (4, scalar last), ω (3, rad/s), Ω (N, rad/s)]``, a
        read-only view (it follows the env: copy it to keep it)."""
        view = self._y.view()
        view.setflags(write=False)
        return view

    @property
    def target_attitude(self) -> np.ndarray:
        """This episode's target attitude (scalar-last quaternion), a read-only view."""
        view = self._target.view()
        view.setflags(write=False)
        return view

    @property
    def observation_size(self) -> int:
        """Entries of the observation the compiled step builds (the error state, plus wheel
        speeds with ``observe_wheel_speeds``; without the ``fault_hint`` flags)."""
        return self._out_obs.shape[1]

    def disturbance_stages(self, t_s: float) -> np.ndarray:
        """External torque (N·m, body axes) at the RK4 stage times (t, t + h/2, t + h) of each
        sub-step of the control period that starts at ``t_s``, shape (n_substeps, 3, 3).
        Returns the env's own buffer (overwritten by the next call); needs a disturbance."""
        h = self.integrator_dt_s
        torque_at = self._disturbance.torque_nm_at
        for j in range(self._substeps):
            t = t_s + j * h
            for k, dt in enumerate((0.0, 0.5 * h, h)):
                self._ext_stages[j, k] = torque_at(t + dt)
        return self._ext_stages

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.reset_episode(seed, options)
        self._measure()
        obs = self._observation()
        n_w = self._plant.n_wheels
        info = self._info(np.zeros(n_w), np.zeros(n_w), 0.0)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def reset_episode(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """Seed, draw and set the start state, target, plant, faults and disturbance: all of
        :meth:`reset` but the sensor reading, observation and info (the batched env's reset
        of a sub-env). ``options`` as for :meth:`reset`."""
        gym.Env.reset(self, seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        rng = self.np_random
        n_w = self._plant.n_wheels
        flight_rng = self._flight_rng(rng)
        if self._uncertainty is not None:
            self._plant = self._true_params.with_inertia(self._uncertainty.draw(self.model.params.inertia_kg_m2, rng))
            self._pack_matrices()
        if self._flight_plant is not None:
            self._draw_flight_plant(flight_rng)
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
        # the sensor layer spawns its own generator: rng's stream is unchanged
        self._reset_layers(rng, options, flight_rng)

    def _draw_flight_plant(self, rng: np.random.Generator) -> None:
        """This episode's true plant within the flight tolerances (from the flight generator):
        the inertia (:class:`~attitude_envs.uncertainty.InertiaUncertainty`, unless
        ``inertia_uncertainty`` is given), each wheel axis tilted by a uniform angle within
        the misalignment tolerance about a random perpendicular, and the offset torque plus a
        uniform error per axis."""
        tol = self._flight_plant
        base = self._plant if self._uncertainty is not None else self._true_params
        inertia = base.inertia_kg_m2
        if self._uncertainty is None:
            draw = InertiaUncertainty("random", None, tol["inertia_moment"], tol["inertia_axis_deg"])
            inertia = draw.draw(self.model.params.inertia_kg_m2, rng)
        axes = misaligned_axes(self.model.params.wheel_axes, tol["wheel_misalignment_deg"], rng)
        offset = self._true_params.offset_torque_nm
        if "offset_torque_nm" in tol:
            offset = offset + tol["offset_torque_nm"] * rng.uniform(-1.0, 1.0, 3)
        p = self._true_params
        self._plant = gyrostat.GyrostatParams(
            inertia, axes, p.wheel_inertia_kg_m2, p.max_wheel_torque_nm, p.max_wheel_speed_rad_s, offset
        )
        self._drawn.update(
            inertia_kg_m2=self._plant.inertia_kg_m2.copy(),
            wheel_axes=self._plant.wheel_axes.copy(),
            offset_torque_nm=self._plant.offset_torque_nm.copy(),
        )
        self._pack_kernel_arguments()

    def step(self, action):
        commanded = self.commanded_torques(validation.action(action, self.action_space.shape[0]))
        delivered = self._deliver(commanded, self._t, self._y[7:])
        if self._disturbance is not None:
            self._disturbance.advance(self.np_random, self.control_dt_s)
            self.disturbance_stages(self._t)
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
        terminated = bool(self._out_terminated[0])  # non-finite, tumbling, or beyond the tilt stop
        truncated = bool(self._out_truncated[0])
        finite = not terminated or (bool(np.isfinite(self._y).all()) and np.isfinite(cost))
        if terminated and finite:  # a limit crossed: the rest of the horizon is charged
            x = self.error_states(self._y.reshape(1, -1), self._target.reshape(1, -1))
            cost += self._termination_charge(x, self._t)
        if finite:
            self._measure()
            self._qe_w = float(self._out_qe_w[0])
        if not finite:
            obs = np.zeros(self.observation_space.shape, np.float32)
        elif self._sensor_layer.enabled or self.fault_hint:
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

    def error_states(self, states: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """The error states ``x`` (E × n, the cost's) of rows of physical states ``[q, ω, Ω]``
        (E × (7+N)) against rows of target quaternions (E × 4), as the compiled step forms them."""
        e = len(states)
        out = np.empty((self.model.cost.n, e))
        kernels.error_state_columns(
            np.ascontiguousarray(np.asarray(states, dtype=float).T),
            np.ascontiguousarray(np.asarray(targets, dtype=float).T),
            self._plant.wheel_inertia_kg_m2,
            self.model.include_wheel_momentum,
            out,
            np.empty(e),
        )
        return out.T.copy()

    def _pack_kernel_arguments(self) -> None:
        """The compiled step, its constants and the plant's matrices."""
        p = self._plant
        self._kernel = kernels.kernel_for(self.model, 1, p.offset_torque_nm)
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

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self._renderer is None:
            # heavy: the renderer loads matplotlib.pyplot, needed only when rendering
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
        if self._sensor_layer.enabled:
            truth = {"gyro": self._y[4:7], "star_tracker": self._y[:4], "tachometer": self._y[7:]}
            self._meas = self._sensor_layer.measure(truth, self._t)

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
        if self._sensor_layer.enabled:
            m = self._meas
            x = self.model.error_state(m["star_tracker"], m["gyro"], m["tachometer"], self._target)
            wheel = m["tachometer"]
        if self.observe_wheel_speeds:
            x = np.concatenate([x, wheel / self._plant.max_wheel_speed_rad_s])
        return self._with_hint(x, self._t)

    def _info(self, applied: np.ndarray, commanded: np.ndarray, cost: float) -> dict:
        # Info holds new arrays every call (gymnasium's checker): one copy of the state and
        # target, whose slices are views of it.
        y = np.concatenate([self._y, self._target])
        y.setflags(write=False)  # measured may share these views with the truth: nobody edits them
        n = y.shape[0] - 4
        state = {"attitude": y[:4], "rate_rad_s": y[4:7], "wheel_speed_rad_s": y[7:n], "target_attitude": y[n:]}
        truth = {
            "state": state,
            "applied": applied,
            "faults": self._fault_truth(self._t),
            "error_angle_deg": float(np.arccos(min(1.0, self._qe_w))) * _TWO_RAD_TO_DEG,
            "disturbance_torque_nm": np.zeros(3)
            if self._disturbance is None
            else np.array(self._disturbance.torque_nm_at(self._t)),
            "true_inertia_kg_m2": self._plant.inertia_kg_m2.copy(),
        }
        if self.tilt_limit_deg is not None:
            truth["tilt_limit_hit"] = bool(kernels.tilt_exceeded(self._y, self._constants))
        if not self._sensor_layer.enabled:  # the flight computer has the truth: the same dict
            return self._make_info(truth=truth, measured=dict(state), cost=cost, time_s=self._t, commanded=commanded)
        sensors = {k: v.copy() for k, v in self._meas.items()}
        measured = {  # the readings (the same arrays as info["sensors"]) and the commanded target
            "attitude": sensors["star_tracker"],
            "rate_rad_s": sensors["gyro"],
            "wheel_speed_rad_s": sensors["tachometer"],
            "target_attitude": state["target_attitude"],
        }
        return self._make_info(
            truth=truth, measured=measured, cost=cost, time_s=self._t, commanded=commanded, sensors=sensors
        )


def misaligned_axes(axes: np.ndarray, max_angle_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Unit wheel axes (3×N columns), each tilted by an angle uniform in [0, ``max_angle_deg``]
    about a uniformly random direction perpendicular to it (a mounting error)."""
    out = np.array(axes, dtype=float)
    for i in range(out.shape[1]):
        a = out[:, i]
        r = rng.normal(size=3)
        perp = r - (r @ a) * a
        perp /= np.linalg.norm(perp)
        angle = math.radians(max_angle_deg) * rng.uniform()
        out[:, i] = math.cos(angle) * a + math.sin(angle) * perp
    return out


def _divides(control_dt_s: float, integrator_dt_s: float) -> bool:
    try:
        substeps(control_dt_s, integrator_dt_s)
    except ValueError:
        return False
    return True


def _optional_quaternion(name: str, value) -> np.ndarray | None:
    return None if value is None else validation.unit_quaternion(name, value)


@dataclasses.dataclass(frozen=True)
class GyrostatConfig:
    """The validated keywords of a :class:`ReactionWheelEnv` (or an
    :class:`~attitude_envs.envs.air_bearing.AirBearingEnv` but its ``initial_euler_max_deg``)
    and what follows from them: the nominal ``model``, the RK4 ``n_substeps``, the start and
    target laws, the env's ``layers`` (:func:`~attitude_envs.envs.base.build_layers`), the
    flight conditions' plant ``flight_tolerances`` (None: none drawn) and the ``true_params``
    (the nominal plant with ``true_offset_torque_nm``)."""

    preset: str | None
    model: ReactionWheelModel
    control_dt_s: float
    integrator_dt_s: float
    n_substeps: int
    episode_duration_s: float
    target_attitude: np.ndarray | None
    initial_attitude: np.ndarray | None
    target_angle_deg: float
    initial_angle_deg: float
    initial_rate_rad_s: np.ndarray | None
    initial_rate_max_rad_s: float
    tilt_limit_deg: float | None
    inertia_uncertainty: InertiaUncertainty | None
    layers: Layers
    flight_tolerances: dict[str, float] | None
    termination_cost: str
    max_rate_rad_s: float
    observe_wheel_speeds: bool
    render_mode: str | None
    action_frame: str
    true_params: gyrostat.GyrostatParams


def configure(cls: type[ReactionWheelEnv], preset: str | None, given: Mapping[str, Any]) -> GyrostatConfig:
    """The keywords ``given`` (the constructor's ``locals()``, or the keywords passed; absent
    ones None) of env class ``cls`` resolved (``preset``, None: the class's default, then every
    keyword that is not None over the env's defaults) and validated, with the same
    ``ValueError`` for a bad one; the env and the JAX plant (:mod:`attitude_envs.jax.gyrostat`)
    are both built from it."""
    preset = cls.default_preset if preset is None else preset
    skip = ("self", "__class__", "preset", "render_mode")
    overrides = {k: v for k, v in given.items() if k not in skip}
    cfg = _DEFAULTS | presets.resolve(cls.env_name, preset, overrides, constructor_keywords(cls))
    missing = [k for k in _REQUIRED if cfg.get(k) is None]
    if missing:
        raise ValueError(f"{cls.env_name} preset {preset!r} sets no {missing[0]!r}; pass {missing[0]}=...")
    for key in ("control_dt_s", "integrator_dt_s"):  # checked before _divides reads them
        cfg[key] = validation.positive(key, cfg[key])
    if (
        given.get("control_dt_s") is not None
        and given.get("integrator_dt_s") is None
        and not _divides(cfg["control_dt_s"], cfg["integrator_dt_s"])
    ):
        cfg["integrator_dt_s"] = cfg["control_dt_s"]  # the preset's sub-step does not fit: one sub-step

    params = gyrostat.GyrostatParams(
        cfg["inertia_kg_m2"],
        cfg["wheel_axes"],
        cfg["wheel_inertia_kg_m2"],
        cfg["max_wheel_torque_nm"],
        cfg["max_wheel_speed_rad_s"],
        cfg.get("offset_torque_nm"),
    )
    control_dt = validation.positive("control_dt_s", cfg["control_dt_s"])
    integrator_dt = validation.positive("integrator_dt_s", cfg["integrator_dt_s"])
    n_sub = substeps(control_dt, integrator_dt)
    duration = validation.positive("episode_duration_s", cfg["episode_duration_s"])
    cost_in = validation.choice("cost_input", cfg["cost_input"], {"body", "wheel"})
    wmw = validation.nonnegative("wheel_momentum_weight", cfg["wheel_momentum_weight"])
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
    model = ReactionWheelModel(params, cost, cost_in, include_h, control_dt)

    target = _optional_quaternion("target_attitude", cfg.get("target_attitude"))
    initial = _optional_quaternion("initial_attitude", cfg.get("initial_attitude"))
    target_angle = validation.in_range("target_angle_deg", cfg["target_angle_deg"], 0.0, 180.0)
    initial_angle = validation.in_range("initial_angle_deg", cfg["initial_angle_deg"], 0.0, 180.0)
    rate = cfg.get("initial_rate_rad_s")
    rate = None if rate is None else validation.finite_array("initial_rate_rad_s", rate, (3,))
    rate_max = validation.nonnegative("initial_rate_max_rad_s", cfg["initial_rate_max_rad_s"])
    tilt = cfg.get("tilt_limit_deg")  # None: no stop
    if tilt is not None:
        tilt = validation.in_range("tilt_limit_deg", tilt, 0.0, 90.0, open_low=True, open_high=True)
    uncertainty = InertiaUncertainty.from_config(cfg.get("inertia_uncertainty"))
    channels = [
        Channel("gyro", 3, units="rad/s"),
        Channel("star_tracker", 4, "attitude", "rad"),
        Channel("tachometer", n_w, units="rad/s"),
    ]
    layers = build_layers(
        *cls._flight_table_key(preset),
        n_actuators=n_w,
        actuator_limits=params.max_wheel_torque_nm,
        channels=channels,
        faults=cfg.get("faults"),
        sensors=cfg.get("sensors"),
        fault_hint=cfg["fault_hint"],
        disturbance=cfg.get("disturbance"),
        conditions=cfg.get("conditions"),
        control_dt_s=control_dt,
    )
    tolerances = _flight_tolerances(layers.conditions, *cls._flight_table_key(preset))
    mode = validation.choice("termination_cost", cfg["termination_cost"], TERMINATION_COSTS)
    max_rate = validation.positive("max_rate_rad_s", cfg["max_rate_rad_s"])
    observe_speeds = validation.flag("observe_wheel_speeds", cfg["observe_wheel_speeds"])
    if observe_speeds and not np.isfinite(params.max_wheel_speed_rad_s):
        raise ValueError("observe_wheel_speeds needs a finite max_wheel_speed_rad_s to normalize by")
    render_mode = given.get("render_mode")
    if render_mode is not None:
        validation.choice("render_mode", render_mode, set(cls.metadata["render_modes"]))
    frame = validation.choice("action_frame", cfg["action_frame"], {"wheel", "body"})
    true_offset = cfg.get("true_offset_torque_nm")
    if true_offset is not None:
        true_offset = validation.finite_array("true_offset_torque_nm", true_offset, (3,))
    return GyrostatConfig(
        preset=preset,
        model=model,
        control_dt_s=control_dt,
        integrator_dt_s=integrator_dt,
        n_substeps=n_sub,
        episode_duration_s=duration,
        target_attitude=target,
        initial_attitude=initial,
        target_angle_deg=target_angle,
        initial_angle_deg=initial_angle,
        initial_rate_rad_s=rate,
        initial_rate_max_rad_s=rate_max,
        tilt_limit_deg=tilt,
        inertia_uncertainty=uncertainty,
        layers=layers,
        flight_tolerances=tolerances,
        termination_cost=mode,
        max_rate_rad_s=max_rate,
        observe_wheel_speeds=observe_speeds,
        render_mode=render_mode,
        action_frame=frame,
        true_params=params if true_offset is None else dataclasses.replace(params, offset_torque_nm=true_offset),
    )


def _flight_tolerances(conditions: Conditions, env_name: str, preset: str | None) -> dict[str, float] | None:
    """The flight conditions' plant tolerances times ``conditions["parameters"]``
    (None when no parameter is drawn): inertia moments (relative) and principal axes
    (deg), wheel misalignment (deg) and, on an air bearing, the offset torque (N·m per
    axis), from :func:`attitude_envs.presets.flight.table` of ``env_name`` and ``preset``."""
    scale = conditions.parameters
    if scale == 0:
        return None
    table = flight.table(env_name, preset)
    tol = {k: table.plant_value(k) * scale for k in ("inertia_moment", "inertia_axis_deg", "wheel_misalignment_deg")}
    if tol["inertia_moment"] >= 0.9:
        raise ValueError(
            f"conditions['parameters'] = {scale:g} scales the inertia tolerance to "
            f"{tol['inertia_moment']:.0%}; it must stay below 90 % (parameters < "
            f"{0.9 / table.plant_value('inertia_moment'):.3g})"
        )
    if "offset_torque_nm" in table.plant:
        tol["offset_torque_nm"] = table.plant_value("offset_torque_nm") * scale
    return tol
