"""The shared base of every env: presets, the fault and sensor layers, ``fault_hint``,
disturbances, and the ``info`` contract (:mod:`attitude_envs.info`), wired once here.

A plant's env subclasses :class:`AttitudeEnv`, sets :attr:`AttitudeEnv.env_name` and
:attr:`AttitudeEnv.default_preset`, and in ``__init__``

1. resolves its keywords with ``cfg = self._configure(preset, locals())`` (the preset's
   values, overridden by every keyword that is not None);
2. builds its plant and nominal ``model``;
3. calls :meth:`AttitudeEnv._init_layers` with its actuator count and limits, its sensor
   channels, and the ``faults``, ``sensors``, ``fault_hint`` and ``disturbance`` keywords;

then in ``reset`` calls :meth:`AttitudeEnv._reset_layers` and in ``step`` passes its
commanded actuator outputs through :meth:`AttitudeEnv._deliver`, builds the observation with
:meth:`AttitudeEnv._with_hint` and the info with :meth:`AttitudeEnv._make_info`.

The base wraps each subclass's ``reset`` and ``step`` in the episode-order guard (as
Gymnasium's ``OrderEnforcing`` wrapper and CartPole-v1 do, but on the raw class too):
``step`` before the first ``reset`` raises ``gymnasium.error.ResetNeeded``; ``step`` after
the episode returned ``terminated`` or ``truncated`` warns once per episode and then runs.

Batched envs, wrappers, estimators and campaigns use only the public members documented
here and on each env (no private attribute of another object).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import error, logger

from attitude_envs import presets, validation
from attitude_envs.actuator_dynamics import ActuatorChain
from attitude_envs.conditions import Conditions
from attitude_envs.disturbances import Disturbance
from attitude_envs.evaluation.success import SuccessMetric
from attitude_envs.faults import ActuatorFaults
from attitude_envs.info import MEASURED, TRUTH
from attitude_envs.sensors import Channel, SensorSuite

_NOT_KEYWORDS = {"self", "preset", "__class__", "render_mode"}

#: the accepted values of every env's ``termination_cost`` keyword (see
#: :meth:`AttitudeEnv.batch_termination_cost`)
TERMINATION_COSTS = ("hold", "episode", "none")


@functools.cache
def constructor_keywords(cls: type) -> frozenset[str]:
    """The keyword arguments ``cls(...)`` accepts: the named parameters of each ``__init__``
    along its MRO, as long as each passes ``**kwargs`` on (cached per class)."""
    names: set[str] = set()
    for klass in inspect.getmro(cls):
        if "__init__" not in klass.__dict__:
            continue
        params = inspect.signature(klass.__dict__["__init__"]).parameters.values()
        names |= {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
        if not any(p.kind == p.VAR_KEYWORD for p in params):
            break
    return frozenset(names - {"self"})


def keyword_defaults(cls: type) -> dict[str, Any]:
    """The default of each keyword of ``cls.__init__`` (what ``cls(**kwargs)`` takes for a
    keyword not passed)."""
    params = inspect.signature(cls.__init__).parameters.values()
    return {p.name: p.default for p in params if p.default is not inspect.Parameter.empty}


def _checking_unknown_keywords(init):
    """``init`` that first rejects keyword arguments the env does not accept: a one-line
    ``ValueError`` naming the env id and the closest accepted name (also through plain
    ``gymnasium.make``, which would otherwise pass Python's bare ``TypeError`` on)."""

    @functools.wraps(init)
    def checked(self, *args: Any, **kwargs: Any) -> None:
        check_keywords(type(self), kwargs)
        init(self, *args, **kwargs)

    return checked


def check_keywords(cls: type, kwargs: Mapping[str, Any]) -> None:
    """A one-line ``ValueError`` for the first of ``kwargs`` that ``cls(...)`` does not accept,
    naming the env id and the closest accepted name."""
    accepted = constructor_keywords(cls)
    for key in kwargs:
        if key not in accepted:
            env_id = f"attitude_envs/{cls.env_name}" if cls.env_name else cls.__name__
            raise ValueError(
                f"bad keyword arguments for env {env_id!r}: it has no keyword argument {key!r}"
                f"{presets.suggest(key, accepted)} (accepted: {sorted(accepted)})"
            )


# Why ``step`` may not simply go on (see :func:`_guarding_step`); None while an episode runs.
_NOT_RESET, _TERMINATED, _TRUNCATED, _WARNED = "not reset", "terminated", "truncated", "warned"


def _guarding_step(step):
    """``step`` with the episode-order guard: before the first ``reset`` it raises
    ``gymnasium.error.ResetNeeded``; after the episode returned ``terminated`` or
    ``truncated`` it warns once (as CartPole-v1 does), then steps as asked (undefined
    behaviour: the state goes on from where it ended). A step that returns ``terminated``
    returns its observation clipped to the observation space
    (:meth:`AttitudeEnv.clip_observation`). One attribute test on the hot path."""

    @functools.wraps(step)
    def guarded(self, action):
        if self._episode_over is not None:
            self._step_out_of_episode()
        result = step(self, action)
        if result[2] or result[3]:
            if self._episode_over is None:
                self._episode_over = _TERMINATED if result[2] else _TRUNCATED
            if result[2]:  # the step that crosses a limit: its observation clipped to the box
                result = (self.clip_observation(result[0]), *result[1:])
        return result

    guarded.episode_guard = True
    return guarded


def _guarding_reset(reset):
    """``reset`` that starts the episode ``step`` checks for (a reset that raises leaves
    the env needing one); its observation clipped to the space
    (:meth:`AttitudeEnv.clip_observation`: only a start given beyond the limits reaches a bound)."""

    @functools.wraps(reset)
    def guarded(self, *args: Any, **kwargs: Any):
        self._episode_over = _NOT_RESET
        obs, info = reset(self, *args, **kwargs)
        self._episode_over = None
        return self.clip_observation(obs), info

    guarded.episode_guard = True
    return guarded


class AttitudeEnv(gym.Env):
    """Base of the suite's envs (see the module docstring for the recipe)."""

    #: the env id without namespace, e.g. ``"ReactionWheel-v0"`` (names its presets)
    env_name: ClassVar[str] = ""
    #: the env's default preset (listed first by :func:`attitude_envs.presets.for_env`). What
    #: ``preset=None`` means is each env's to document: the envs whose plant needs a full
    #: parameter set (ReactionWheel, AirBearing, Magnetorquer) then take this default;
    #: FuelSlosh-v0 and LinearSystem-v0 take no preset (every value given explicitly).
    default_preset: ClassVar[str | None] = None
    #: how an episode is judged a success (:mod:`attitude_envs.evaluation.success`): each env
    #: declares its own
    success_metric: ClassVar[SuccessMetric]
    #: True where an episode records as an :class:`~attitude_envs.evaluation.trace.EpisodeTrace`
    #: (:func:`~attitude_envs.evaluation.trace.record_episode`: reaction wheels, N·m torques) and
    #: takes :func:`~attitude_envs.evaluation.metrics.episode_metrics`; else
    #: :func:`~attitude_envs.evaluation.trace.record_state_trace` only
    wheel_trace: ClassVar[bool] = False
    #: the keywords that pose the learning task on the same episodes: how often the agent
    #: decides and what a limit crossing costs, not the plant, its draws or the running cost
    #: (an agent in a campaign may set them on a cell's episodes; the ``-v1`` ids change them)
    task_keywords: ClassVar[frozenset[str]] = frozenset({"control_dt_s", "termination_cost"})
    #: why ``step`` may not simply go on: "not reset" (until the first reset), "terminated"
    #: or "truncated" (the episode ended), "warned" (and the warning was given); None while
    #: an episode runs
    _episode_over: str | None = _NOT_RESET

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "__init__" in cls.__dict__:  # every env's constructor rejects unknown keywords by name
            cls.__init__ = _checking_unknown_keywords(cls.__dict__["__init__"])
        # every env enforces the episode order (step after reset; a warning past the end)
        for name, guarding in (("step", _guarding_step), ("reset", _guarding_reset)):
            method = cls.__dict__.get(name)
            if method is not None and not getattr(method, "episode_guard", False):
                setattr(cls, name, guarding(method))

    # ------------------------------------------------------------------ construction
    def _configure(self, preset: str | None, given: Mapping[str, Any]) -> dict[str, Any]:
        """Constructor values: preset ``preset`` (None: none), overridden by each keyword
        in ``given`` (the constructor's ``locals()``) that is not None."""
        overrides = {k: v for k, v in given.items() if k not in _NOT_KEYWORDS and not k.startswith("_")}
        self.preset = preset
        return presets.resolve(self.env_name, preset, overrides, constructor_keywords(type(self)))

    def _init_layers(self, **kwargs: Any) -> None:
        """Build and hold the env's layers: :func:`build_layers` of this env and preset."""
        self._use_layers(build_layers(*self._flight_table_key(self.preset), **kwargs))

    def _use_layers(self, layers: Layers) -> None:
        """Hold ``layers`` (built by :func:`build_layers` for this env and preset)."""
        self._layers = layers
        self.conditions = layers.conditions
        self._fault_layer = layers.fault_layer
        self._sensor_layer = layers.sensor_layer
        self._actuator_chain = layers.actuator_chain
        #: the relative scale-factor tolerance of each actuator drawn per episode (0: exact)
        self._gain_tolerance = layers.gain_tolerance
        self._n_actuators = layers.fault_layer.n
        #: this episode's drawn true parameters (empty in the lab; see :meth:`drawn_parameters`)
        self._drawn: dict[str, Any] = {}
        self.fault_hint = layers.fault_hint
        self._disturbance = layers.disturbance

    @property
    def flight_table(self):
        """This env's cited flight values (:class:`attitude_envs.presets.flight.FlightTable`),
        looked up by env name (not stored: the env stays picklable); ValueError for a plant
        without one."""
        from attitude_envs.presets import flight

        return flight.table(*self._flight_table_key(self.preset))

    @classmethod
    def _flight_table_key(cls, preset: str | None) -> tuple[str, str | None]:
        """``(env name, preset)`` whose flight table (:mod:`attitude_envs.presets.flight`) the
        env with ``preset`` takes: its own, unless an env shares another's plant."""
        return cls.env_name, preset

    @property
    def fault_layer(self) -> ActuatorFaults:
        """The actuator fault layer (read it, e.g. ``realized`` faults; do not modify)."""
        return self._fault_layer

    @property
    def sensor_layer(self) -> SensorSuite:
        """The sensor layer (``enabled`` is False when the truth is observed)."""
        return self._sensor_layer

    @property
    def disturbance(self) -> Disturbance | None:
        """The external-torque disturbance model, or None."""
        return self._disturbance

    @property
    def n_hint_flags(self) -> int:
        """Entries ``fault_hint`` appends to the observation (0 when off): one per actuator,
        then one per sensor channel."""
        return self._layers.n_hint_flags

    def _init_termination_cost(self, mode: str, Q: np.ndarray, horizon: float) -> None:
        """Validate the ``termination_cost`` keyword; ``Q`` weighs the error state and
        ``horizon`` is the episode's length (s, or steps for a discrete-time env)."""
        self.termination_cost = validation.choice("termination_cost", mode, TERMINATION_COSTS)
        self._hold_q = np.asarray(Q, dtype=float)
        self._horizon = float(horizon)

    def _termination_charge(self, x: np.ndarray, elapsed: float) -> float:
        """:meth:`batch_termination_cost` of one error state (the single envs' step)."""
        return float(self.batch_termination_cost(np.reshape(x, (1, -1)), np.array([elapsed]))[0])

    def batch_termination_cost(self, x: np.ndarray, elapsed: np.ndarray) -> np.ndarray:
        """The cost charged on the step that ends an episode by crossing a limit, for rows
        ``x`` (E × n) of true error states at that step and the time ``elapsed`` (E; s, or
        steps for a discrete-time env) at its end, by ``termination_cost``:

        * ``"hold"`` (the v0 envs): the running state cost ``xᵀQx`` held over the rest of
          the horizon, ``(T − t) xᵀQx``;
        * ``"episode"`` (the v1 envs): ``xᵀQx`` held over a whole episode, ``T xᵀQx``;
        * ``"none"``: zeros.

        Without a charge a terminated episode costs nothing more, so an agent maximizing the
        return −J learns to cross a limit early (the learned agents on FuelSlosh-v0 did,
        within 1–3 steps). ``"hold"`` prices the rest of the horizon at the state the episode
        ended in, which is what the undiscounted J of holding that state would add; but a
        learner that bootstraps its value at the time limit (PPO, SAC) values holding a
        state of running cost ``c`` at ``c·Δt/(1 − γ)`` at every time, and ``(T − t)·c``
        falls below that near the end of the episode, so there a crossing pays in its
        objective. ``"episode"`` charges ``T·c``: at least the rest of the horizon at every
        ``t``, and at least ``c·Δt/(1 − γ)`` for every discount whose horizon ``Δt/(1 − γ)``
        is at most the episode ``T`` (every shipped recipe's is: a test checks). Each row is
        summed on its own, so the single and the batched envs charge the same bits."""
        x = np.ascontiguousarray(x, dtype=float)  # one memory layout: the same products' bits
        out = np.zeros(len(x))
        if self.termination_cost == "none":
            return out
        for i in range(len(x)):
            row = x[i]
            held = self._horizon if self.termination_cost == "episode" else max(self._horizon - float(elapsed[i]), 0.0)
            out[i] = float(row @ self._hold_q @ row) * held
        return out

    # ------------------------------------------------------------------ the learning task
    @property
    def episode_length_s(self) -> float:
        """An episode's time limit, s (``episode_duration_s``; LinearSystem: its plant steps × ``dt_s``)."""
        return float(self.episode_duration_s)

    @property
    def decisions_per_episode(self) -> int:
        """Env steps (decisions of ``control_dt_s`` s) in an episode that reaches its time limit:
        a discount's horizon ``1/(1 − γ)`` decisions beyond this is past the episode."""
        return max(1, round(self.episode_length_s / float(self.control_dt_s)))

    # ------------------------------------------------------------------ episode
    def _step_out_of_episode(self) -> None:
        """``step`` outside an episode: before the first reset a ``ResetNeeded`` error; after
        the end a warning, once per episode (the step then runs, as CartPole-v1's does)."""
        if self._episode_over == _NOT_RESET:
            env_id = f"attitude_envs/{self.env_name}" if self.env_name else type(self).__name__
            raise error.ResetNeeded(
                f"Cannot call env.step() before calling env.reset(): call reset() first to start an episode of {env_id}"
            )
        if self._episode_over != _WARNED:
            logger.warn(
                f"You are calling 'step()' even though this environment has already returned "
                f"{self._episode_over} = True. You should always call 'reset()' once you receive "
                f"'{self._episode_over} = True' -- any further steps are undefined behavior.",
                stacklevel=3,
            )
            self._episode_over = _WARNED

    def _flight_rng(self, rng: np.random.Generator) -> np.random.Generator | None:
        """A generator for this episode's flight draws (the true plant, the actuator gains),
        spawned from ``rng`` without advancing it, so the episode's start, target and faults
        are the lab episode's of the same seed; None in the lab (nothing drawn). Call it once
        per reset, before :meth:`_reset_layers`."""
        if self.conditions.is_lab:
            return None
        self._drawn = {}
        return rng.spawn(1)[0]

    def _reset_layers(
        self, rng: np.random.Generator, options: Mapping[str, Any], flight_rng: np.random.Generator | None = None
    ) -> None:
        """Draw this episode's sensor faults and biases (from a generator the sensor layer
        spawns: ``rng``'s own stream is unchanged by it), actuator faults and disturbance;
        with flight conditions, the actuator gains (from ``flight_rng``) and an empty delay
        line."""
        faults = options.get("faults")
        if self._disturbance is not None:
            self._disturbance.reset(rng)
        self._sensor_layer.reset(rng, faults)
        self._fault_layer.reset(rng, faults)
        if flight_rng is not None and self._gain_tolerance.any():
            tol = self._gain_tolerance
            self._drawn["actuator_gain"] = 1.0 + tol * flight_rng.uniform(-1.0, 1.0, size=tol.shape)
        if self._actuator_chain is not None:
            self._actuator_chain.reset(self._n_actuators, self._drawn.get("actuator_gain"))

    def _deliver(self, commanded: np.ndarray, t_s: float, speeds: np.ndarray | None = None) -> np.ndarray:
        """The actuator outputs delivered for ``commanded`` at time ``t_s`` (faults applied;
        with flight conditions also the delay, the actuator dynamics and the scale-factor
        errors, :mod:`attitude_envs.actuator_dynamics`; ``speeds``, rad/s per actuator, give
        wheel friction)."""
        if self._actuator_chain is not None:
            out = self._actuator_chain.deliver(commanded, lambda c: self._fault_layer.apply(c, t_s), speeds)
            return out if self._actuator_chain.model is not None else self._with_gain(out)
        return self._with_gain(self._fault_layer.apply(commanded, t_s))

    def _with_gain(self, delivered: np.ndarray) -> np.ndarray:
        gain = self._drawn.get("actuator_gain")
        return delivered if gain is None else delivered * gain

    def drawn_parameters(self) -> dict[str, Any]:
        """This episode's true parameters drawn by the flight conditions (copies; empty in
        the lab): ``actuator_gain`` (scale-factor of each actuator) and the plant's own
        (e.g. ``inertia_kg_m2``). The truth: controllers hold the nominal model."""
        return {k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in self._drawn.items()}

    def _hint_flags(self, t_s: float) -> np.ndarray:
        """1.0 per actuator, then per sensor channel, with a fault active at ``t_s``."""
        return np.concatenate([self._fault_layer.active_flags(t_s), self._sensor_layer.active_flags(t_s)])

    def _with_hint(self, obs: np.ndarray, t_s: float) -> np.ndarray:
        """``obs`` with the fault flags appended when ``fault_hint`` is on, as float32."""
        if self.fault_hint:
            obs = np.concatenate([obs, self._hint_flags(t_s)])
        return obs.astype(np.float32)

    def _hint_bounds(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Observation bounds with the ``fault_hint`` flags' [0, 1] appended when on."""
        return self._layers.hint_bounds(low, high)

    def clip_observation(self, obs: np.ndarray) -> np.ndarray:
        """``obs`` clipped to :attr:`observation_space` (a new float32 array): the observation
        ``step`` returns on the step that ends an episode by crossing a limit, and ``reset``'s.

        The bounds of the quantities that end an episode (rates, angles, divergence) lie
        beyond their limits (twice the limit on the gyrostats, the magnetorquer and the fuel
        slosh; one step's reach from the divergence threshold on LinearSystem), so a step that
        crosses no limit never reaches one and is observed as measured. The step that crosses
        a limit can overshoot a bound within its decision: FuelSlosh-v1's pitch rate (its
        0.25 s decision, up to 1.8 times the bound on about a third of random-action
        episodes), FuelSlosh-v0's on one in a hundred bang-bang episodes, and AirBearing-v1's
        and Magnetorquer-v1's rates under limits smaller than the defaults. That terminal
        observation is the measurement clipped to the box, a sensor saturating at its range;
        ``info["truth"]`` holds the true state. No policy acts on a terminal observation and
        no learner bootstraps from a terminated one, so the clip changes no return, no
        trained agent and no benchmark. At ``reset`` only a start given beyond the limits
        (``initial_state``, ``options["state"]``, limits set below a preset's start) reaches
        a bound; its first step ends the episode. A diverged (non-finite) state is observed as
        zeros. Not clipped: a sensor dropout in ``"nan"`` mode, which observes NaN on purpose."""
        space = self.observation_space
        return np.clip(obs, space.low, space.high).astype(np.float32, copy=False)

    def _fault_truth(self, actuator_t_s: float, sensor_t_s: float | None = None) -> list[dict]:
        """Ground truth of every fault of the episode and whether it is active."""
        if not (self._fault_layer.realized or self._sensor_layer.realized):
            return []  # the common fault-free episode: a fast path for every step's info
        t_sensor = actuator_t_s if sensor_t_s is None else sensor_t_s
        return self._fault_layer.info(actuator_t_s) + self._sensor_layer.info(t_sensor)

    def _make_info(
        self, *, truth: dict[str, Any], measured: Any, cost: float, time_s: float, **public: Any
    ) -> dict[str, Any]:
        """The info of :mod:`attitude_envs.info`: ``truth`` (must hold ``state``; the sensor
        biases are added when sensors are on), ``measured`` (same structure as
        ``truth["state"]``), ``cost``, ``time_s`` and the env's other public entries."""
        if self._sensor_layer.enabled:
            truth = dict(truth, sensor_bias={k: v.copy() for k, v in self._sensor_layer.bias.items()})
        if not self.conditions.is_lab:
            truth = dict(truth, drawn_parameters=self.drawn_parameters())
        return {TRUTH: truth, MEASURED: measured, "cost": cost, "time_s": time_s, **public}


@dataclasses.dataclass(frozen=True)
class Layers:
    """An env's validated layers (:func:`build_layers`): its ``conditions``, actuator
    ``fault_layer``, ``sensor_layer``, flight ``actuator_chain`` (None without a delay or
    actuator dynamics), per-actuator ``gain_tolerance``, ``fault_hint`` and ``disturbance``."""

    conditions: Conditions
    fault_layer: ActuatorFaults
    sensor_layer: SensorSuite
    actuator_chain: ActuatorChain | None
    gain_tolerance: np.ndarray
    fault_hint: bool
    disturbance: Disturbance | None

    @property
    def n_hint_flags(self) -> int:
        """Entries ``fault_hint`` appends to the observation (0 when off): one per actuator,
        then one per sensor channel."""
        return self.fault_layer.n + len(self.sensor_layer.channels) if self.fault_hint else 0

    def hint_bounds(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Observation bounds with the ``fault_hint`` flags' [0, 1] appended when on."""
        n = self.n_hint_flags
        return np.concatenate([low, np.zeros(n)]), np.concatenate([high, np.ones(n)])


def build_layers(
    env_name: str,
    preset: str | None,
    *,
    n_actuators: int,
    actuator_limits,
    channels: list[Channel],
    faults: list[dict] | None,
    sensors: dict | None,
    fault_hint: bool,
    disturbance: dict | None = None,
    conditions=None,
    control_dt_s: float | None = None,
) -> Layers:
    """The actuator-fault, sensor, disturbance and flight layers of env ``env_name`` with
    ``preset`` (validated here, once). ``faults`` entries with ``"target": "sensor"`` go to
    the sensor layer. ``conditions`` (:mod:`attitude_envs.conditions`) takes its flight values
    from :func:`attitude_envs.presets.flight.table` of this env and preset; ``control_dt_s``
    is the env's control period (s; needed by the delay and the actuator dynamics)."""
    from attitude_envs.presets import flight

    cond = Conditions.from_config(conditions)
    table = None if cond.is_lab else flight.table(env_name, preset)
    if table is not None and sensors is None and cond.sensors > 0:
        sensors = table.sensor_config(cond.sensors)
    fault_layer = ActuatorFaults(faults, n_actuators, actuator_limits, other_targets={"sensor"})
    sensor_layer = SensorSuite(sensors, channels, faults)
    chain = None
    if cond.actuators or cond.delay_steps:
        limits = np.broadcast_to(np.asarray(actuator_limits, dtype=float), (n_actuators,))
        model = table.actuator_model(limits) if cond.actuators else None
        chain = ActuatorChain(model, cond.delay_steps, control_dt_s)
    gain = np.zeros(n_actuators) if cond.parameters == 0 else table.gain_tolerance_of(n_actuators) * cond.parameters
    return Layers(
        conditions=cond,
        fault_layer=fault_layer,
        sensor_layer=sensor_layer,
        actuator_chain=chain,
        gain_tolerance=gain,
        fault_hint=validation.flag("fault_hint", fault_hint),
        disturbance=None if disturbance is None else Disturbance(disturbance),
    )
