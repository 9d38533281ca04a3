"""LinearSystem-v0: a discrete LTI plant with quadratic stage cost, for verifying learners
against the Riccati solution."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from attitude_envs import presets, validation
from attitude_envs.conditions import Conditions
from attitude_envs.cost import QuadraticCost
from attitude_envs.envs.base import TERMINATION_COSTS, AttitudeEnv, constructor_keywords
from attitude_envs.evaluation.success import FINAL_STATE_FRACTION
from attitude_envs.linearization import LinearModel
from attitude_envs.plants import linear_hold, linear_kernels
from attitude_envs.presets.flight_linear import state_sensor_config
from attitude_envs.sensors import Channel

ENV = "LinearSystem-v0"


class _DefaultPreset:
    """The ``preset`` argument's default: the env's default preset, or none when the caller
    gives its own ``A`` or ``B``."""

    def __repr__(self) -> str:
        return "<'heravi-2017' unless A or B is given>"


DEFAULT_PRESET = _DefaultPreset()


def state_scale(x0_mean: np.ndarray, x0_std: np.ndarray) -> np.ndarray:
    """Each state entry's typical scale, the RMS of its initial distribution
    ``√(x0_mean² + x0_std²)`` (state units; an entry whose start is exactly 0 takes the
    largest entry's, and 1 when every entry's is 0): what the flight sensor noise is a
    fraction of (:mod:`attitude_envs.presets.flight_linear`)."""
    scale = np.hypot(x0_mean, x0_std)
    top = float(scale.max())
    return np.where(scale > 0, scale, top if top > 0 else 1.0)


class LinearSystemEnv(AttitudeEnv):
    """Discrete linear plant ``x⁺ = A x + B u + w`` with stage cost ``xᵀQx + uᵀRu``, the
    input held over ``k = control_dt_s / dt_s`` plant steps per decision.

    **Description.** A learner's test bench: the plant is exactly linear and known (the
    model's Riccati solution is the optimal controller), so a model-free learner can be
    checked against it. The default preset is the linearized quaternion/rate model of the
    1000 kg·m² satellite of Heravi & Novinzadeh (2017), eq. 59, discretized by forward
    Euler (eqs. 61–62) with Δt = 0.01 s; any ``A``, ``B`` can be given instead. One
    compiled call per step (:func:`attitude_envs.plants.linear_kernels.linear_step`).

    **Decision period.** The matrices are the plant over ``dt_s``; the agent acts every
    ``control_dt_s = k · dt_s`` (default ``dt_s``, k = 1) and its input is held (zero-order
    hold) over the k plant steps. A step applies the exact discretization
    ``x⁺ = Aᵏ x + (Σ_{i<k} Aⁱ) B u`` and charges the exact sum of the k plant steps' stage
    costs, ``xᵀQ_k x + 2xᵀN_k u + uᵀR_k u`` (:func:`attitude_envs.plants.linear_hold.hold_model`,
    precomputed once; the matrices are ``env.unwrapped.decision_model``), so J of a
    piecewise-constant input is the same quantity at every k. With process noise and k > 1
    the k plant steps are taken one by one in one compiled call
    (:func:`attitude_envs.plants.linear_hold.noisy_held_steps`, k draws of ``w``), bitwise the
    k = 1 env fed the held action.

    **Action space.** ``Box(-1, 1, (m,), float32)``, clipped (saturation); the physical
    input is ``u = action_scale · a``.

    **Observation space.** float32 ``x`` (n) of the float64 state, measured when sensors
    are on; with ``fault_hint`` m + 1 flags in [0, 1] appended (actuators, then the
    ``state`` sensor). Bounds: ``‖A‖∞ · divergence_threshold + ‖B‖∞ · max(action_scale)
    + 10 · process_noise_std`` (what one step can reach from a non-terminated state), with
    k > 1 ``‖Aᵏ‖∞ · divergence_threshold + ‖B_k‖∞ · max(action_scale) + 10 · process_noise_std
    · Σ_{i<k} ‖Aⁱ‖∞``. The step that crosses the divergence threshold observes its
    measurement clipped to the bounds
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`; ``info["truth"]`` holds
    the true state).

    **Reward.** ``−(xᵀQx + uᵀRu)`` with ``x`` the state the step starts from and ``u`` the
    applied input; with k > 1 the sum of the k plant steps' such costs,
    ``−(xᵀQ_k x + 2xᵀN_k u + uᵀR_k u)`` (see Decision period).

    **Starting state.** ``x0 ~ N(x0_mean, diag(x0_std²))`` from the env's RNG, or
    ``reset(options={"state": x0, "faults": [...]})``.

    **Episode end.** Terminated when ``‖x‖∞ > divergence_threshold`` or the state is not
    finite (the observation is then zeros), checked at the end of each env step (after its
    k plant steps); truncated after ``episode_steps`` plant steps (``episode_steps / k`` env
    steps). A finite step that crosses the threshold is charged, on top of its cost, the
    terminal state's ``xᵀQx`` once per remaining plant step, ``(episode_steps − t) xᵀQx``
    with ``t`` the plant steps elapsed (``termination_cost="hold"``; ``"episode"``:
    ``episode_steps · xᵀQx``; ``"none"``: nothing more).

    **Arguments** (None takes the preset's value, or the neutral default without preset):

    ========================  ==============  ===========  ======  ==============================================
    name                      type            default      unit    description
    ========================  ==============  ===========  ======  ==============================================
    ``preset``                str or None     see below    —       parameter set; None: none
    ``A``                     n×n             preset       —       state matrix (required without preset)
    ``B``                     n×m             preset       —       input matrix (required without preset)
    ``Q``, ``R``              n×n, m×m PSD    preset / I   —       stage-cost weights
    ``x0_mean``               n floats        preset / 0   state   mean initial state
    ``x0_std``                float or n      preset / 1   state   initial-state standard deviation (≥ 0)
    ``process_noise_std``     float ≥ 0       0            state   ``w ~ N(0, process_noise_std²)`` per entry
                                                                   and plant step
    ``action_scale``          float or m > 0  preset / 1   input   physical input of a unit action
    ``episode_steps``         int ≥ 1         1000         steps   time limit, plant steps of dt_s (a multiple
                                                                   of k): ``episode_steps · dt_s`` s
    ``divergence_threshold``  float > 0       1e6          state   termination limit on ‖x‖∞
    ``dt_s``                  float > 0       preset / 1   s       the period the matrices represent (time_s)
    ``control_dt_s``          float > 0       ``dt_s``     s       decision period, a whole multiple k·dt_s
                                                                   (k ≥ 1; input held over k plant steps)
    ``faults``                list of dicts   None         —       :mod:`attitude_envs.faults` (time = plant
                                                                   steps·dt_s, taken at each decision)
    ``sensors``               dict            None         —       ``{"state": {...}}``, :mod:`attitude_envs.sensors`
    ``fault_hint``            bool            False        —       append the active-fault flags
    ``termination_cost``      str             "hold"       —       ``"hold"``/``"episode"``: charge a divergence
                                                                   (see Episode end); ``"none"``: no charge
    ``conditions``            str or dict     "lab"        —       ``"lab"``, ``"flight"`` or features
                                                                   (:mod:`attitude_envs.conditions`; see Flight
                                                                   conditions)
    ========================  ==============  ===========  ======  ==============================================

    **Presets.** ``heravi-2017`` (default): Heravi & Novinzadeh
    (2017), A and B of eq. 59 by forward Euler (eqs. 61–62, Δt = 0.01 s) with
    J = diag(1000, 1000, 800) kg·m² (eq. 71), Q = I₆, R = I₃, the fixed initial state of
    eqs. 72 and 74 (the quaternion read scalar-first and normalized), ``action_scale`` 2
    N·m (assumed). When ``preset`` is not passed and ``A`` or ``B`` is, no preset is used
    (a user's system gets the neutral defaults Q = I, R = I, x0_mean = 0, x0_std = 1,
    action_scale = 1, dt_s = 1); ``preset="heravi-2017"`` with ``A`` is an explicit
    override of that preset.

    **Faults and sensors.** Actuator i is input u_i (physical units, limit
    ``action_scale[i]``); ``"target": "sensor"`` faults hit the ``state`` sensor, which
    measures the whole state at the observation times (reset and the end of each step).

    **Flight conditions** (``conditions=``, :mod:`attitude_envs.conditions`; values and
    sources in :mod:`attitude_envs.presets.flight_linear`, all assumed but the delay: the
    plant is abstract). ``"lab"`` (default) is the exact plant, bit for bit. ``"flight"``:

    * *sensors*: the ``state`` sensor adds white noise of 1 % of each entry's typical scale
      (:attr:`state_scale`) to the whole state; an explicit ``sensors=`` replaces it;
    * *delay*: one decision period (``control_dt_s``; a command acts from the next step,
      zeros before: with k > 1 that is k plant steps);
    * *parameters*: each input's scale factor drawn per episode within ±5 % (the flight
      error of ``B``: the true plant is ``B · diag(gain)``), from a generator spawned at
      reset, so the start equals the lab's of the same seed;
      :meth:`~attitude_envs.envs.base.AttitudeEnv.drawn_parameters` holds ``actuator_gain``;
      ``model`` stays the nominal plant;
    * *actuators*: no dynamics beyond the scale factor (the inputs are abstract).

    The batched env (``vector_entry_point``) runs the lab only; use
    ``gymnasium.vector.SyncVectorEnv`` for flight conditions.

    **Info** (:mod:`attitude_envs.info`). ``truth``: ``state`` (the state the observation
    shows: after the step; at reset the initial state x0), ``previous_state`` (the state the
    step started from; step infos only, so the true transition is
    ``(truth["previous_state"], truth["applied"], truth["state"])``), ``applied`` (u after
    saturation and faults), ``faults`` (actuator faults as applied over the step, sensor
    faults at the observation time), ``sensor_bias`` (with sensors). ``measured``: the
    measurement of ``truth["state"]``, the one in the observation (sensors are only sampled
    at observation times; with sensors off it equals ``truth["state"]``). Top level:
    ``cost``, ``time_s`` (plant steps · dt_s), ``commanded`` (``action_scale ·`` the clipped
    action, before faults) and, with sensors, ``sensors`` (``{"state": reading}``). An
    actuator fault is applied as it is at the decision time (plant steps · dt_s) and held
    over the decision period, like the input.

    ``env.unwrapped.model`` is the :class:`LinearModel` of the plant step (A, B, Q, R, dt_s);
    ``env.unwrapped.decision_model`` the one of the decision period (``Aᵏ``, ``B_k``, ``Q_k``,
    ``R_k``, ``N_k``, ``control_dt_s``; ``model`` itself when k = 1), the model a controller
    acting every ``control_dt_s`` designs for; ``env.unwrapped.control_dt_s`` (s) and
    ``env.unwrapped.decision_steps`` (k). The batched env uses the public members
    :attr:`state`, :attr:`process_noise_std`, :attr:`action_scale`, :attr:`cost`,
    :attr:`decision_model`, :attr:`decision_steps`, :attr:`episode_steps`,
    :attr:`divergence_threshold` and the base's ``fault_layer``.

    **Success** (:mod:`attitude_envs.evaluation.success`): ``success_metric`` is
    ``FINAL_STATE_FRACTION``, ‖x‖ at the end over ‖x‖ at the start (default threshold 0.1).

    **Version history.** v1 (``attitude_envs/LinearSystem-v1``, 2026-11-27): the learning task — Heravi & Novinzadeh 2017's 400 s regulation (``preset="heravi-2017"``, ``episode_steps=40000``) decided every 5 s (``control_dt_s``: the exact 500-step hold of the 0.01 s model, the same J) and a divergence charged ``T·xᵀQx`` (``termination_cost="episode"``). v0: a limit crossing charged the terminal running cost over the rest of the episode (``termination_cost``, 2026-11); presets through :mod:`attitude_envs.presets` (``"spec-001"`` is
    an alias of ``heravi-2017``); a user's ``A``/``B`` no longer inherit the default
    preset's ``x0_mean`` and ``action_scale``; infos follow the truth/measured contract
    (``truth["state"]`` is the state after the step, ``truth["previous_state"]`` the one
    before; ``truth["next_state"]`` was removed).
    """

    env_name = ENV
    default_preset = "heravi-2017"
    success_metric = FINAL_STATE_FRACTION
    metadata = {"render_modes": []}

    def __init__(
        self,
        preset: str | None = DEFAULT_PRESET,  # type: ignore[assignment]
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
        control_dt_s: float | None = None,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        termination_cost: str = "hold",
        conditions=None,
        render_mode: str | None = None,
    ) -> None:
        cfg = configure(locals())
        self.preset = cfg.preset
        self.model, self.cost, self.decision_model = cfg.model, cfg.cost, cfg.decision_model
        self._x0_mean, self._x0_std = cfg.x0_mean, cfg.x0_std
        #: standard deviation of the process noise w per state entry
        self.process_noise_std = cfg.process_noise_std
        #: physical input of a unit action, per input (m)
        self.action_scale = cfg.action_scale
        #: the decision period (s), k = ``decision_steps`` plant steps of ``dt_s``
        self.control_dt_s = cfg.control_dt_s
        #: plant steps per env step, k = control_dt_s / dt_s (the input is held over them)
        self.decision_steps = cfg.decision_steps
        self.episode_steps = cfg.episode_steps
        self.divergence_threshold = cfg.divergence_threshold
        self._init_termination_cost(cfg.termination_cost, cfg.cost.Q, self.episode_steps)
        self.render_mode = None
        n, m = cfg.model.n, cfg.model.m
        sensors = cfg.sensors
        if sensors is None and cfg.conditions.sensors > 0:  # the flight sensors, scaled to this plant's state
            sensors = {"state": state_sensor_config(self.state_scale, cfg.conditions.sensors)}
        self._init_layers(
            n_actuators=m,
            actuator_limits=self.action_scale,
            channels=[Channel("state", n)],
            faults=faults,
            sensors=sensors,
            fault_hint=fault_hint,
            conditions=cfg.conditions,
            control_dt_s=self.control_dt_s,
        )
        low, high = self._hint_bounds(np.full(n, -cfg.obs_bound), np.full(n, cfg.obs_bound))
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(m,), dtype=np.float32)
        self._x = self._x0_mean.copy()
        self._steps = 0
        self._sensing = self.sensor_layer.enabled

    @property
    def episode_length_s(self) -> float:
        """An episode's time limit, s: ``episode_steps · dt_s``."""
        return self.episode_steps * float(self.model.dt_s)

    @property
    def state(self) -> np.ndarray:
        """The true state ``x`` (n), a copy."""
        return self._x.copy()

    @property
    def measured_entries(self) -> np.ndarray:
        """One bool per observation entry (before any fault flags): whether the sensors
        measure it; the ``state`` sensor measures every entry (all True; FuelSlosh's flight
        sensors leave some out)."""
        return np.ones(self.model.n, dtype=bool)

    @property
    def state_scale(self) -> np.ndarray:
        """Each state entry's typical scale (:func:`state_scale` of the reset distribution)."""
        return state_scale(self._x0_mean, self._x0_std)

    @property
    def reset_distribution(self) -> dict[str, np.ndarray]:
        """How :meth:`reset` draws ``x0 ~ N(x0_mean, diag(x0_std²))`` (read only, copies):
        ``x0_mean`` and ``x0_std`` (n, state units)."""
        return {"x0_mean": self._x0_mean.copy(), "x0_std": self._x0_std.copy()}

    @property
    def steps_taken(self) -> int:
        """Plant steps of ``dt_s`` taken in the current episode (``time_s = steps_taken · dt_s``)."""
        return self._steps

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, {"state", "faults"})
        n = self.model.n
        flight_rng = self._flight_rng(self.np_random)  # spawned: the start is the lab's of this seed
        if "state" in options:
            self._x = validation.finite_array("options['state']", options["state"], (n,)).copy()
        else:
            self._x = self._x0_mean + self._x0_std * self.np_random.normal(size=n)
        self._steps = 0
        self._reset_layers(self.np_random, options, flight_rng)
        self._sensing = self.sensor_layer.enabled  # fixed for the episode
        x = self._x.copy()
        truth = {"state": x, "faults": self._fault_truth(0.0)}
        if not self._sensing:
            info = self._make_info(truth=truth, measured=x.copy(), cost=0.0, time_s=0.0)
            return self._with_hint(x, 0.0), info
        readings = self.sensor_layer.measure({"state": x}, 0.0)
        info = self._make_info(truth=truth, measured=readings["state"], cost=0.0, time_s=0.0, sensors=readings)
        return self._with_hint(readings["state"], 0.0), info

    def step(self, action):
        a = np.clip(validation.action(action, self.model.m), -1.0, 1.0)
        t_s = self._steps * self.model.dt_s
        commanded = self.action_scale * a
        u = self._deliver(commanded, t_s)  # faults; in flight the delay and the gains
        x = self._x
        x_next = np.empty_like(x)
        k, noisy = self.decision_steps, self.process_noise_std > 0
        if k == 1:
            cost = linear_kernels.linear_step(x, u, self.model.A, self.model.B, self.cost.Q, self.cost.R, x_next)
            if noisy:
                x_next = x_next + self.process_noise_std * self.np_random.normal(size=self.model.n)
        elif noisy:  # the k plant steps one by one, each with its draw of w
            noise = self.process_noise_std * self.np_random.normal(size=(k, self.model.n))
            cost = linear_hold.noisy_held_steps(
                x, u, self.model.A, self.model.B, self.cost.Q, self.cost.R, noise, x_next
            )
        else:  # exact discretization over the decision period
            d = self.decision_model
            cost = linear_hold.held_step(x, u, d.A, d.B, d.Q, d.N, d.R, x_next)
        self._x = x_next
        self._steps += k  # plant steps: time, fault onsets, time limit and termination charge
        t_next = self._steps * self.model.dt_s
        finite = bool(np.isfinite(x_next).all())
        terminated = not finite or bool(np.abs(x_next).max() > self.divergence_threshold)
        if terminated and finite:  # diverged: the rest of the horizon is charged, per step
            cost += self._termination_charge(x_next, self._steps)
        truncated = self._steps >= self.episode_steps and not terminated
        # actuator faults as applied over this step, sensor faults at the observation time
        truth = {
            "state": x_next.copy(),
            "previous_state": x.copy(),
            "applied": u,
            "faults": self._fault_truth(t_s, t_next),
        }
        if not self._sensing:
            measured = x_next.copy()
            public = {"commanded": commanded}
        elif finite:
            readings = self.sensor_layer.measure({"state": x_next}, t_next)
            measured = readings["state"]
            public = {"commanded": commanded, "sensors": readings}
        else:  # no sensor sample of a diverged state
            measured = np.full(self.model.n, np.nan)
            public = {"commanded": commanded, "sensors": {"state": measured}}
        info = self._make_info(truth=truth, measured=measured, cost=cost, time_s=t_next, **public)
        obs = self._with_hint(measured, t_next) if finite else np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, info


def decision_period(control_dt_s: float, dt_s: float) -> float:
    """``control_dt_s`` (s) checked to be a whole multiple ``k ≥ 1`` of ``dt_s`` (s; relative
    tolerance 1e-9); a ``ValueError`` naming both and the accepted values otherwise."""
    value = validation.positive("control_dt_s", control_dt_s)
    k = round(value / dt_s)
    if k < 1 or abs(k * dt_s - value) > 1e-9 * value:
        raise ValueError(
            f"control_dt_s must be a whole multiple k >= 1 of dt_s={dt_s:g} (k·{dt_s:g} s: {dt_s:g}, "
            f"{2 * dt_s:g}, {3 * dt_s:g}, ...), got {control_dt_s!r}"
        )
    return value


@dataclass(frozen=True)
class LinearSystemConfig:
    """The validated keywords of :class:`LinearSystemEnv` and what follows from them (the
    plant step ``model``, its stage ``cost``, the decision period's ``decision_model``, the
    observation bound ``obs_bound``); ``faults``, ``sensors`` and ``fault_hint`` as given
    (the env's fault and sensor layers validate them)."""

    preset: str | None
    model: LinearModel
    cost: QuadraticCost
    x0_mean: np.ndarray
    x0_std: np.ndarray
    process_noise_std: float
    action_scale: np.ndarray
    control_dt_s: float
    decision_steps: int
    decision_model: LinearModel
    episode_steps: int
    divergence_threshold: float
    termination_cost: str
    conditions: Conditions
    faults: list[dict] | None
    sensors: dict | None
    fault_hint: bool
    obs_bound: float


def configure(given: Mapping[str, Any]) -> LinearSystemConfig:
    """:class:`LinearSystemEnv`'s keywords ``given`` (every one: the constructor's
    ``locals()``) resolved (preset, then the keywords given) and validated, with the same
    ``ValueError`` for a bad one; the env and the JAX plant (:mod:`attitude_envs.jax.linear_system`)
    are both built from it."""
    preset = given["preset"]
    if preset is DEFAULT_PRESET:  # a user's own system takes no preset values
        own = given["A"] is not None or given["B"] is not None
        preset = None if own else LinearSystemEnv.default_preset
    overrides = {k: v for k, v in given.items() if k not in ("self", "__class__", "preset", "render_mode")}
    cfg = presets.resolve(ENV, preset, overrides, constructor_keywords(LinearSystemEnv))
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
    dt = validation.positive("dt_s", cfg.get("dt_s", 1.0))
    model = LinearModel(a_mat, b_mat, cost.Q, cost.R, np.zeros((n, m)), dt)
    x0_mean = validation.finite_array("x0_mean", cfg.get("x0_mean", np.zeros(n)), (n,))
    std = validation.finite_array("x0_std", cfg.get("x0_std", 1.0))
    x0_std = np.broadcast_to(std, (n,)).copy() if std.ndim == 0 else validation.finite_array("x0_std", std, (n,))
    if np.any(x0_std < 0):
        raise ValueError(f"x0_std must be >= 0, got {x0_std.tolist()}")
    noise_std = validation.nonnegative("process_noise_std", given["process_noise_std"])
    scale = validation.finite_array("action_scale", cfg.get("action_scale", 1.0))
    action_scale = np.broadcast_to(scale, (m,)).copy() if scale.ndim == 0 else scale
    if action_scale.shape != (m,) or np.any(action_scale <= 0):
        raise ValueError(f"action_scale must be > 0, a scalar or length {m}, got {scale.tolist()}")
    period = dt if cfg.get("control_dt_s") is None else decision_period(cfg["control_dt_s"], dt)
    k = round(period / dt)
    held = linear_hold.hold_model(model, k)
    steps = validation.integer("episode_steps", given["episode_steps"], 1)
    if steps % k:
        raise ValueError(
            f"episode_steps must be a multiple of the plant steps per decision k = control_dt_s / dt_s = "
            f"{period:g} / {dt:g} = {k}, got episode_steps={steps}"
        )
    threshold = validation.positive("divergence_threshold", given["divergence_threshold"])
    mode = validation.choice("termination_cost", given["termination_cost"], TERMINATION_COSTS)
    if given["render_mode"] is not None:
        raise ValueError(f"render_mode must be None for {ENV}, got {given['render_mode']!r}")
    # |x⁺|∞ <= ‖A‖∞ |x|∞ + ‖B‖∞ |u|∞ (+ noise, 10σ margin) while |x|∞ <= divergence_threshold;
    # over k held steps A_k = Aᵏ, B_k and the noise Σ_{i<k} Aⁱ w_{k−1−i}.
    noise_gain = 1.0
    if k > 1 and noise_std > 0:
        noise_gain, power = 0.0, np.eye(n)
        for _ in range(k):  # construction only: Σ_{i<k} ‖Aⁱ‖∞
            noise_gain += float(np.linalg.norm(power, np.inf))
            power = a_mat @ power
    bound = (
        threshold * max(1.0, np.linalg.norm(held.A, np.inf))
        + np.linalg.norm(held.B, np.inf) * float(np.max(action_scale))
        + 10.0 * noise_std * noise_gain
    )
    return LinearSystemConfig(
        preset=preset,
        model=model,
        cost=cost,
        x0_mean=x0_mean,
        x0_std=x0_std,
        process_noise_std=noise_std,
        action_scale=action_scale,
        control_dt_s=period,
        decision_steps=k,
        decision_model=held,
        episode_steps=steps,
        divergence_threshold=threshold,
        termination_cost=mode,
        conditions=Conditions.from_config(given["conditions"]),
        faults=given["faults"],
        sensors=given["sensors"],
        fault_hint=given["fault_hint"],
        obs_bound=bound,
    )
