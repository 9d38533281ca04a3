"""FuelSlosh-v0: planar spacecraft burn with two-pendulum fuel slosh (Navabi & Davoodi;
year not in our copy, ≥ 2012)."""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from attitude_envs import presets, validation
from attitude_envs.conditions import Conditions
from attitude_envs.cost import QuadraticCost
from attitude_envs.envs.base import TERMINATION_COSTS, AttitudeEnv, constructor_keywords
from attitude_envs.evaluation.success import FINAL_STATE_FRACTION
from attitude_envs.integrators import substeps
from attitude_envs.plants import slosh
from attitude_envs.plants import slosh_kernels as kernels
from attitude_envs.plants.slosh_model import REDUCED_INDEX, FuelSloshModel, reduced_state
from attitude_envs.presets.flight_slosh import MEASURED as _FLIGHT_MEASURED
from attitude_envs.presets.flight_slosh import state_sensor_config
from attitude_envs.presets.navabi_slosh import PAPER_INITIAL_STATE  # re-exported: the paper's start state
from attitude_envs.sensors import Channel

ENV = "FuelSlosh-v0"
_INITIAL_ORDER = (slosh.IVX, slosh.IVZ, slosh.ITH, slosh.IOM, slosh.IPSI1, slosh.IDPSI1, slosh.IPSI2, slosh.IDPSI2)
_OPTION_KEYS = {"state", "faults"}
# full-state indices of the observation [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2, v_x], or [v_z, θ, Ω, v_x]
OBS_INDEX = np.append(REDUCED_INDEX, slosh.IVX)
OBS_INDEX_NO_SLOSH = OBS_INDEX[[0, 1, 2, 7]]
OBS_INDEX.setflags(write=False)
OBS_INDEX_NO_SLOSH.setflags(write=False)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def flight_state_sensor(observe_slosh: bool, noise_scale: float) -> tuple[dict, np.ndarray]:
    """The flight ``state`` sensor over the observed entries (one value per entry, its noise,
    bias walk and bias spread times ``noise_scale``) and the observation positions it does not
    measure (the slosh states, reported as 0)."""
    entries = np.arange(8) if observe_slosh else np.array([0, 1, 2, 7])
    return state_sensor_config(entries, noise_scale), np.flatnonzero(~np.array(_FLIGHT_MEASURED)[entries])


def flight_plant_tolerances(table, scale: float) -> dict[str, float] | None:
    """The flight tolerances (relative) of the slosh masses and pendulum lengths in ``table``
    (:class:`~attitude_envs.presets.flight.FlightTable`) times the conditions' ``parameters``
    ``scale``; None when no parameter is drawn. A ``ValueError`` where a tolerance would reach
    90 %."""
    if scale == 0:
        return None
    tol = {k: table.plant_value(k) * scale for k in ("slosh_mass", "pendulum_length")}
    for key, value in tol.items():
        if value >= 0.9:
            raise ValueError(
                f"conditions['parameters'] = {scale:g} scales the {key} tolerance to {value:.0%}; it must "
                f"stay below 90 % (parameters < {0.9 / table.plant_value(key):.3g})"
            )
    return tol


