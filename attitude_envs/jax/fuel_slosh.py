"""FuelSlosh-v0/-v1 in JAX: the planar spacecraft burn with two-pendulum fuel slosh of
:class:`attitude_envs.envs.fuel_slosh.FuelSloshEnv` (Navabi & Davoodi; year not in our copy,
≥ 2012), one decision per step.

The plant is the full 5-DOF nonlinear model in mass-matrix form (the paper's eqs. 11–14,
re-derived from its Lagrangian, eqs. 1–10; :mod:`attitude_envs.plants.slosh`),
``M(ψ) ṡ = f(s, ψ) + G(δ, M_c)`` with ``s = [v_x, v_z, Ω, ψ̇1, ψ̇2]``, traced from the plant's
one definition (:mod:`attitude_envs.plants.slosh_definition`: the translational block
eliminated in closed form, an unrolled LDLᵀ of the 3×3 Schur complement), which the numba
kernel compiles. A decision holds ``[δ (rad), M_c (N·m)]`` over ``n_substeps`` classical RK4
sub-steps of ``integrator_dt_s`` s, with the stage cost ``xᵀQx + u_cᵀRu_c`` (Q, R of the
paper's eqs. 30–31 by default) and the new inputs ``u_c = [a_z, Ω̇]`` integrated as three
extra states (:func:`attitude_envs.plants.slosh_kernels.control_step`), in the kernel's
order of operations: under ``jax.enable_x64`` a step matches the numba env's to rounding
(XLA's CPU backend fuses ``a·b + c`` into FMAs where numba rounds the product, so the two
differ by ulps; over a 100 s open-loop episode the state agrees to ~1e-13–1e-12, the
cost to ~1e-12 relative: tests/test_jax_fuel_slosh.py). A non-finite action (the numba env
raises) gives a non-finite step, which terminates.

Time is counted as the numba env counts it: ``state.time`` in decisions, ``time_s = time ·
control_dt_s``; the actuator faults are applied at the decision's start time and held over
it; a limit crossing is charged :func:`attitude_envs.jax.cost.termination_charge` with the
horizon ``episode_duration_s`` and the elapsed time at the step's end.

Full state ``y`` (10, SI): ``[X, Z, θ, ψ1, ψ2, v_x, v_z, Ω, ψ̇1, ψ̇2]`` (m, rad, m/s,
rad/s; :mod:`attitude_envs.plants.slosh`); reduced (error) state
``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]``.

Flight conditions (``conditions=``, :mod:`attitude_envs.conditions`; the values of
:mod:`attitude_envs.presets.flight_slosh`): the delay and the actuator chain (the gimbal's rate
limit and first-order lag, each actuator's scale factor) act on ``[δ, M_c]`` around the faults
as :meth:`attitude_envs.actuator_dynamics.ActuatorChain.deliver` (:mod:`attitude_envs.jax.actuators`;
its runtime state in ``EnvState.flight``); ``reset_env`` draws the episode's true slosh masses
and pendulum lengths (the fixed propellant mass taking the slosh mass change) and the gains
from its key folded with :data:`~attitude_envs.jax.actuators.FLIGHT_STREAM`, by the numba
env's law (not its draws; the start and the faults are the lab episode's of the same key), or
takes a numba episode's (:func:`with_drawn_parameters`); the cost weights, limits and the
actuator limits stay nominal, as in the numba env. The ``state`` sensor (the IMU navigation
solution of the flight table, one noise, bias walk and bias spread per observed entry, or an
explicit ``sensors=`` with the conditions' sensors on) samples at reset and at the end of each
finite step from keys folded with :data:`~attitude_envs.jax.sensors.SENSOR_STREAM` (the numba
sensor layer's law, not its draws); the observation is then the measurement, with the slosh
entries the flight sensors do not measure (``unmeasured``) reading 0, as the numba env's;
``info``, the cost and the limits stay the truth's. The lab's compiled program is unchanged
(``flight`` and ``sensors`` None in the env, its params and state).

Modeled: every keyword of the numba env (``preset``/``params``, limits, periods, ``Q``,
``R``, ``observe_slosh``, ``initial_state``, ``randomize_initial_state``, the termination
limits and ``termination_cost``, actuator ``faults`` with per-episode draws, ``fault_hint``,
``conditions``) except ``sensors`` in the lab (sensors only as flight conditions' sensors) and
sensor faults outside flight conditions' sensors
(:func:`attitude_envs.jax.sensors.channel_faults`; the others are modeled, draws and ``fault_hint`` flags included), for which :func:`from_keywords` raises a ``ValueError`` naming them.
``design_v_x_m_s`` only sets the nominal linear model (``numba_env.model``), not the step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.envs.base import Layers, check_keywords, keyword_defaults
from attitude_envs.envs.fuel_slosh import (
    OBS_INDEX,
    OBS_INDEX_NO_SLOSH,
    FuelSloshConfig,
    configure,
    flight_plant_tolerances,
    flight_state_sensor,
)
from attitude_envs.envs.fuel_slosh import FuelSloshEnv as NumbaFuelSloshEnv
from attitude_envs.jax import actuators as jact
from attitude_envs.jax import cost as jcost
from attitude_envs.jax import faults as jfaults
from attitude_envs.jax import sensors as jsens
from attitude_envs.jax.environment import (
    Environment,
    check_state_from,
    drawn_arrays,
    episode_decisions,
    preset_defaults,
)
from attitude_envs.jax.make import state_layers
from attitude_envs.jax.ops import JAX
from attitude_envs.jax.spaces import Box
from attitude_envs.plants import slosh
from attitude_envs.plants.slosh_definition import define
from attitude_envs.plants.slosh_model import REDUCED_INDEX
from attitude_envs.presets.flight import table as flight_table
from attitude_envs.presets.navabi_slosh import PAPER_INITIAL_STATE

#: full-state indices of the start state ``[v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]``
INITIAL_ORDER = (slosh.IVX, slosh.IVZ, slosh.ITH, slosh.IOM, slosh.IPSI1, slosh.IDPSI1, slosh.IPSI2, slosh.IDPSI2)
#: entries of the start state ``randomize_initial_state`` draws: v_z, θ, ψ1, ψ2
RANDOM_START = (1, 2, 4, 6)
_REDUCED = tuple(int(i) for i in REDUCED_INDEX)
N_ACTUATORS = 2  # gimbal angle δ (rad), pitch moment M_c (N·m)
_PLANT = define(JAX)


@dataclass(frozen=True)
class FlightLayout:
    """What the flight conditions switch on in the compiled program (static): the
    ``actuators`` chain's layout (:class:`attitude_envs.jax.actuators.ActuatorLayout`: delay,
    rate limit, lag, gains) and ``draw_plant`` (the slosh masses and lengths drawn per episode)."""

    actuators: jact.ActuatorLayout
    draw_plant: bool = False


@struct.dataclass
class FlightParams:
    """The flight conditions' numbers: the ``actuators`` chain
    (:class:`attitude_envs.jax.actuators.ActuatorParams`) and the relative tolerances drawn per
    episode (``slosh_mass``, ``pendulum_length``: each pendulum's, times ``1 + tol · U(−1, 1)``;
    ``gain_tolerance`` (2): each actuator's scale factor). ``given``: the reset takes the
    ``given_*`` draws instead (a numba episode's: :func:`with_drawn_parameters`):
    ``given_slosh_mass_kg`` (2, kg), ``given_length_m`` (2, m), ``given_fuel_mass_kg`` (kg),
    ``given_gain`` (2)."""

    actuators: jact.ActuatorParams
    slosh_mass: jax.Array
    pendulum_length: jax.Array
    gain_tolerance: jax.Array
    given: jax.Array
    given_slosh_mass_kg: jax.Array
    given_length_m: jax.Array
    given_fuel_mass_kg: jax.Array
    given_gain: jax.Array


@struct.dataclass
class EpisodePlant:
    """One episode's true slosh parameters drawn by the flight conditions: ``slosh_mass_kg``
    (2, kg), ``length_m`` (2, m) and the fixed propellant's ``fuel_mass_kg`` (kg)."""

    slosh_mass_kg: jax.Array
    length_m: jax.Array
    fuel_mass_kg: jax.Array


@struct.dataclass
class FlightState:
    """An episode's flight state: the actuator chain's runtime state ``actuators`` (delay
    line, rate limiter, lag), the true ``plant`` (None: the params') and the actuators' scale
    factors ``gain`` (2; None: ones)."""

    actuators: jact.ActuatorState
    plant: EpisodePlant | None = None
    gain: jax.Array | None = None


@struct.dataclass
class EnvState:
    """One episode's state: ``time`` (decisions taken), ``y`` (10, the full state of
    :mod:`attitude_envs.plants.slosh`, SI), the episode's realized actuator ``faults`` and
    their runtime ``fault_state`` (latched stuck values, intermittent phases; times in s);
    under flight conditions its ``flight`` state and the ``state`` sensor's (``sensors``;
    None: the truth is observed)."""

    time: jax.Array
    y: jax.Array
    faults: jfaults.FaultParams
    fault_state: jfaults.FaultState
    flight: FlightState | None = None
    sensors: jsens.StateSensor | None = None


#: a params field whose default is that group of the default preset's params
_default = preset_defaults(lambda: configure(keyword_defaults(NumbaFuelSloshEnv)), lambda cfg: params_of(cfg))


@struct.dataclass
class PlantParams:
    """The plant (Navabi & Davoodi, Table 3; :class:`attitude_envs.plants.slosh.SloshParams`):
    ``mass_kg``, ``inertia_kg_m2`` (vehicle), ``fuel_mass_kg``, ``fuel_inertia_kg_m2`` (rigid
    fuel), ``slosh_mass_kg`` (2), ``slosh_inertia_kg_m2`` (2), ``hinge_m`` (2, a_i),
    ``length_m`` (2, l_i), ``fuel_offset_m`` (a0), ``b_m``, ``d_m`` (m), ``thrust_n`` (N),
    ``damping_kg_m2_s`` (2, ε_i); and ``actuator_limits`` (2): ``[max gimbal (rad), max
    moment (N·m)]``, the scale of a unit action and the actuators' own limits."""

    mass_kg: jax.Array
    inertia_kg_m2: jax.Array
    fuel_mass_kg: jax.Array
    fuel_inertia_kg_m2: jax.Array
    slosh_mass_kg: jax.Array
    slosh_inertia_kg_m2: jax.Array
    hinge_m: jax.Array
    length_m: jax.Array
    fuel_offset_m: jax.Array
    b_m: jax.Array
    d_m: jax.Array
    thrust_n: jax.Array
    damping_kg_m2_s: jax.Array
    actuator_limits: jax.Array


@struct.dataclass
class TimingParams:
    """``control_dt_s`` (s, the decision period) and ``integrator_dt_s`` (s, the RK4 sub-step;
    the env's static ``n_substeps`` times it must be ``control_dt_s``)."""

    control_dt_s: jax.Array
    integrator_dt_s: jax.Array


@struct.dataclass
class CostParams:
    """``Q`` (7×7) on ``x``, ``R`` (2×2) on ``[a_z, Ω̇]`` (the paper's eqs. 30–31 by default);
    the termination limits ``max_slosh_angle_rad``, ``max_pitch_rate_rad_s``,
    ``max_pitch_angle_rad`` on |ψ_i|, |Ω|, |θ|; ``termination_mode``
    (:func:`attitude_envs.jax.cost.mode_code`) and ``horizon_s`` (s, the charge's horizon T:
    ``episode_duration_s``)."""

    Q: jax.Array
    R: jax.Array
    max_slosh_angle_rad: jax.Array
    max_pitch_rate_rad_s: jax.Array
    max_pitch_angle_rad: jax.Array
    termination_mode: jax.Array
    horizon_s: jax.Array


@struct.dataclass
class StartParams:
    """The start: ``initial_state`` (8, ``[v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` m/s, rad,
    rad/s), ``initial_random`` (8, bool) and ``initial_half_width`` (8): entry k is drawn
    ``U(−w_k, w_k)`` where ``initial_random[k]``, else fixed."""

    initial_state: jax.Array
    initial_random: jax.Array
    initial_half_width: jax.Array


@struct.dataclass
class EnvParams:
    """Every number of the plant and the task (a pytree: ``jax.vmap`` over it randomizes
    plants, faults and tasks), in groups that default to the default preset's
    (FuelSlosh-v0's): ``plant``, ``timing``, ``cost`` (with the limits and the termination
    charge), ``start``, ``faults`` (the actuator faults of every episode; an env with
    ``redraw_faults`` draws each episode's from its fault configs instead, as the numba env
    does), ``max_steps_in_episode`` (the time limit in decisions), ``flight`` (the flight
    conditions' actuator chain and per-episode draws, None in the lab) and ``sensors`` (the
    ``state`` sensor's model over the observed entries, None: the truth is observed)."""

    plant: PlantParams = _default("plant")
    timing: TimingParams = _default("timing")
    cost: CostParams = _default("cost")
    start: StartParams = _default("start")
    faults: jfaults.FaultParams = struct.field(default_factory=jfaults.no_faults)
    max_steps_in_episode: jax.Array = _default("max_steps_in_episode")
    flight: FlightParams | None = None
    sensors: jsens.ChannelParams | None = None


def _take(v: jax.Array, index: tuple[int, ...]) -> jax.Array:
    """``v[index]`` for static indices, by slices (cheaper to compile than a gather, also
    under ``vmap``)."""
    return jnp.stack([v[i] for i in index])


def plant_constants(params: EnvParams) -> jax.Array:
    """The packed constants (:mod:`attitude_envs.plants.slosh_definition`, ``P_*``) of the
    physical parameters, as :class:`~attitude_envs.plants.slosh.SloshParams` derives them."""
    return jnp.stack(_PLANT.packed_constants(params.plant))


def derivative(pk: jax.Array, y: jax.Array, sin_d: jax.Array, cos_d: jax.Array, moment: jax.Array) -> jax.Array:
    """``ẏ`` (10) of the full state ``y`` under gimbal sin/cos and pitch moment (N·m), with
    the packed constants ``pk`` (:func:`plant_constants`): the definition's derivative."""
    return jnp.stack(_PLANT.derivative(pk, y, sin_d, cos_d, moment))


def _augmented(pk, aug, sin_d, cos_d, moment, Q, R) -> jax.Array:
    """ẏ (10), the stage cost ``xᵀQx + u_cᵀRu_c`` and the new inputs ``u_c = [a_z, Ω̇]``
    (``a_z = v̇_z − Ω v_x`` of the tank centre, m/s²; Ω̇ rad/s²)."""
    dy, stage, a_z, dom = _PLANT.augmented(pk, aug, sin_d, cos_d, moment, Q, R)
    return jnp.stack([*dy, stage, a_z, dom])


def control_step(
    y: jax.Array, inputs: jax.Array, params: EnvParams, n_substeps: int
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Advance the full state ``y`` over ``n_substeps`` classical RK4 sub-steps of
    ``params.timing.integrator_dt_s`` s with ``inputs = [δ (rad), M_c (N·m)]`` held
    (:func:`attitude_envs.plants.slosh_kernels.control_step`): ``(y⁺, cost, new_inputs)``,
    the step cost ∫(xᵀQx + u_cᵀRu_c) dt and the step means of ``[a_z, Ω̇]`` (m/s², rad/s²)."""
    pk = plant_constants(params)
    h = params.timing.integrator_dt_s
    sin_d, cos_d, moment = jnp.sin(inputs[0]), jnp.cos(inputs[0]), inputs[1]

    def f(a):
        return _augmented(pk, a, sin_d, cos_d, moment, params.cost.Q, params.cost.R)

    # classical RK4, its four stages as a loop (one copy of the derivative in the compiled
    # program: half the compile time of the unrolled stages): stage i evaluates at
    # aug + offset[i]·k_{i−1} and accumulates weight[i]·k_i, in the kernel's order
    # (((k0 + 2k1) + 2k2) + k3; 2k is exact, so the sums round as the kernel's do)
    offset = jnp.stack([jnp.zeros_like(h), 0.5 * h, 0.5 * h, h])
    weight = jnp.array([1.0, 2.0, 2.0, 1.0], dtype=offset.dtype)

    def substep(_, aug):
        def stage(i, carry):
            k, acc = carry
            k = f(aug + offset[i] * k)
            return k, acc + weight[i] * k

        zero = jnp.zeros_like(aug)
        _, acc = jax.lax.fori_loop(0, 4, stage, (zero, zero))
        return aug + (h / 6.0) * acc

    aug = jnp.concatenate([y, jnp.zeros(3, y.dtype)])
    aug = jax.lax.fori_loop(0, n_substeps, substep, aug)
    return aug[:10], aug[10], aug[11:13] / params.timing.control_dt_s


class FuelSloshEnv(Environment):
    """The JAX plant of FuelSlosh-v0/-v1 (module docstring). Static (fixed at construction,
    part of the compiled program): ``n_substeps`` RK4 sub-steps per decision, the
    observation layout ``obs_index`` (full-state indices: ``[v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2,
    v_x]``, or ``[v_z, θ, Ω, v_x]`` without ``observe_slosh``), ``fault_hint`` (append 3
    active-fault flags: gimbal, moment, then the ``state`` sensor, never faulted here), the
    fault configs (``fault_configs``; ``redraw_faults``: draw the faults per episode),
    ``flight`` (:class:`FlightLayout`, None in the lab), ``sensors`` (the ``state`` sensor is
    modeled) and ``unmeasured`` (positions in the observation the sensors do not measure,
    reading 0: the slosh entries under the flight sensors).

    Action: ``Box(-1, 1, (2,))``, clipped: ``δ = a0 · max gimbal``, ``M_c = a1 · max moment``.
    Observation: the state entries (m/s, rad, rad/s; their measurements with ``sensors``) in
    the compute dtype (float64 under x64; the numba env casts to float32), then the hint flags; zeros when the step's state
    is not finite (as the numba env's). Reward ``−cost``."""

    def __init__(
        self,
        n_substeps: int,
        default_params: EnvParams,
        *,
        obs_index: tuple[int, ...] = tuple(int(i) for i in REDUCED_INDEX) + (slosh.IVX,),
        fault_hint: bool = False,
        n_hint_flags: int = 3,
        fault_configs: tuple[dict, ...] = (),
        redraw_faults: bool = False,
        flight: FlightLayout | None = None,
        sensors: bool = False,
        unmeasured: tuple[int, ...] = (),
    ) -> None:
        self.n_substeps = int(n_substeps)
        self.obs_index = tuple(int(i) for i in obs_index)
        self.fault_hint = bool(fault_hint)
        self.n_hint_flags = int(n_hint_flags) if self.fault_hint else 0
        if self.fault_hint and self.n_hint_flags < N_ACTUATORS:
            raise ValueError(f"n_hint_flags must be >= {N_ACTUATORS} with fault_hint, got {n_hint_flags}")
        self.fault_configs = tuple(dict(c) for c in fault_configs)
        self.redraw_faults = bool(redraw_faults)
        self.n_faults = int(default_params.faults.kind.shape[-1])
        self.obs_size = len(self.obs_index) + self.n_hint_flags
        #: the flight conditions' static layout (None: the lab, the step and reset unchanged)
        self.flight = flight
        #: the ``state`` sensor is modeled (False: the truth is observed)
        self.sensors = bool(sensors)
        #: observation positions the sensors do not measure (read 0)
        self.unmeasured = tuple(int(i) for i in unmeasured)
        self._default_params = default_params

    @property
    def name(self) -> str:
        return "FuelSlosh"

    # ------------------------------------------------------------------ dynamics
    def _observe(
        self,
        y: jax.Array,
        faults: jfaults.FaultParams,
        t_s,
        measured: jax.Array | None = None,
        sensor_flag: jax.Array | None = None,
    ) -> jax.Array:
        """The observation of the full state ``y`` at ``t_s`` (s), or of the sensors'
        ``measured`` entries (the unmeasured ones then read 0), with the hint flags (the
        ``state`` sensor's ``sensor_flag``: None, 0)."""
        obs = _take(y, self.obs_index) if measured is None else self._reading(measured)
        if not self.fault_hint:
            return obs
        flags = jfaults.active_flags(faults, t_s, N_ACTUATORS).astype(y.dtype)
        rest = jnp.zeros(self.n_hint_flags - N_ACTUATORS, y.dtype)
        if sensor_flag is not None:
            rest = rest.at[0].set(sensor_flag)
        return jnp.concatenate([obs, flags, rest])

    def step_env(self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams):
        """One decision: clip the action to [-1, 1], scale it to ``[δ (rad), M_c (N·m)]``,
        apply the actuator faults at the decision's start time ``time · control_dt_s`` s
        (under flight conditions between the delay and rate limit and the lag and gains),
        advance the plant (this episode's true plant in flight) over the RK4 sub-steps and
        charge their cost, plus the termination charge on a finite step that crosses a slosh,
        pitch-rate or pitch limit. A non-finite step terminates (no charge; observation
        zeros). Reward ``−cost``; info ``cost``, ``time_s`` (s), ``commanded`` and ``applied``
        (``[δ rad, M_c N·m]`` before clipping, delivered to the plant), ``new_inputs``
        (step-mean ``[a_z m/s², Ω̇ rad/s²]``)."""
        dtype = state.y.dtype
        t_s = state.time * params.timing.control_dt_s
        a = jnp.asarray(action, dtype)
        limits = params.plant.actuator_limits
        commanded = a * limits
        applied = jnp.clip(a, -1.0, 1.0) * limits
        fl, flight = self.flight, state.flight
        plant_params = params
        if fl is None:
            applied, fault_state = self._faulted(key, state, applied, t_s, limits)
        else:  # ActuatorChain.deliver: delay, rate limit, faults, lag, gains
            applied, fault_state, act = jact.deliver(
                fl.actuators,
                params.flight.actuators,
                flight.actuators,
                applied,
                lambda c: self._faulted(key, state, c, t_s, limits),
                flight.gain,
                jnp.zeros_like(applied),
            )
            flight = flight.replace(actuators=act)
            if fl.draw_plant:  # this episode's true slosh parameters
                pl = flight.plant
                plant = params.plant.replace(
                    slosh_mass_kg=pl.slosh_mass_kg, length_m=pl.length_m, fuel_mass_kg=pl.fuel_mass_kg
                )
                plant_params = params.replace(plant=plant)
        y, cost, new_inputs = control_step(state.y, applied, plant_params, self.n_substeps)
        time = state.time + 1
        t_next = time * params.timing.control_dt_s
        finite = jnp.isfinite(cost) & jnp.all(jnp.isfinite(y)) & jnp.all(jnp.isfinite(new_inputs))
        c = params.cost
        rows = _PLANT.limit_rows(y, c.max_slosh_angle_rad, c.max_pitch_rate_rad_s, c.max_pitch_angle_rad)
        crossed = jnp.any(jnp.stack(rows) > 0.0)
        terminated = ~finite | crossed
        x = _take(y, _REDUCED)
        charge = jcost.termination_charge(c.termination_mode, x, c.Q, c.horizon_s, t_next)
        cost = jnp.where(terminated & finite, cost + charge, cost)
        obs = self._observe(y, state.faults, t_next)
        sensors = state.sensors
        if self.sensors:  # sampled at the step's end when the state is finite (as the numba env)
            key_sensor = jax.random.fold_in(key, jsens.SENSOR_STREAM)
            truth = _take(y, self.obs_index)
            m, measured = jsens.measure_state(key_sensor, params.sensors, state.sensors, truth, t_next)
            obs = self._observe(y, state.faults, t_next, m, jsens.state_flag(params.sensors, measured, t_next, y.dtype))
            sensors = jax.tree.map(lambda a, b: jnp.where(finite, a, b), measured, state.sensors)
        obs = jnp.where(finite, obs, jnp.zeros_like(obs))
        new_state = EnvState(
            time=time, y=y, faults=state.faults, fault_state=fault_state, flight=flight, sensors=sensors
        )
        info = {
            "cost": cost,
            "time_s": t_next,
            "commanded": commanded,
            "applied": applied,
            "new_inputs": new_inputs,
        }
        return obs, new_state, -cost, terminated, info

    def reset_env(self, key: jax.Array, params: EnvParams):
        """A fresh episode: the start state (entry k ``U(−w_k, w_k)`` where
        ``initial_random[k]``, else ``initial_state[k]``; the numba env's law), the episode's
        faults (``params.faults``, or drawn from the fault configs with ``redraw_faults``)
        and their initial runtime state; under flight conditions the actuator chain at rest,
        the true slosh parameters and the gains (drawn, or the params' given ones), and the
        ``state`` sensor's bias and first sample."""
        key_init, key_faults, key_state = jax.random.split(key, 3)
        start = params.start
        dtype = start.initial_state.dtype
        w = start.initial_half_width
        drawn = jax.random.uniform(key_init, (8,), dtype, minval=-w, maxval=w)
        init = jnp.where(start.initial_random, drawn, start.initial_state)
        entries = [jnp.zeros((), dtype)] * slosh.N_STATE
        for j, i in enumerate(INITIAL_ORDER):
            entries[i] = init[j]
        y = jnp.stack(entries)
        faults = params.faults
        if self.redraw_faults:
            faults = jfaults.for_episode(key_faults, self.fault_configs, N_ACTUATORS, params.faults)
        flight = None
        if self.flight is not None:
            flight = self._draw_flight(jax.random.fold_in(key, jact.FLIGHT_STREAM), params)
        state = EnvState(
            time=jnp.zeros((), jnp.int32),
            y=y,
            faults=faults,
            fault_state=jfaults.initial_state(key_state, faults),
            flight=flight,
        )
        zero = jnp.zeros((), dtype)
        if not self.sensors:
            return self._observe(y, faults, zero), state
        key_sensor = jax.random.fold_in(key, jsens.SENSOR_STREAM)
        m, sensors = jsens.start_state_sensor(key_sensor, params.sensors, _take(y, self.obs_index))
        flag = jsens.state_flag(params.sensors, sensors, zero, dtype)
        return self._observe(y, faults, zero, m, flag), state.replace(sensors=sensors)

    def _faulted(self, key: jax.Array, state: EnvState, c: jax.Array, t_s, limits: jax.Array):
        """The episode's actuator faults on ``c`` (``[δ rad, M_c N·m]``) at ``t_s`` (s):
        ``(output, fault state)``."""
        if not self.n_faults:
            return c, state.fault_state
        return jfaults.apply(state.faults, state.fault_state, key, c, t_s, limits)

    def _reading(self, measured: jax.Array) -> jax.Array:
        """The sensors' ``measured`` observation entries with the unmeasured ones set to 0."""
        if not self.unmeasured:
            return measured
        keep = np.ones(len(self.obs_index), dtype=bool)
        keep[list(self.unmeasured)] = False
        return jnp.where(keep, measured, 0.0)

    def _draw_flight(self, key: jax.Array, params: EnvParams) -> FlightState:
        """An episode's flight state: the actuator chain at rest and, with the parameters
        drawn, each pendulum's slosh mass and length times ``1 + tol · U(−1, 1)``, the fixed
        propellant mass taking the slosh masses' change, and each actuator's gain
        ``1 + tol · U(−1, 1)`` (:meth:`FuelSloshEnv._draw_flight_plant`'s law, not its draws),
        or the params' ``given_*`` draws."""
        fl, fp, nominal = self.flight, params.flight, params.plant
        dtype = nominal.mass_kg.dtype
        actuators = jact.initial_state(fl.actuators, N_ACTUATORS, dtype)
        if not (fl.draw_plant or fl.actuators.gain):
            return FlightState(actuators=actuators)
        # one uniform draw (one threefry program): 2 masses, 2 lengths, 2 gains
        u = jax.random.uniform(key, (6,), dtype, -1.0, 1.0)
        given = fp.given
        plant = gain = None
        if fl.draw_plant:
            masses = nominal.slosh_mass_kg * (1.0 + fp.slosh_mass * u[0:2])
            lengths = nominal.length_m * (1.0 + fp.pendulum_length * u[2:4])
            change = (masses[0] + masses[1]) - (nominal.slosh_mass_kg[0] + nominal.slosh_mass_kg[1])
            fuel = jnp.maximum(0.0, nominal.fuel_mass_kg - change)
            plant = EpisodePlant(
                slosh_mass_kg=jnp.where(given, fp.given_slosh_mass_kg, masses),
                length_m=jnp.where(given, fp.given_length_m, lengths),
                fuel_mass_kg=jnp.where(given, fp.given_fuel_mass_kg, fuel),
            )
        if fl.actuators.gain:
            gain = jnp.where(given, fp.given_gain, 1.0 + fp.gain_tolerance * u[4:6])
        return FlightState(actuators=actuators, plant=plant, gain=gain)

    # ------------------------------------------------------------------ spaces
    def action_space(self, params: EnvParams | None = None) -> Box:
        """``Box(-1, 1, (2,))``: the normalized ``[δ, M_c]``."""
        return Box(-1.0, 1.0, (N_ACTUATORS,), jnp.float32)

    def observation_space(self, params: EnvParams | None = None) -> Box:
        """The numba env's bounds: speeds ±1e4 m/s, θ and Ω within twice their termination
        limits, ψ_i within twice theirs, ψ̇_i ±50 rad/s; the hint flags in [0, 1]."""
        p = (self.default_params if params is None else params).cost
        bound = {
            slosh.IVZ: 1e4,
            slosh.IVX: 1e4,
            slosh.ITH: 2 * float(p.max_pitch_angle_rad),
            slosh.IOM: 2 * float(p.max_pitch_rate_rad_s),
            slosh.IPSI1: 2 * float(p.max_slosh_angle_rad),
            slosh.IPSI2: 2 * float(p.max_slosh_angle_rad),
            slosh.IDPSI1: 50.0,
            slosh.IDPSI2: 50.0,
        }
        high = np.array([bound[i] for i in self.obs_index])
        low = np.concatenate([-high, np.zeros(self.n_hint_flags)])
        high = np.concatenate([high, np.ones(self.n_hint_flags)])
        return Box(low, high, (self.obs_size,), jnp.result_type(float))

    # ------------------------------------------------------------------ numba bridge
    def state_from(self, numba_env: Any, key: jax.Array | None = None, time: int = 0) -> EnvState:
        """The JAX state of the numba env's current episode: its full state ``y``, realized
        actuator faults and their runtime state; ``time`` the decisions it has taken (0 after
        its reset: the numba env keeps its counter private). An intermittent fault not yet
        evaluated (no first switch drawn) gets its first switch time drawn with ``key``
        (default ``PRNGKey(0)``) from the same law. ``numba_env`` may be wrapped (``gym.make``'s env).
        Under flight conditions the episode's drawn slosh parameters and gains and the actuator
        chain at rest (its runtime state is not public: a ``ValueError`` for ``time > 0`` with a
        delay or actuator dynamics); a ``ValueError`` with sensors (their state is not public:
        reset the JAX env instead)."""
        numba_env = getattr(numba_env, "unwrapped", numba_env)
        faults, fault_state = jfaults.from_numba_layer(numba_env.fault_layer.realized, self.n_faults, key)
        y = jnp.asarray(np.asarray(numba_env.state, dtype=float))
        check_state_from(self.sensors, None if self.flight is None else self.flight.actuators, int(time))
        return EnvState(
            time=jnp.asarray(int(time), jnp.int32),
            y=y,
            faults=faults,
            fault_state=fault_state,
            flight=None if self.flight is None else self._flight_state_from(numba_env, int(time), y.dtype),
        )

    def _flight_state_from(self, env: Any, time: int, dtype) -> FlightState:
        """The flight state of the numba env's current episode (:meth:`state_from`)."""
        fl = self.flight
        drawn = env.drawn_parameters()

        def f(v: Any) -> jax.Array:
            return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

        plant = gain = None
        if fl.draw_plant:
            plant = EpisodePlant(
                slosh_mass_kg=f(drawn["slosh_mass_kg"]),
                length_m=f(drawn["length_m"]),
                fuel_mass_kg=f(drawn["fuel_mass_kg"]),
            )
        if fl.actuators.gain:
            gain = f(drawn["actuator_gain"])
        return FlightState(actuators=jact.initial_state(fl.actuators, N_ACTUATORS, dtype), plant=plant, gain=gain)


def with_drawn_parameters(params: EnvParams, drawn: dict) -> EnvParams:
    """``params`` whose resets take the true slosh parameters and gains ``drawn`` (a numba
    flight episode's ``env.unwrapped.drawn_parameters()``: ``slosh_mass_kg``, ``length_m``,
    ``fuel_mass_kg``, ``actuator_gain``) instead of drawing them: the JAX episode of that numba
    episode's plant. ``ValueError`` for lab params or a missing entry."""
    fp = params.flight
    shapes = {"slosh_mass_kg": (2,), "length_m": (2,), "fuel_mass_kg": (), "actuator_gain": (N_ACTUATORS,)}
    a = drawn_arrays(fp, drawn, shapes)
    dtype = fp.given_gain.dtype

    def f(key: str) -> jax.Array:
        return jnp.asarray(a[key], dtype=dtype)

    return params.replace(
        flight=fp.replace(
            given=jnp.asarray(True),
            given_slosh_mass_kg=f("slosh_mass_kg"),
            given_length_m=f("length_m"),
            given_fuel_mass_kg=f("fuel_mass_kg"),
            given_gain=f("actuator_gain"),
        )
    )


def params_of(
    cfg: FuelSloshConfig,
    fault_configs: tuple[dict, ...] = (),
    layers: Layers | None = None,
    plant_tolerances: dict[str, float] | None = None,
) -> EnvParams:
    """The ``EnvParams`` of a validated configuration (:func:`attitude_envs.envs.fuel_slosh.configure`)
    with the validated actuator ``fault_configs``, drawn once with ``PRNGKey(0)`` (with random
    fields only a default: each episode draws its own, ``redraw_faults``) and, under flight
    conditions, the flight numbers and the ``state`` sensor's model of its ``layers``
    (:func:`attitude_envs.jax.make.state_layers`; None: the lab's params) with the
    relative ``plant_tolerances`` ``slosh_mass`` and ``pendulum_length`` (None: not drawn)."""
    p = cfg.model.params
    # one compiled draw (eager, its many small ops would each compile)
    faults = jax.jit(lambda key: jfaults.realize(key, list(fault_configs), N_ACTUATORS))(jax.random.PRNGKey(0))
    initial_random = np.zeros(8, bool)
    if cfg.randomize_initial_state:
        initial_random[list(RANDOM_START)] = True
    half_width = np.where(initial_random, np.abs(PAPER_INITIAL_STATE), 0.0)

    def f(v: Any) -> jax.Array:
        return jnp.asarray(np.asarray(v, dtype=float))

    physical = {field: f(getattr(p, field)) for field in PlantParams.__dataclass_fields__ if field != "actuator_limits"}
    flight = sensors = None
    if layers is not None and not layers.conditions.is_lab:
        dtype = jnp.result_type(float)
        tol = plant_tolerances or {}
        flight = FlightParams(
            actuators=jact.chain_params(layers, N_ACTUATORS, cfg.control_dt_s, dtype),
            slosh_mass=f(tol.get("slosh_mass", 0.0)),
            pendulum_length=f(tol.get("pendulum_length", 0.0)),
            gain_tolerance=f(layers.gain_tolerance),
            given=jnp.asarray(False),
            given_slosh_mass_kg=physical["slosh_mass_kg"],
            given_length_m=physical["length_m"],
            given_fuel_mass_kg=physical["fuel_mass_kg"],
            given_gain=f(np.ones(N_ACTUATORS)),
        )
        config = layers.sensor_layer.config.get("state")
        n_obs = len(OBS_INDEX if cfg.observe_slosh else OBS_INDEX_NO_SLOSH)
        sensor_faults = jsens.channel_faults(layers.sensor_layer, dtype, "FuelSlosh JAX plant")
        sensors = None if config is None else jsens.params_of(config, n_obs, dtype, sensor_faults.get("state"))
    return EnvParams(
        plant=PlantParams(**physical, actuator_limits=f([cfg.model.max_gimbal_rad, cfg.model.max_moment_nm])),
        timing=TimingParams(control_dt_s=f(cfg.control_dt_s), integrator_dt_s=f(cfg.integrator_dt_s)),
        cost=CostParams(
            Q=f(cfg.model.cost.Q),
            R=f(cfg.model.cost.R),
            max_slosh_angle_rad=f(cfg.max_slosh_angle_rad),
            max_pitch_rate_rad_s=f(cfg.max_pitch_rate_rad_s),
            max_pitch_angle_rad=f(cfg.max_pitch_angle_rad),
            termination_mode=jnp.asarray(jcost.mode_code(cfg.termination_cost), jnp.int32),
            horizon_s=f(cfg.episode_duration_s),
        ),
        start=StartParams(
            initial_state=f(cfg.initial_state),
            initial_random=jnp.asarray(initial_random),
            initial_half_width=f(half_width),
        ),
        faults=faults,
        max_steps_in_episode=jnp.asarray(episode_decisions(cfg.episode_duration_s, cfg.control_dt_s), jnp.int32),
        flight=flight,
        sensors=sensors,
    )


def from_keywords(plant: str, kwargs: dict[str, Any]) -> tuple[FuelSloshEnv, EnvParams]:
    """The JAX ``plant`` and its ``EnvParams`` for the numba env's keywords ``kwargs``, validated
    as the numba env validates them (no numba env is built). A ``ValueError`` names what the
    JAX plant does not model (``sensors`` or sensor faults in the lab)."""
    check_keywords(NumbaFuelSloshEnv, kwargs)
    cfg = configure({**keyword_defaults(NumbaFuelSloshEnv), **kwargs})
    obs_index = OBS_INDEX if cfg.observe_slosh else OBS_INDEX_NO_SLOSH
    limits = np.array([cfg.model.max_gimbal_rad, cfg.model.max_moment_nm])
    cond = cfg.conditions
    layers = flight = tolerances = None
    unmeasured: tuple[int, ...] = ()
    if cond.is_lab:
        layer = state_layers(plant, cfg, limits, len(obs_index)).fault_layer
    else:
        sensors, missing = flight_state_sensor(cfg.observe_slosh, cond.sensors)
        if cfg.sensors is None and cond.sensors > 0:
            unmeasured = tuple(int(i) for i in missing)
        layers = state_layers(plant, cfg, limits, len(obs_index), sensors, cfg.control_dt_s)
        layer = layers.fault_layer
        tolerances = flight_plant_tolerances(flight_table(NumbaFuelSloshEnv.env_name, cfg.preset), cond.parameters)
        flight = FlightLayout(actuators=jact.chain_layout(layers), draw_plant=tolerances is not None)
    configs = tuple(dict(c) for c in layer.configs)
    params = params_of(cfg, configs, layers, tolerances)
    env = FuelSloshEnv(
        cfg.n_substeps,
        params,
        obs_index=tuple(int(i) for i in obs_index),
        fault_hint=cfg.fault_hint,
        n_hint_flags=layer.n + 1,
        fault_configs=configs,
        redraw_faults=any(jfaults.draws_per_episode(c) for c in configs),
        flight=flight,
        sensors=params.sensors is not None,
        unmeasured=unmeasured,
    )
    return env, params
