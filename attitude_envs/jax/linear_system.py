"""LinearSystem-v0/-v1 in JAX: the discrete LTI plant ``x⁺ = A x + B u (+ w)`` of
:class:`attitude_envs.envs.linear_system.LinearSystemEnv`, one decision per step.

A decision holds the input over ``k = control_dt_s / dt_s`` plant steps of ``dt_s`` s. Without
process noise the step is the exact discretization of the hold,
``x⁺ = A_k x + B_k u`` with ``A_k = Aᵏ``, ``B_k = (Σ_{i<k} Aⁱ) B``, charged the exact sum of
the k plant steps' stage costs ``xᵀQ_k x + 2xᵀN_k u + uᵀR_k u``
(:func:`attitude_envs.plants.linear_hold.hold_model`, the numba env's ``decision_model``;
``held_step``); with process noise the k plant steps are taken one by one, each with its
draw ``w ~ N(0, σ² I)`` (``noisy_held_steps``). The default preset is the linearized
quaternion/rate model of Heravi & Novinzadeh (2017), eq. 59, forward-Euler discretized
(eqs. 61–62) with Δt = 0.01 s; the -v1 learning task decides every 5 s (k = 500).

Time is counted as the numba env counts it: ``state.time`` in decisions, the plant steps
``time · k`` for the time (``time_s = time · k · dt_s``), the fault onsets (the actuator
faults are applied at the decision's start time and held over it) and the termination
charge (``horizon_steps`` and the elapsed plant steps, :func:`attitude_envs.jax.cost.termination_charge`).

Flight conditions (``conditions=``, :mod:`attitude_envs.conditions`; the values of
:mod:`attitude_envs.presets.flight_linear`): the delay and the actuator chain act between the
command and the faults and after them as :meth:`attitude_envs.actuator_dynamics.ActuatorChain.deliver`
(:mod:`attitude_envs.jax.actuators`; LinearSystem's chain has no dynamics beyond each input's
scale factor, the flight error of ``B``), its runtime state in ``EnvState.flight``; ``reset_env``
draws the episode's gains within the flight tolerance from its key folded with
:data:`~attitude_envs.jax.actuators.FLIGHT_STREAM` (by the numba env's law, not its draws; the
start and the faults are the lab episode's of the same key), or takes a numba episode's
(:func:`with_drawn_parameters`). The ``state`` sensor (white noise of 1 % of each entry's
:attr:`~attitude_envs.envs.linear_system.LinearSystemEnv.state_scale`, or an explicit
``sensors=`` with flight conditions' sensors on) samples at reset and at the end of each finite
step from keys folded with :data:`~attitude_envs.jax.sensors.SENSOR_STREAM` (the numba sensor
layer's law, not its draws); the observation is then the measurement, as the numba env's, and
``info``, the cost and the limit stay the truth's. The lab's compiled program is unchanged
(``flight`` and ``sensors`` None in the env, its params and state).

Modeled: every keyword of the numba env except ``sensors`` in the lab (sensors only as flight
conditions' sensors) and sensor faults outside flight conditions' sensors
(:func:`attitude_envs.jax.sensors.channel_faults`; the others are modeled, draws and ``fault_hint`` flags included) (a ``ValueError`` names them); actuator faults
(``faults``, per-episode draws included) and ``fault_hint``; process noise (the same law, draws
from the step's key).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.envs.base import Layers, check_keywords, keyword_defaults
from attitude_envs.envs.linear_system import LinearSystemConfig, configure, state_scale
from attitude_envs.envs.linear_system import LinearSystemEnv as NumbaLinearSystemEnv
from attitude_envs.faults import RealizedFault
from attitude_envs.jax import actuators as jact
from attitude_envs.jax import cost as jcost
from attitude_envs.jax import faults as jfaults
from attitude_envs.jax import sensors as jsens
from attitude_envs.jax.environment import Environment, check_state_from, drawn_arrays, preset_defaults
from attitude_envs.jax.make import state_layers
from attitude_envs.jax.spaces import Box
from attitude_envs.presets.flight_linear import state_sensor_config


@struct.dataclass
class FlightParams:
    """The flight conditions' numbers: the ``actuators`` chain
    (:class:`attitude_envs.jax.actuators.ActuatorParams`; neutral entries but the gains),
    ``gain_tolerance`` (m, relative: each input's scale factor is drawn per episode within
    ± it). ``given``: the reset takes ``given_gain`` (m) instead of drawing (a numba
    episode's: :func:`with_drawn_parameters`)."""

    actuators: jact.ActuatorParams
    gain_tolerance: jax.Array
    given: jax.Array
    given_gain: jax.Array


@struct.dataclass
class FlightState:
    """An episode's flight state: the actuator chain's runtime state ``actuators`` (delay
    line) and the inputs' scale factors ``gain`` (m; None: not drawn, ones)."""

    actuators: jact.ActuatorState
    gain: jax.Array | None = None


@struct.dataclass
class EnvState:
    """One episode's state: ``time`` (decisions taken), ``x`` (n, the plant state in the
    units of the model), the episode's realized actuator ``faults`` and their runtime
    ``fault_state`` (latched stuck values, intermittent phases; times in s); under flight
    conditions its ``flight`` state and the ``state`` sensor's (``sensors``; None: the
    truth is observed)."""

    time: jax.Array
    x: jax.Array
    faults: jfaults.FaultParams
    fault_state: jfaults.FaultState
    flight: FlightState | None = None
    sensors: jsens.StateSensor | None = None


#: a params field whose default is that group of the default preset's params
_default = preset_defaults(lambda: configure(keyword_defaults(NumbaLinearSystemEnv)), lambda cfg: params_of(cfg))


@struct.dataclass
class PlantParams:
    """The plant step of ``dt_s`` s, ``x⁺ = A x + B u`` (``A`` n×n, ``B`` n×m), and
    ``action_scale`` (m; the physical input of a unit action, also the actuator limits)."""

    A: jax.Array
    B: jax.Array
    dt_s: jax.Array
    action_scale: jax.Array


@struct.dataclass
class HoldParams:
    """The decision step (the input held over k plant steps): ``x⁺ = A_k x + B_k u`` and its
    exact cost ``xᵀQ_k x + 2xᵀN_k u + uᵀR_k u`` (``N_k`` n×m)."""

    A_k: jax.Array
    B_k: jax.Array
    Q_k: jax.Array
    R_k: jax.Array
    N_k: jax.Array


@struct.dataclass
class CostParams:
    """The stage cost ``xᵀQx + uᵀRu`` per plant step (``Q`` also weighs the termination
    charge), the limit ``divergence_threshold`` on ‖x‖∞, ``termination_mode``
    (:func:`attitude_envs.jax.cost.mode_code`) and ``horizon_steps`` (the episode's plant
    steps, the charge's horizon T)."""

    Q: jax.Array
    R: jax.Array
    divergence_threshold: jax.Array
    termination_mode: jax.Array
    horizon_steps: jax.Array


@struct.dataclass
class StartParams:
    """The start ``x0 ~ N(x0_mean, diag(x0_std²))`` (n each)."""

    x0_mean: jax.Array
    x0_std: jax.Array


@struct.dataclass
class DisturbanceParams:
    """``process_noise_std``: σ of ``w`` per entry and plant step (read only by an env built
    with ``noisy=True``)."""

    process_noise_std: jax.Array


@struct.dataclass
class EnvParams:
    """Every number of the plant (a pytree: ``jax.vmap`` over it randomizes plants), in
    groups that default to the default preset's (LinearSystem-v0's): ``plant``, ``hold``
    (the decision step), ``cost`` (with the limit and the termination charge), ``start``,
    ``disturbance`` (process noise), ``faults`` (the actuator faults of every episode; an
    env with ``redraw_faults`` draws each episode's from its fault configs instead, as the
    numba env does), ``max_steps_in_episode`` (the time limit in decisions,
    ``episode_steps / k``), ``flight`` (the flight conditions' actuator chain and gain
    draws, None in the lab) and ``sensors`` (the ``state`` sensor's model, None: the truth
    is observed)."""

    plant: PlantParams = _default("plant")
    hold: HoldParams = _default("hold")
    cost: CostParams = _default("cost")
    start: StartParams = _default("start")
    disturbance: DisturbanceParams = _default("disturbance")
    faults: jfaults.FaultParams = struct.field(default_factory=jfaults.no_faults)
    max_steps_in_episode: jax.Array = _default("max_steps_in_episode")
    flight: FlightParams | None = None
    sensors: jsens.ChannelParams | None = None


class LinearSystemEnv(Environment):
    """The JAX plant of LinearSystem-v0/-v1 (module docstring). Static (fixed at
    construction, part of the compiled program): ``n`` states, ``m`` inputs,
    ``decision_steps`` k, ``noisy`` (k plant steps with process noise instead of the exact
    hold), ``fault_hint`` (the observation appends m + 1 active-fault flags: the actuators,
    then the ``state`` sensor, never faulted here), the fault configs (``fault_configs``,
    ``redraw_faults``: draw the faults per episode), the observation bounds, ``flight`` (the
    actuator chain's :class:`~attitude_envs.jax.actuators.ActuatorLayout` under flight
    conditions, None in the lab) and ``sensors`` (the ``state`` sensor is modeled).

    Observation: ``x`` (n; its measurement with ``sensors``) in the compute dtype, then the
    hint flags; zeros when the state is not finite (as the numba env's)."""

    def __init__(
        self,
        n: int,
        m: int,
        decision_steps: int,
        default_params: EnvParams,
        *,
        noisy: bool = False,
        fault_hint: bool = False,
        fault_configs: tuple[dict, ...] = (),
        redraw_faults: bool = False,
        obs_bound: float = np.inf,
        flight: jact.ActuatorLayout | None = None,
        sensors: bool = False,
    ) -> None:
        self.n = int(n)
        self.m = int(m)
        self.decision_steps = int(decision_steps)
        self.noisy = bool(noisy)
        self.fault_hint = bool(fault_hint)
        self.fault_configs = tuple(dict(c) for c in fault_configs)
        self.redraw_faults = bool(redraw_faults)
        self.n_faults = int(default_params.faults.kind.shape[-1])
        self.obs_size = self.n + (self.m + 1 if self.fault_hint else 0)
        self.obs_bound = float(obs_bound)
        #: the flight conditions' actuator chain (None: the lab, the step and reset unchanged)
        self.flight = flight
        #: the ``state`` sensor is modeled (False: the truth is observed)
        self.sensors = bool(sensors)
        self._default_params = default_params

    @property
    def name(self) -> str:
        return "LinearSystem"

    # ------------------------------------------------------------------ dynamics
    def plant_step(self, x: jax.Array, u: jax.Array, noise: jax.Array | None, params: EnvParams):
        """One decision from ``x`` with the delivered input ``u`` (physical) held:
        ``(x⁺, cost)``. ``noise`` None: the exact hold (``held_step``); else the k plant
        steps one by one, ``noise[j]`` (n, already scaled by σ) added after step j
        (``noisy_held_steps``), cost the sum of their stage costs."""
        if noise is None:
            x_next = params.hold.A_k @ x + params.hold.B_k @ u
            cost = x @ params.hold.Q_k @ x + u @ params.hold.R_k @ u + 2.0 * (x @ (params.hold.N_k @ u))
            return x_next, cost
        drive = params.plant.B @ u
        stage_u = u @ params.cost.R @ u

        def one(cur, w):
            return params.plant.A @ cur + drive + w, cur @ params.cost.Q @ cur + stage_u

        x_next, stages = jax.lax.scan(one, x, noise)
        return x_next, jnp.sum(stages)

    def _observe(
        self, x: jax.Array, faults: jfaults.FaultParams, t_s, sensor_flag: jax.Array | None = None
    ) -> jax.Array:
        """The observation ``x`` with the ``fault_hint`` flags: the actuators', then the ``state``
        sensor's ``sensor_flag`` (None: 0)."""
        if not self.fault_hint:
            return x
        flags = jfaults.active_flags(faults, t_s, self.m).astype(x.dtype)
        sensor = jnp.zeros(1, x.dtype) if sensor_flag is None else sensor_flag[None].astype(x.dtype)
        return jnp.concatenate([x, flags, sensor])

    def _faulted(self, key: jax.Array, state: EnvState, c: jax.Array, t_s, params: EnvParams):
        """The episode's actuator faults on the inputs ``c`` at ``t_s`` (s): ``(u, fault state)``."""
        if not self.n_faults:
            return c, state.fault_state
        return jfaults.apply(state.faults, state.fault_state, key, c, t_s, params.plant.action_scale)

    def step_env(self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams):
        """One decision: clip the action to [-1, 1], scale it to the physical input, apply
        the actuator faults at the decision's start time ``time · k · dt_s`` s (under flight
        conditions between the delay and the gains), advance the plant k plant steps and
        charge their cost (plus the termination charge on a finite step that crosses
        ``divergence_threshold``). Reward ``−cost``."""
        dtype = state.x.dtype
        # a split only when both draw (noise, intermittent faults): fewer programs to compile
        key_noise, key_fault = jax.random.split(key) if self.noisy and self.n_faults else (key, key)
        k = self.decision_steps
        steps = state.time * k
        t_s = _seconds(steps, params.plant.dt_s, dtype)
        a = jnp.clip(jnp.asarray(action, dtype), -1.0, 1.0)
        commanded = params.plant.action_scale * a
        flight = state.flight
        if self.flight is None:
            u, fault_state = self._faulted(key_fault, state, commanded, t_s, params)
        else:  # ActuatorChain.deliver: the delay, the faults, the gains
            u, fault_state, act = jact.deliver(
                self.flight,
                params.flight.actuators,
                flight.actuators,
                commanded,
                lambda c: self._faulted(key_fault, state, c, t_s, params),
                flight.gain,
                jnp.zeros_like(commanded),
            )
            flight = flight.replace(actuators=act)
        noise = None
        if self.noisy:
            noise = params.disturbance.process_noise_std * jax.random.normal(key_noise, (k, self.n), dtype)
        x_next, cost = self.plant_step(state.x, u, noise, params)
        steps_next = steps + k
        elapsed = steps_next.astype(dtype)
        t_next = _seconds(steps_next, params.plant.dt_s, dtype)
        finite = jnp.all(jnp.isfinite(x_next))
        terminated = jnp.logical_or(~finite, jnp.max(jnp.abs(x_next)) > params.cost.divergence_threshold)
        c = params.cost
        charge = jcost.termination_charge(c.termination_mode, x_next, c.Q, c.horizon_steps, elapsed)
        cost = cost + jnp.where(terminated & finite, charge, 0.0)
        obs = self._observe(x_next, state.faults, t_next)
        sensors = state.sensors
        if self.sensors:  # sampled at the step's end when the state is finite (as the numba env)
            key_sensor = jax.random.fold_in(key, jsens.SENSOR_STREAM)
            m, measured = jsens.measure_state(key_sensor, params.sensors, state.sensors, x_next, t_next)
            obs = self._observe(
                m, state.faults, t_next, jsens.state_flag(params.sensors, measured, t_next, x_next.dtype)
            )
            sensors = jax.tree.map(lambda a, b: jnp.where(finite, a, b), measured, state.sensors)
        obs = jnp.where(finite, obs, jnp.zeros_like(obs))
        new_state = EnvState(
            time=state.time + 1,
            x=x_next,
            faults=state.faults,
            fault_state=fault_state,
            flight=flight,
            sensors=sensors,
        )
        info = {"cost": cost, "time_s": t_next, "commanded": commanded, "applied": u}
        return obs, new_state, -cost, terminated, info

    def reset_env(self, key: jax.Array, params: EnvParams):
        """A fresh episode: ``x0 = x0_mean + x0_std · N(0, I)``, the episode's faults
        (``params.faults``, or drawn from the fault configs with ``redraw_faults``) and
        their initial runtime state; under flight conditions the actuator chain at rest and
        the inputs' gains (drawn, or the params' given ones), and the ``state`` sensor's bias
        and first sample."""
        key_x, key_faults, key_state = jax.random.split(key, 3) if self.n_faults else (key, key, key)
        start = params.start
        dtype = start.x0_mean.dtype
        x0 = start.x0_mean + start.x0_std * jax.random.normal(key_x, (self.n,), dtype)
        faults = params.faults
        if self.redraw_faults:
            faults = jfaults.for_episode(key_faults, self.fault_configs, self.m, params.faults)
        flight = None
        if self.flight is not None:
            flight = self._draw_flight(jax.random.fold_in(key, jact.FLIGHT_STREAM), params)
        state = EnvState(
            time=jnp.zeros((), jnp.int32),
            x=x0,
            faults=faults,
            fault_state=jfaults.initial_state(key_state, faults),
            flight=flight,
        )
        zero = jnp.zeros((), dtype)
        if not self.sensors:
            return self._observe(x0, faults, zero), state
        m, sensors = jsens.start_state_sensor(jax.random.fold_in(key, jsens.SENSOR_STREAM), params.sensors, x0)
        return self._observe(m, faults, zero, jsens.state_flag(params.sensors, sensors, zero, dtype)), state.replace(
            sensors=sensors
        )

    def _draw_flight(self, key: jax.Array, params: EnvParams) -> FlightState:
        """An episode's flight state: the actuator chain at rest and, with the gains drawn,
        each input's ``1 + tol · U(−1, 1)`` (the numba env's law, not its draws) or the
        params' ``given_gain``."""
        fp = params.flight
        dtype = params.start.x0_mean.dtype
        actuators = jact.initial_state(self.flight, self.m, dtype)
        if not self.flight.gain:
            return FlightState(actuators=actuators)
        gain = 1.0 + fp.gain_tolerance * jax.random.uniform(key, (self.m,), dtype, -1.0, 1.0)
        return FlightState(actuators=actuators, gain=jnp.where(fp.given, fp.given_gain, gain))

    # ------------------------------------------------------------------ spaces
    def action_space(self, params: EnvParams | None = None) -> Box:
        """``Box(-1, 1, (m,))``: the normalized input (``u = action_scale · a``)."""
        return Box(-1.0, 1.0, (self.m,), jnp.float32)

    def observation_space(self, params: EnvParams | None = None) -> Box:
        """``x`` within ± the numba env's bound (what one step can reach from a
        non-terminated state), then the hint flags in [0, 1]."""
        hint = self.obs_size - self.n
        low = np.concatenate([np.full(self.n, -self.obs_bound), np.zeros(hint)])
        high = np.concatenate([np.full(self.n, self.obs_bound), np.ones(hint)])
        return Box(low, high, (self.obs_size,), jnp.result_type(float))

    # ------------------------------------------------------------------ numba bridge
    def state_from(self, numba_env: Any, key: jax.Array | None = None) -> EnvState:
        """The JAX state of the numba env's current episode: its state ``x``, decisions
        taken, realized actuator faults and their runtime state. An intermittent fault not
        yet evaluated (no first switch drawn) gets its first switch time drawn with ``key``
        (default ``PRNGKey(0)``) from the same law. ``numba_env`` may be wrapped (``gym.make``'s env).
        Under flight conditions the episode's drawn gains and the actuator chain at rest (its
        delay line is not public: a ``ValueError`` after the first step with a delay); a
        ``ValueError`` with sensors (their state is not public: reset the JAX env instead)."""
        numba_env = getattr(numba_env, "unwrapped", numba_env)
        faults, fault_state = jfaults.from_numba_layer(numba_env.fault_layer.realized, self.n_faults, key)
        steps = int(numba_env.steps_taken)  # plant steps elapsed
        x = jnp.asarray(numba_env.state, dtype=float)
        check_state_from(self.sensors, self.flight, steps)
        flight = None
        if self.flight is not None:
            flight = FlightState(actuators=jact.initial_state(self.flight, self.m, x.dtype))
            if self.flight.gain:
                gain = numba_env.drawn_parameters()["actuator_gain"]
                flight = flight.replace(gain=jnp.asarray(np.asarray(gain, dtype=float), dtype=x.dtype))
        return EnvState(
            time=jnp.asarray(steps // self.decision_steps, jnp.int32),
            x=x,
            faults=faults,
            fault_state=fault_state,
            flight=flight,
        )


def with_drawn_parameters(params: EnvParams, drawn: dict) -> EnvParams:
    """``params`` whose resets take the gains ``drawn`` (a numba flight episode's
    ``env.unwrapped.drawn_parameters()``: ``actuator_gain``) instead of drawing them: the JAX
    episode of that numba episode's plant. ``ValueError`` for lab params or a missing entry."""
    fp = params.flight
    shape = () if fp is None else tuple(fp.given_gain.shape)
    gain = drawn_arrays(fp, drawn, {"actuator_gain": shape})["actuator_gain"]
    dtype = fp.given_gain.dtype
    return params.replace(flight=fp.replace(given=jnp.asarray(True), given_gain=jnp.asarray(gain, dtype=dtype)))


def _seconds(steps: jax.Array, dt_s: jax.Array, dtype) -> jax.Array:
    """The time (s) after ``steps`` plant steps of ``dt_s`` s: the numba env's product
    ``steps · dt_s`` in float64 (bit for bit, so fault onsets switch on the same step). In
    float32 the product can round a decision time just below an onset (20 · 0.01f < 0.2f), so
    when ``1 / dt_s`` is an integer (0.01 s: 100 steps per s) the time is ``steps / (1 / dt_s)``,
    correctly rounded; otherwise the product."""
    n = steps.astype(dtype)
    if jnp.dtype(dtype) == jnp.float64:
        return n * dt_s
    rate = 1.0 / dt_s
    whole = jnp.round(rate)
    # a select, so that XLA does not simplify n / (1 / dt) back into the product n · dt
    return jnp.where(jnp.abs(rate - whole) <= 1e-6 * whole, n / whole, n * dt_s)


def _nominal_faults(configs: tuple[dict, ...], n_actuators: int) -> jfaults.FaultParams:
    """The faults of ``configs`` (validated fault dicts) as :func:`attitude_envs.jax.faults.realize`
    lays them out, without a draw: the given numbers, a ``"random"`` index as 0 and a
    ``{"uniform": [a, b]}`` as its midpoint (an env that draws redraws them per episode)."""

    def number(spec: Any) -> float:
        return 0.5 * (float(spec["uniform"][0]) + float(spec["uniform"][1])) if isinstance(spec, dict) else float(spec)

    realized = []
    for c in configs:
        index = c.get("index", "random")
        indices = range(n_actuators) if index == "all" else [0 if index == "random" else int(index)]
        for i in indices:
            realized.append(
                RealizedFault(
                    c["kind"],
                    i,
                    None if c.get("value") is None else number(c["value"]),
                    number(c.get("onset_s", 0.0)),
                    None if c.get("duration_s") is None else number(c["duration_s"]),
                    None if c.get("schedule") is None else np.asarray(c["schedule"], dtype=float),
                    float(c.get("mean_on_s", 1.0)),
                    float(c.get("mean_off_s", 1.0)),
                )
            )
    return jfaults.from_realized(realized)


def params_of(cfg: LinearSystemConfig, fault_configs: tuple[dict, ...] = (), layers: Layers | None = None) -> EnvParams:
    """The ``EnvParams`` of a validated configuration (:func:`attitude_envs.envs.linear_system.configure`)
    with the validated actuator ``fault_configs`` as :func:`_nominal_faults` lays them out and,
    under flight conditions, the flight numbers and the ``state`` sensor's model of its
    ``layers`` (:func:`~attitude_envs.jax.make.state_layers`; None: the lab's params)."""
    model, held = cfg.model, cfg.decision_model
    n, m = model.n, model.m

    def f(v: Any) -> jax.Array:
        return jnp.asarray(np.asarray(v, dtype=float))

    flight = sensors = None
    if layers is not None and not layers.conditions.is_lab:
        dtype = jnp.result_type(float)
        flight = FlightParams(
            actuators=jact.chain_params(layers, m, cfg.control_dt_s, dtype),
            gain_tolerance=f(layers.gain_tolerance),
            given=jnp.asarray(False),
            given_gain=f(np.ones(m)),
        )
        config = layers.sensor_layer.config.get("state")
        sensor_faults = jsens.channel_faults(layers.sensor_layer, dtype, "LinearSystem JAX plant")
        sensors = None if config is None else jsens.params_of(config, n, dtype, sensor_faults.get("state"))

    return EnvParams(
        plant=PlantParams(A=f(model.A), B=f(model.B), dt_s=f(model.dt_s), action_scale=f(cfg.action_scale)),
        hold=HoldParams(
            A_k=f(held.A),
            B_k=f(held.B),
            Q_k=f(held.Q),
            R_k=f(held.R),
            N_k=f(np.zeros((n, m)) if held.N is None else held.N),
        ),
        cost=CostParams(
            Q=f(cfg.cost.Q),
            R=f(cfg.cost.R),
            divergence_threshold=f(cfg.divergence_threshold),
            termination_mode=jnp.asarray(jcost.mode_code(cfg.termination_cost), jnp.int32),
            horizon_steps=f(cfg.episode_steps),
        ),
        start=StartParams(x0_mean=f(cfg.x0_mean), x0_std=f(cfg.x0_std)),
        disturbance=DisturbanceParams(process_noise_std=f(cfg.process_noise_std)),
        faults=_nominal_faults(fault_configs, m),
        max_steps_in_episode=jnp.asarray(cfg.episode_steps // cfg.decision_steps, jnp.int32),
        flight=flight,
        sensors=sensors,
    )


def from_keywords(plant: str, kwargs: dict[str, Any]) -> tuple[LinearSystemEnv, EnvParams]:
    """The JAX ``plant`` and its ``EnvParams`` for the numba env's keywords ``kwargs``, validated
    as the numba env validates them (no numba env is built). A ``ValueError`` names what the
    JAX plant does not model (``sensors`` or sensor faults in the lab)."""
    check_keywords(NumbaLinearSystemEnv, kwargs)
    cfg = configure({**keyword_defaults(NumbaLinearSystemEnv), **kwargs})
    n, m, k = cfg.model.n, cfg.model.m, cfg.decision_steps
    layers = chain = None
    if cfg.conditions.is_lab:
        layer = state_layers(plant, cfg, cfg.action_scale, n).fault_layer
    else:
        sensors = state_sensor_config(state_scale(cfg.x0_mean, cfg.x0_std), cfg.conditions.sensors)
        layers = state_layers(plant, cfg, cfg.action_scale, n, sensors, cfg.control_dt_s)
        layer = layers.fault_layer
        chain = jact.chain_layout(layers)
    configs = tuple(dict(c) for c in layer.configs)
    params = params_of(cfg, configs, layers)
    env = LinearSystemEnv(
        n,
        m,
        k,
        params,
        noisy=cfg.process_noise_std > 0,
        fault_hint=cfg.fault_hint,
        fault_configs=configs,
        redraw_faults=any(jfaults.draws_per_episode(c) for c in configs),
        obs_bound=float(np.float32(cfg.obs_bound)),
        flight=chain,
        sensors=params.sensors is not None,
    )
    return env, params