class FuelSloshEnv(AttitudeEnv):
    """Stabilize pitch, transverse velocity and fuel slosh during a constant-thrust burn.

    **Description.** A spacecraft fires its main engine (constant thrust F, gimbal angle δ)
    in a plane; the propellant sloshes as two damped pendulums in the tank. The plant is
    the full 5-DOF nonlinear model of Navabi & Davoodi (eqs. 11–14, re-derived from their
    Lagrangian, eqs. 1–10; :mod:`attitude_envs.plants.slosh`): body translation v_x, v_z,
    pitch θ and the pendulum angles ψ1, ψ2, in mass-matrix form, integrated by fixed-step
    RK4 with ``integrator_dt_s`` sub-steps in one compiled call per step
    (:func:`attitude_envs.plants.slosh_kernels.control_step`). With the input held over a
    control period the plant is not stiff (its fastest modes are the slosh pendulums at
    ≈ 1–1.5 rad/s; RK4 at 0.05 s has |λh| ≤ 0.08, per-step error ~1e-8). The paper's
    continuous-time LQR has a closed-loop pole near −448 rad/s; a policy here is sampled
    every ``control_dt_s`` and must be designed for that period (the LQR baseline uses the
    exact zero-order-hold discretization; the reproduction simulates the continuous LQR
    with scipy's stiff LSODA).

    **Action space.** ``Box(-1, 1, (2,), float32)``, clipped: gimbal angle
    δ = a0 · ``max_gimbal_deg`` (rad), pitch moment M_c = a1 · ``max_moment_nm`` (N·m);
    the thrust is constant.

    **Observation space.** float32 ``[v_z (m/s), θ (rad), Ω (rad/s), ψ1 (rad), ψ̇1 (rad/s),
    ψ2 (rad), ψ̇2 (rad/s), v_x (m/s)]``; with ``observe_slosh=False`` only ``[v_z, θ, Ω,
    v_x]``; with ``fault_hint`` 3 flags in [0, 1] appended (gimbal, moment, state sensor).
    Bounds: speeds ±1e4 m/s, angles and rates twice their termination limits, slosh rates
    ±50 rad/s. With sensors the observation is measured (see below). The step that crosses a
    limit observes its measurement clipped to the bounds: FuelSlosh-v1's 0.25 s decision
    carries the pitch rate past twice its limit on about a third of random-action episodes
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`; ``info["truth"]`` holds the
    true state). The speeds' bound is not a limit: the presets' burns reach about 6.0e3 m/s at
    the end of v0's 1500 s (a_x = F/m ≈ 2 m/s²); a burn much longer than that
    (``episode_duration_s`` beyond about 3,500 s) would pass it.

    **Reward.** ``−∫ (xᵀQx + u_cᵀRu_c) dt`` over the step (RK4 of the augmented state),
    with x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2] and u_c the new inputs [a_z, Ω̇] the plant
    realized; Q, R default to the paper's LQR weights (eqs. 30–31).

    **Starting state.** The paper's (Table 4): v_x 3000 m/s, v_z 100 m/s, θ 2°, ψ1 30°,
    ψ2 −30°, rates 0 (``initial_state``); ``randomize_initial_state`` draws v_z, θ, ψ1 and
    ψ2 uniformly within ± the magnitudes of Table 4; ``reset(options={"state": 8 values,
    "faults": [...]})`` pins the start state (order of ``initial_state``) and the
    episode's faults.

    **Episode end.** Terminated on a non-finite state (the observation is then zeros),
    |ψ_i| > ``max_slosh_angle_deg``, |θ| > ``max_pitch_angle_deg`` or |Ω| >
    ``max_pitch_rate_rad_s``; truncated when the simulated time reaches
    ``episode_duration_s``.
    A step that crosses a limit (with a finite state) is charged, on top of its running
    cost, the terminal error state's running cost held over the rest of the episode,
    ``(episode_duration_s − t) xᵀQx`` (``termination_cost="hold"``; ``"none"``: nothing
    more), so ending an episode early never lowers J.

    **Arguments** (None takes the preset's value):

    ==========================  ===============  ===========  ========  ==========================================
    name                        type             default      unit      description
    ==========================  ===============  ===========  ========  ==========================================
    ``preset``                  str              navabi-fill  —         parameter set (see Presets); None: none,
                                                 -i                     every preset keyword must then be given
    ``params``                  SloshParams      preset       SI        the whole plant (Table 3 values)
    ``max_gimbal_deg``          float in (0,90]  30           deg       gimbal limit (assumed)
    ``max_moment_nm``           float > 0        2000         N·m       pitch-moment limit (assumed)
    ``control_dt_s``            float > 0        0.1          s         control period (zero-order hold)
    ``integrator_dt_s``         float > 0        0.05         s         RK4 sub-step (must divide control_dt_s)
    ``episode_duration_s``      float > 0        1500         s         time limit
    ``Q``, ``R``                7×7, 2×2 PSD     eqs. 30–31   —         cost weights on x and [a_z, Ω̇]
    ``observe_slosh``           bool             True         —         observe ψ_i, ψ̇_i
    ``initial_state``           8 floats         Table 4      m/s, rad  [v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]
    ``randomize_initial_state`` bool             False        —         draw the start (see Starting state)
    ``max_slosh_angle_deg``     float > 0        90           deg       termination limit on |ψ_i|
    ``max_pitch_rate_rad_s``    float > 0        0.5          rad/s     termination limit on |Ω|
    ``max_pitch_angle_deg``     float > 0        90           deg       termination limit on |θ|
    ``design_v_x_m_s``          float            3000         m/s       axial speed of the nominal linear model
    ``faults``                  list of dicts    None         —         :mod:`attitude_envs.faults`
    ``sensors``                 dict             None         —         ``{"state": {...}}``, :mod:`attitude_envs.sensors`
    ``fault_hint``              bool             False        —         append the active-fault flags
    ``termination_cost``        str              "hold"       —         ``"hold"``: charge a limit crossing (see
                                                                        Episode end); ``"episode"`` (v1): ``T·xᵀQx``; ``"none"``: none
    ``fill_preset``             str              None         —         deprecated: ``preset="i"`` … ``"iv"``
    ``conditions``              str or dict      "lab"        —         ``"lab"``, ``"flight"`` or features
                                                                        (:mod:`attitude_envs.conditions`; see
                                                                        Flight conditions)
    ==========================  ===============  ===========  ========  ==========================================

    **Presets** (:mod:`attitude_envs.presets.navabi_slosh`): ``navabi-fill-i`` (default,
    alias ``"i"``) … ``navabi-fill-iv`` (``"iv"``): Table 3 of the paper under the four
    readings of its five tank lengths, whose symbols our copy lost; everything else is the
    same. ``presets.get("FuelSlosh-v0", name).source(key)`` tells where each value comes from.

    **Faults and sensors.** Actuator 0 is the gimbal angle (rad), actuator 1 the pitch
    moment (N·m); ``"target": "sensor"`` faults hit the ``state`` sensor, which measures
    the observation vector (without the flags).

    **Flight conditions** (``conditions=``, :mod:`attitude_envs.conditions`; values and
    sources in :mod:`attitude_envs.presets.flight_slosh`). ``"lab"`` (default) is the
    paper's world, bit for bit. ``"flight"``:

    * *sensors*: the ``state`` sensor is an IMU navigation solution, one noise, bias walk and
      bias spread per entry (STIM300 gyro on Ω, a star-tracker-grade θ, navigation velocities).
      **The slosh states are not measured**: the observation's ψ1, ψ̇1, ψ2, ψ̇2 entries are
      0 (the observation keeps its shape, so lab policies and controllers run; an estimator
      must reconstruct the slosh from the rigid-body response; ``observe_slosh=False`` drops
      the entries), ``info["measured"]`` has no ``slosh_angle_rad``/``slosh_rate_rad_s`` and
      :attr:`measured_entries` marks them False (an estimator drops them from its model).
      This holds with the flight sensors; an explicit ``sensors=`` replaces them, and then
      the slosh entries are measured as that dict says;
    * *actuators*: the gimbal slews at most 10 °/s (as a fraction of ``max_gimbal_deg``: 1/3
      of the 30° limit per second) behind a 0.05 s first-order lag; the pitch moment is ideal;
    * *delay*: one control period (a command acts from the next step; zeros before);
    * *parameters*: per episode, the true slosh masses and pendulum lengths are drawn
      uniformly within ±15 % (each pendulum, each quantity; the fixed propellant mass takes
      the slosh mass change, so the total mass is the nominal one) and each actuator's scale
      factor within ±5 %, from a generator spawned at reset: starts equal the lab's of the
      same seed. :meth:`~attitude_envs.envs.base.AttitudeEnv.drawn_parameters` (and
      ``info["truth"]["drawn_parameters"]``) holds them; ``model`` stays the nominal plant.

    The batched env (``vector_entry_point``) runs the lab only; use
    ``gymnasium.vector.SyncVectorEnv`` for flight conditions.

    **Info** (:mod:`attitude_envs.info`). ``truth``: ``state`` (``position_m`` [X, Z] of the
    tank centre, ``theta_rad``, ``slosh_angle_rad`` [ψ1, ψ2], ``v_x_m_s``, ``v_z_m_s``,
    ``pitch_rate_rad_s``, ``slosh_rate_rad_s`` [ψ̇1, ψ̇2]), ``full_state`` (the 10 entries
    of :mod:`attitude_envs.plants.slosh`), ``x`` (the true reduced state, float64),
    ``applied`` ([δ rad, M_c N·m] after clipping and faults), ``new_inputs`` (step-mean
    [a_z m/s², Ω̇ rad/s²] the true plant realized under the applied inputs; zeros at reset),
    ``faults``, ``sensor_bias`` (with sensors). ``measured``: with sensors off, the truth's
    ``state`` (a copy of the dict); with sensors on, only what the ``state`` sensor measures: ``theta_rad``,
    ``v_x_m_s``, ``v_z_m_s``, ``pitch_rate_rad_s`` and, with ``observe_slosh``,
    ``slosh_angle_rad`` and ``slosh_rate_rad_s`` (``position_m`` is never measured; after
    a non-finite step every entry is NaN). Top level: ``cost``, ``time_s``, ``commanded``
    ([δ, M_c] the action asked for, before clipping) and, with sensors, ``sensors``
    (``{"state": reading}``).

    ``env.unwrapped.model`` is the nominal :class:`FuelSloshModel` (reduced model,
    linearizations, input inversion). The batched env and tools use the public members
    :attr:`state`, :attr:`observation_index`, :attr:`actuator_limits`,
    :attr:`kernel_constants`, :meth:`batch_termination` and the base's ``fault_layer``.

    **Success** (:mod:`attitude_envs.evaluation.success`): ``success_metric`` is
    ``FINAL_STATE_FRACTION``, the norm of the true reduced state ``truth["x"]`` at the end
    over its norm at the start (default threshold 0.1).

    **Version history.** v1 (``attitude_envs/FuelSlosh-v1``, 2026-11-27): the learning task — decisions every 0.25 s over the same 0.05 s RK4 physics, 100 s episodes from random starts within the paper's magnitudes (``randomize_initial_state``; 400 decisions) and a limit crossing charged ``T·xᵀQx`` (``termination_cost="episode"``); the plant and J are v0's. v0: a limit crossing charged the terminal running cost over the rest of the episode (``termination_cost``, 2026-11); the full 5-DOF plant with one compiled RK4 step; presets
    ``navabi-fill-i`` … ``-iv`` replace ``fill_preset`` (kept, deprecated); infos follow
    the truth/measured contract; ``new_inputs`` moved from the top level to
    ``truth["new_inputs"]`` (it is truth-derived: it reveals actuator faults).
    """

    env_name = ENV
    default_preset = "navabi-fill-i"
    success_metric = FINAL_STATE_FRACTION
    metadata = {"render_modes": []}

    def __init__(
        self,
        preset: str | None = "navabi-fill-i",
        params: slosh.SloshParams | None = None,
        max_gimbal_deg: float | None = None,
        max_moment_nm: float | None = None,
        control_dt_s: float | None = None,
        integrator_dt_s: float | None = None,
        episode_duration_s: float | None = None,
        Q=None,
        R=None,
        observe_slosh: bool = True,
        initial_state=None,
        randomize_initial_state: bool = False,
        max_slosh_angle_deg: float | None = None,
        max_pitch_rate_rad_s: float | None = None,
        max_pitch_angle_deg: float | None = None,
        design_v_x_m_s: float | None = None,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        termination_cost: str = "hold",
        fill_preset: str | None = None,
        conditions=None,
        render_mode: str | None = None,
    ) -> None:
        cfg = configure(locals())
        self.preset = cfg.preset
        self.render_mode = None
        self.control_dt_s, self.integrator_dt_s = cfg.control_dt_s, cfg.integrator_dt_s
        self._substeps = cfg.n_substeps
        self.episode_duration_s = cfg.episode_duration_s
        self.model = cfg.model
        self._init_termination_cost(cfg.termination_cost, cfg.model.cost.Q, self.episode_duration_s)
        self.observe_slosh = cfg.observe_slosh
        self._initial = cfg.initial_state
        self.randomize_initial_state = cfg.randomize_initial_state
        self.max_slosh_angle_rad = cfg.max_slosh_angle_rad
        self.max_pitch_rate_rad_s = cfg.max_pitch_rate_rad_s
        self.max_pitch_angle_rad = cfg.max_pitch_angle_rad
        # Bounds: speeds stay below |v(0)| + a_x t ≤ 1e4 m/s on any sensible burn; angles and
        # rates within twice their termination limits; slosh rates within 50 rad/s.
        high = np.array([1e4, 2 * self.max_pitch_angle_rad, 2 * self.max_pitch_rate_rad_s])
        slosh_high = np.array([2 * self.max_slosh_angle_rad, 50.0] * 2)
        high = np.concatenate([high, slosh_high, [1e4]]) if self.observe_slosh else np.append(high, 1e4)
        self._limits = _read_only(np.array([self.model.max_gimbal_rad, self.model.max_moment_nm]))
        cond = cfg.conditions
        #: observation entries the sensors do not measure (reported as 0): the slosh states
        #: under the flight sensors
        self._unmeasured = np.zeros(0, dtype=int)
        if sensors is None and cond.sensors > 0:  # the flight sensors, one value per observed entry
            config, self._unmeasured = flight_state_sensor(self.observe_slosh, cond.sensors)
            sensors = {"state": config}
        # actuator 0: gimbal angle (rad), actuator 1: pitch moment (N·m)
        self._init_layers(
            n_actuators=2,
            actuator_limits=self._limits,
            channels=[Channel("state", len(high))],
            faults=faults,
            sensors=sensors,
            fault_hint=fault_hint,
            conditions=cond,
            control_dt_s=self.control_dt_s,
        )
        self._flight_plant = flight_plant_tolerances(self.flight_table, self.conditions.parameters)
        low, high = self._hint_bounds(-high, high)
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._y = np.zeros(slosh.N_STATE)
        self._t = 0.0
        self._steps = 0
        self._sensing = self.sensor_layer.enabled
        self._obs_index = OBS_INDEX if self.observe_slosh else OBS_INDEX_NO_SLOSH
        self._work = np.empty(kernels.WORK_SIZE)
        self._constants = self._step_constants(self.model.params)
        self._nominal_constants = self._constants

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        flight_rng = self._flight_rng(self.np_random)  # spawned: the start is the lab's of this seed
        if self._flight_plant is not None:
            self._draw_flight_plant(flight_rng)
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
        self._reset_layers(self.np_random, options, flight_rng)
        self._sensing = self.sensor_layer.enabled  # fixed for the episode
        zero = np.zeros(2)
        measured = self._measure()
        return self._with_hint(measured, self._t), self._info(zero, zero, zero, 0.0, measured)

    def step(self, action):
        a0, a1 = validation.action(action, 2).tolist()  # Python floats: cheaper than tiny arrays
        gimbal, moment = self.model.max_gimbal_rad, self.model.max_moment_nm
        commanded = np.array([a0 * gimbal, a1 * moment])
        applied = np.array([min(max(a0, -1.0), 1.0) * gimbal, min(max(a1, -1.0), 1.0) * moment])
        applied = self._deliver(applied, self._t)  # faults; in flight the delay, dynamics and gains
        new_inputs = np.empty(2)  # step-mean [a_z, Ω̇]
        cost = kernels.control_step(self._y, applied, self._constants, new_inputs, self._work)
        self._steps += 1
        self._t = self._steps * self.control_dt_s  # from the step count: no drift of onsets/time limit
        y = self._y.tolist()
        a_z, dom = new_inputs.tolist()
        # a finite sum proves every entry finite; only a non-finite one needs the exact check
        finite = math.isfinite(cost + sum(y) + a_z + dom) or (
            math.isfinite(cost) and all(map(math.isfinite, y)) and math.isfinite(a_z) and math.isfinite(dom)
        )
        terminated = not finite or kernels.limit_crossed(
            self._y, self.max_slosh_angle_rad, self.max_pitch_rate_rad_s, self.max_pitch_angle_rad
        )
        if terminated and finite:  # a limit crossed: the rest of the horizon is charged
            cost += self._termination_charge(reduced_state(self._y), self._t)
        truncated = bool(self._t >= self.episode_duration_s - 1e-9 * self.control_dt_s) and not terminated
        if finite:
            measured = self._measure()
            obs = self._with_hint(measured, self._t)
        else:  # no sensor sample of a diverged state
            measured = None
            obs = np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, self._info(applied, commanded, new_inputs, cost, measured)

    # ------------------------------------------------------------------ public interface
    @property
    def state(self) -> np.ndarray:
        """The full true state ``y`` (10 entries, see :mod:`attitude_envs.plants.slosh`), a copy."""
        return self._y.copy()

    @property
    def initial_state(self) -> np.ndarray:
        """The fixed start state ``[v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` (m/s, rad, rad/s; the
        ``initial_state`` keyword, order of ``reset(options={"state": ...})``), a copy."""
        return self._initial.copy()

    @property
    def observation_index(self) -> np.ndarray:
        """Full-state indices of the observation's entries (before any fault flags), read-only."""
        return self._obs_index

    @property
    def measured_entries(self) -> np.ndarray:
        """One bool per observation entry (before any fault flags): whether the sensors
        measure it. All True but under the flight sensors, whose slosh entries (ψ1, ψ̇1, ψ2,
        ψ̇2) are not measured and read 0: an estimator drops them from its measurement model
        (a copy)."""
        out = np.ones(len(self._obs_index), dtype=bool)
        out[self._unmeasured] = False
        return out

    @property
    def actuator_limits(self) -> np.ndarray:
        """``[max gimbal angle (rad), max pitch moment (N·m)]``, read-only."""
        return self._limits

    @property
    def kernel_constants(self) -> np.ndarray:
        """The constants of :func:`~attitude_envs.plants.slosh_kernels.control_step` (plant,
        sub-step, cost weights; the same for every env built with the same keywords, except
        under flight conditions with ``parameters``: this episode's drawn true plant), read-only."""
        return self._constants

    @property
    def nominal_kernel_constants(self) -> np.ndarray:
        """:attr:`kernel_constants` of the nominal plant ``model.params`` (what a model-based
        controller may use; equal to :attr:`kernel_constants` unless flight conditions draw the
        true plant), read-only."""
        return self._nominal_constants

    def batch_termination(self, states: np.ndarray) -> np.ndarray:
        """The limits :meth:`step` terminates on (slosh angle, pitch rate, pitch angle) for
        rows of full states ``y`` (E × 10); the batched env's hook (it checks finiteness)."""
        states = np.asarray(states, dtype=float)
        out = np.empty(states.shape[0], dtype=bool)
        kernels.limits_crossed(
            states, self.max_slosh_angle_rad, self.max_pitch_rate_rad_s, self.max_pitch_angle_rad, out
        )
        return out

    # ------------------------------------------------------------------ internals
    def _step_constants(self, params: slosh.SloshParams) -> np.ndarray:
        """The compiled step's constants for the plant ``params`` (read-only)."""
        return _read_only(
            kernels.step_constants(
                params.packed,
                self.integrator_dt_s,
                self._substeps,
                self.control_dt_s,
                self.model.cost.Q,
                self.model.cost.R,
            )
        )

    def _draw_flight_plant(self, rng: np.random.Generator) -> None:
        """This episode's true plant (from the flight generator): each pendulum's slosh mass
        and length times ``1 + tol · U(−1, 1)``; the fixed propellant mass takes the change of
        the slosh masses (the propellant load is known, its split into sloshing and fixed
        parts is not). Recorded in ``_drawn``; the compiled step's constants follow."""
        tol = self._flight_plant
        nominal = self.model.params
        masses = np.asarray(nominal.slosh_mass_kg, dtype=float) * (1.0 + tol["slosh_mass"] * rng.uniform(-1, 1, 2))
        lengths = np.asarray(nominal.length_m, dtype=float) * (1.0 + tol["pendulum_length"] * rng.uniform(-1, 1, 2))
        fuel = max(0.0, nominal.fuel_mass_kg - float(masses.sum() - np.sum(nominal.slosh_mass_kg)))
        true = dataclasses.replace(
            nominal, slosh_mass_kg=tuple(masses.tolist()), length_m=tuple(lengths.tolist()), fuel_mass_kg=fuel
        )
        self._constants = self._step_constants(true)
        self._drawn.update(slosh_mass_kg=masses, length_m=lengths, fuel_mass_kg=fuel)

    def _measure(self) -> np.ndarray:
        """The observation's state entries, measured by the ``state`` sensor when sensors are
        on (entries the sensors do not measure, the slosh states in flight, read 0)."""
        obs = self._y[self._obs_index]
        if self._sensing:
            obs = self.sensor_layer.measure({"state": obs}, self._t)["state"]
            if self._unmeasured.size:
                obs[self._unmeasured] = 0.0
        return obs

    def _measured_state(self, reading: np.ndarray) -> dict[str, Any]:
        """``info["measured"]`` from the ``state`` sensor's reading."""
        m = reading.tolist()
        out: dict[str, Any] = {"theta_rad": m[1], "v_x_m_s": m[-1], "v_z_m_s": m[0], "pitch_rate_rad_s": m[2]}
        if self.observe_slosh and not self._unmeasured.size:
            out["slosh_angle_rad"] = reading[[3, 5]]
            out["slosh_rate_rad_s"] = reading[[4, 6]]
        return out

    def _info(self, applied, commanded, new_inputs, cost: float, reading: np.ndarray | None) -> dict:
        # New arrays every call (gymnasium's checker): one copy of the state, whose slices
        # are views of it.
        y = self._y.copy()
        th, vx, vz, om = y[[slosh.ITH, slosh.IVX, slosh.IVZ, slosh.IOM]].tolist()
        state = {
            "position_m": y[slosh.IX : slosh.IZ + 1],
            "theta_rad": th,
            "slosh_angle_rad": y[slosh.IPSI1 : slosh.IPSI2 + 1],
            "v_x_m_s": vx,
            "v_z_m_s": vz,
            "pitch_rate_rad_s": om,
            "slosh_rate_rad_s": y[slosh.IDPSI1 :],
        }
        truth = {
            "state": state,
            "full_state": y,
            "x": reduced_state(y),
            "applied": applied,
            "new_inputs": new_inputs,
            "faults": self._fault_truth(self._t),
        }
        if not self._sensing:
            return self._make_info(
                truth=truth,
                measured=dict(state),
                cost=cost,
                time_s=self._t,
                commanded=commanded,
            )
        if reading is None:  # no sample of a diverged state
            reading = np.full(len(self._obs_index), np.nan)
        return self._make_info(
            truth=truth,
            measured=self._measured_state(reading),
            cost=cost,
            time_s=self._t,
            commanded=commanded,
            sensors={"state": reading},
        )


def _preset_names() -> str:
    return ", ".join(p.name for p in presets.for_env(ENV))


def _preset_of_fill(preset: str | None, fill_preset: str) -> str:
    """The preset the deprecated ``fill_preset`` selects (a conflicting ``preset`` raises)."""
    warnings.warn(
        f"{ENV}: fill_preset is deprecated; pass preset='navabi-fill-{fill_preset}' (or its alias "
        f"preset={fill_preset!r}) instead",
        DeprecationWarning,
        stacklevel=3,
    )
    validation.choice("fill_preset", fill_preset, set(slosh.FILL_PRESETS))
    name = f"navabi-fill-{fill_preset}"
    if preset not in (None, FuelSloshEnv.default_preset) and presets.get(ENV, preset).name != name:
        raise ValueError(f"pass preset or the deprecated fill_preset, not both (got {preset!r} and {fill_preset!r})")
    return name


@dataclasses.dataclass(frozen=True)
class FuelSloshConfig:
    """The validated keywords of :class:`FuelSloshEnv` and what follows from them (the
    nominal ``model``, the RK4 ``n_substeps`` per decision, the limits in rad);
    ``faults``, ``sensors`` and ``fault_hint`` as given (the env's fault and sensor layers
    validate them)."""

    preset: str | None
    model: FuelSloshModel
    control_dt_s: float
    integrator_dt_s: float
    n_substeps: int
    episode_duration_s: float
    termination_cost: str
    observe_slosh: bool
    initial_state: np.ndarray
    randomize_initial_state: bool
    max_slosh_angle_rad: float
    max_pitch_rate_rad_s: float
    max_pitch_angle_rad: float
    conditions: Conditions
    faults: list[dict] | None
    sensors: dict | None
    fault_hint: bool


def configure(given: Mapping[str, Any]) -> FuelSloshConfig:
    """:class:`FuelSloshEnv`'s keywords ``given`` (every one: the constructor's ``locals()``)
    resolved (preset, then the keywords given) and validated, with the same ``ValueError`` for
    a bad one; the env and the JAX plant (:mod:`attitude_envs.jax.fuel_slosh`) are both built
    from it."""
    preset = given["preset"]
    if given["fill_preset"] is not None:
        preset = _preset_of_fill(preset, given["fill_preset"])
    skip = ("self", "__class__", "preset", "render_mode", "fill_preset")
    overrides = {k: v for k, v in given.items() if k not in skip}
    cfg = presets.resolve(ENV, preset, overrides, constructor_keywords(FuelSloshEnv))
    missing = sorted(set(presets.get(ENV).values) - set(cfg))
    if missing:
        raise ValueError(f"{ENV} with preset=None needs {missing}; or pass a preset ({_preset_names()})")
    params = cfg["params"]
    if not isinstance(params, slosh.SloshParams):
        raise ValueError(f"params must be a SloshParams, got {type(params).__name__}")
    gimbal = validation.in_range("max_gimbal_deg", cfg["max_gimbal_deg"], 0.0, 90.0, open_low=True)
    if given["render_mode"] is not None:
        raise ValueError(f"render_mode must be None for {ENV}, got {given['render_mode']!r}")
    dt = validation.positive("control_dt_s", cfg["control_dt_s"])
    h = validation.positive("integrator_dt_s", cfg["integrator_dt_s"])
    n_sub = substeps(dt, h)
    duration = validation.positive("episode_duration_s", cfg["episode_duration_s"])
    cost = QuadraticCost.build(cfg["Q"], cfg["R"], 7, 2)
    model = FuelSloshModel(
        params,
        cost,
        math.radians(gimbal),
        validation.positive("max_moment_nm", cfg["max_moment_nm"]),
        validation.in_range("design_v_x_m_s", cfg["design_v_x_m_s"]),
        dt,
    )
    mode = validation.choice("termination_cost", given["termination_cost"], TERMINATION_COSTS)
    return FuelSloshConfig(
        preset=preset,
        model=model,
        control_dt_s=dt,
        integrator_dt_s=h,
        n_substeps=n_sub,
        episode_duration_s=duration,
        termination_cost=mode,
        observe_slosh=validation.flag("observe_slosh", given["observe_slosh"]),
        initial_state=validation.finite_array("initial_state", cfg["initial_state"], (8,)),
        randomize_initial_state=validation.flag("randomize_initial_state", given["randomize_initial_state"]),
        max_slosh_angle_rad=math.radians(validation.positive("max_slosh_angle_deg", cfg["max_slosh_angle_deg"])),
        max_pitch_rate_rad_s=validation.positive("max_pitch_rate_rad_s", cfg["max_pitch_rate_rad_s"]),
        max_pitch_angle_rad=math.radians(validation.positive("max_pitch_angle_deg", cfg["max_pitch_angle_deg"])),
        conditions=Conditions.from_config(given["conditions"]),
        faults=given["faults"],
        sensors=given["sensors"],
        fault_hint=given["fault_hint"],
    )
