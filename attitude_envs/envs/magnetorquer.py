"""Magnetorquer-v0: nano-satellite with three magnetorquers and one y-axis wheel (Sadigh,
Kashaninia & Dehghan 2022)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from attitude_envs import presets, quaternion, validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.envs.base import TERMINATION_COSTS, AttitudeEnv, Layers, build_layers, constructor_keywords
from attitude_envs.evaluation.success import FINAL_ERROR_DEG
from attitude_envs.integrators import substeps
from attitude_envs.plants import magnetorquer as mt
from attitude_envs.plants import magnetorquer_kernels as kernels
from attitude_envs.plants.magnetic_field import FieldModel
from attitude_envs.plants.orbit import KeplerOrbit
from attitude_envs.presets import flight
from attitude_envs.presets.sadigh_2022 import TIME_VARYING_INERTIA
from attitude_envs.sensors import Channel
from attitude_envs.trajectories import SmoothBangBang
from attitude_envs.uncertainty import InertiaUncertainty

_OPTION_KEYS = {"attitude", "rate_rad_s", "wheel_speed_rad_s", "faults", "mean_anomaly_deg"}
_ORBIT_KEYS = (
    "model",
    "apogee_altitude_km",
    "perigee_altitude_km",
    "inclination_deg",
    "raan_deg",
    "arg_perigee_deg",
    "mean_anomaly_deg",
)
_REFERENCE_KEYS = ("delta_deg", "t_final_s", "start_deg")
# The keywords that must come from the preset or the caller.
_REQUIRED = (
    "inertia_kg_m2",
    "wheel_inertia_kg_m2",
    "max_dipole_am2",
    "max_wheel_torque_nm",
    "max_wheel_momentum_nms",
    "orbit",
    "reference",
    "field_model",
    "dipole_strength_t_m3",
    "control_dt_s",
    "Q",
    "R",
)


def _slice(offset: int, start: int, size: int) -> slice:
    return slice(offset + start, offset + start + size)


# The info's entries in ``[state (8), step outputs, snapshot]`` (built once: the hot path slices)
_ST, _SN = 8, 8 + kernels.STEP_OUT_SIZE
_V_APPLIED = _slice(_ST, kernels.ST_APPLIED, 4)
_V_TAU = _slice(_ST, kernels.ST_TAU, 3)
_V_CONTROL = _slice(_ST, kernels.ST_CONTROL, 3)
_V_BBODY = _slice(_SN, kernels.SN_BBODY, 3)
_V_WBI = _slice(_SN, kernels.SN_WBI, 3)
_V_QD = _slice(_SN, kernels.SN_QD, 4)
_V_WD = _slice(_SN, kernels.SN_WD, 3)
_V_QDOT = _slice(_SN, kernels.SN_QDOT, 4)
_V_BORB = _slice(_SN, kernels.SN_BORB, 3)
_V_EXT = _slice(_SN, kernels.SN_EXT, 3)
_V_INERTIA = _slice(_SN, kernels.SN_I, 9)
_SN_HW, _SN_ANGLE, _SN_R, _SN_U, _SN_RATE = kernels.SN_HW, kernels.SN_ANGLE, kernels.SN_R, kernels.SN_U, kernels.SN_RATE
FIELD_SCALE_T = kernels.FIELD_SCALE_T  # observation scale of the body-frame field
WHEEL_SPEED_SCALE_RAD_S = kernels.WHEEL_SPEED_SCALE_RAD_S  # observation scale of the wheel speed


@dataclass(frozen=True)
class MagnetorquerModel:
    """The nominal model a model-based controller may use (``env.unwrapped.model``).

    ``params`` holds the nominal inertia ``J_t`` (with the wheel's spin inertia), the wheel
    and the limits; ``orbital_rate_rad_s`` is the mean motion ω0 (the paper's constant
    orbital rate); ``reference`` the desired trajectory; ``cost`` the Q, R of the reward on
    ``x = [q_e,vec, ω_e]`` and the body control torque ``u = m × b + e_y T_w``.
    """

    params: mt.MagnetorquerParams
    orbital_rate_rad_s: float
    inclination_rad: float
    reference: SmoothBangBang
    cost: QuadraticCost
    control_dt_s: float


class MagnetorquerEnv(AttitudeEnv):
    """Attitude tracking or regulation of a nano-satellite with three magnetorquers and one
    reaction wheel on the body y axis.

    **Description.** The spacecraft of Sadigh, Kashaninia & Dehghan (2022), "fault-tolerant
    adaptive modified nonsingular fast terminal sliding-mode control" (Journal of Control
    15(4), DOI 10.52547/joc.15.4.49): a 0.95 kg·m² nano-satellite on an elliptic
    311 × 1250 km orbit, inclination 69.5°, with 0.5 A·m² magnetorquers on three axes and a
    small wheel on y, tracking a smooth 3-2-1 Euler slew relative to the orbital (LVLH)
    frame. Plant: :mod:`attitude_envs.plants.magnetorquer` (exact gyrostat equations with
    one wheel, attitude relative to the orbital frame); orbit
    :mod:`attitude_envs.plants.orbit`; field :mod:`attitude_envs.plants.magnetic_field`.
    Fixed-step RK4 with the stage cost as an extra state, quaternion renormalized after every
    sub-step; each step is one compiled call
    (:func:`attitude_envs.plants.magnetorquer_kernels.advance`).

    **Action space.** ``Box(-1, 1, (4,), float32)``, clipped: dipoles
    ``m = a[:3] · max_dipole_am2`` (A·m²) and the wheel torque on the body about +y
    ``T_w = a[3] · max_wheel_torque_nm`` (N·m; the motor applies −T_w to the wheel, the
    paper's eq. 7). The magnetic torque is ``m × b``: none along the field.

    **Observation space.** ``Box(float32)`` of ``[q_e,vec (3), ω_e (3, rad/s), Ω/1000
    (1, krad/s)]``, ``q_e = q_d* ⊗ q`` (w ≥ 0), ``ω_e = ω_bo − C(q_e)ᵀ ω_d``; plus the body
    field ``b / 5e-5 T`` (3) with ``observe_field``; plus 8 fault flags with ``fault_hint``
    (4 actuators: m_x, m_y, m_z, wheel; 4 sensor channels: gyro, star tracker, tachometer,
    magnetometer). With sensors the observation is built from the measurements. Bounds: rates
    within 2 × ``max_rate_rad_s``, ``Ω/1000`` within ±1000, field entries within ±3 (1.5e-4 T).
    The step that crosses a limit observes its measurement clipped to the bounds
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`; ``info["truth"]`` holds
    the true state).

    **Reward.** ``−∫ (xᵀQx + uᵀRu) dt`` over the step, ``x = [q_e,vec, ω_e]``,
    ``u = m_applied × b + e_y T_w,applied`` (body torque, N·m).

    **Starting state.** Tracking: q = q_d(0), ω_bo = 0, Ω = 0 (the paper's start).
    Regulation: q within ``initial_angle_deg`` of the target, ω_bo uniform in
    ±``initial_rate_max_rad_s``. The start on the orbit is drawn from the seed (or fixed by
    ``orbit["mean_anomaly_deg"]``). ``reset(options=...)`` pins ``attitude`` (scalar-last
    quaternion), ``rate_rad_s`` (ω_bo), ``wheel_speed_rad_s`` (1), ``mean_anomaly_deg`` and
    ``faults`` (this episode's fault list).

    **Episode end.** Terminated on a non-finite state or ``max|ω_bo| > max_rate_rad_s``;
    truncated when the simulated time reaches ``episode_duration_s`` (default two orbital
    periods, the paper's 12 038 s).
    A step that crosses a limit (with a finite state) is charged, on top of its running
    cost, the terminal error state's running cost held over the rest of the episode,
    ``(episode_duration_s − t) xᵀQx`` (``termination_cost="hold"``; ``"none"``: nothing
    more), so ending an episode early never lowers J.

    **Arguments.** Where the default column says "preset", ``None`` (the default) takes the
    preset's value; the preset ``sadigh-2022`` gives every physical value with its source
    (:mod:`attitude_envs.presets.sadigh_2022`). ``disturbance`` and ``time_varying_inertia``
    default to the paper's models (eqs. 39 and 35); ``None`` switches either off.

    ===============================  ============  ==================  ========  ==========================================
    name                             type          default             unit      description
    ===============================  ============  ==================  ========  ==========================================
    ``preset``                       str           "sadigh-2022"       —         parameter set (:mod:`attitude_envs.presets`;
                                                                                 None: the default preset)
    ``task``                         str           ``"tracking"``      —         ``"tracking"`` the ``reference`` slew or
                                                                                 ``"regulation"`` to ``target_euler_deg``
    ``reference``                    dict          preset              deg, s    ``delta_deg`` (3-2-1 Euler slew),
                                                                                 ``t_final_s``, ``start_deg``; keys left out
                                                                                 are the preset's
    ``target_euler_deg``             3 floats      (0, 0, 0)           deg       regulation target (3-2-1 Euler)
    ``initial_angle_deg``            float         10                  deg       regulation: start within this angle
    ``initial_rate_max_rad_s``       float         0 / 1e-3            rad/s     start rate bound (tracking / regulation)
    ``inertia_kg_m2``                3×3           preset              kg·m²     nominal ``J_t`` with the wheel's spin
    ``wheel_inertia_kg_m2``          float         preset (50e-6)      kg·m²     wheel spin inertia J_w
    ``max_dipole_am2``               float         preset (0.5)        A·m²      dipole limit per axis
    ``max_wheel_torque_nm``          float         preset (2.3e-4)     N·m       wheel torque limit
    ``max_wheel_momentum_nms``       float         preset (40)         N·m·s     storable momentum (torque that would
                                                                                 raise ``|h_w|`` past it is blocked)
    ``orbit``                        dict          preset              km, deg   ``model`` ("keplerian"/"circular"),
                                                                                 ``apogee_altitude_km``,
                                                                                 ``perigee_altitude_km``,
                                                                                 ``inclination_deg``, ``raan_deg``,
                                                                                 ``arg_perigee_deg``, ``mean_anomaly_deg``
                                                                                 (number or "random"); keys left out are
                                                                                 the preset's
    ``field_model``                  str           preset ("dipole")   —         "dipole", "dipole-printed", "igrf"
    ``dipole_strength_t_m3``         float         preset (7.96e15)    T·m³      dipole strength μ_e
    ``field_epoch``                  str           2020-01-01          —         IGRF epoch (ISO date-time)
    ``observe_field``                bool          False               —         append the body field to the observation
    ``disturbance``                  str/dict      ``"paper"``         N·m       "paper" (eq. 39, ×``disturbance_scale``),
                                                                                 a dict of :mod:`attitude_envs.disturbances`,
                                                                                 or None
    ``disturbance_scale``            float         1                   —         scale of the "paper" disturbance
    ``disturbance_second_harmonic``  bool          False               —         eq. 39's second term at 2ω0
    ``gravity_gradient``             bool          False               —         add the gravity-gradient torque
    ``time_varying_inertia``         str/dict      ``"paper"``         kg·m², s  ΔJ(t): "paper" (eq. 35), a dict (keys
                                                                                 left out are eq. 35's) or None
    ``inertia_uncertainty``          dict          None                —         random dispersions
                                                                                 (:mod:`attitude_envs.uncertainty`)
    ``control_dt_s``                 float         preset (0.1)        s         control period (zero-order hold)
    ``integrator_dt_s``              float         ``control_dt_s``    s         RK4 sub-step
    ``episode_duration_s``           float         two orbits          s         episode length
    ``Q``, ``R``                     6×6, 3×3      preset              —         cost weights
    ``max_rate_rad_s``               float         1                   rad/s     tumbling limit (terminates)
    ``faults``                       list[dict]    preset (none)       —         :mod:`attitude_envs.faults`; actuators
                                                                                 0–2 dipoles, 3 wheel
    ``sensors``                      dict          None                —         :mod:`attitude_envs.sensors`
    ``fault_hint``                   bool          False               —         append the 8 active-fault flags
    ``termination_cost``             str           "hold"              —         ``"hold"``: charge tumbling (see Episode
                                                                                 end); ``"episode"`` (v1): ``T·xᵀQx``; ``"none"``: none
    ``conditions``                   str/dict      "lab"               —         ``"lab"``, ``"flight"`` or a dict of
                                                                                 features (:mod:`attitude_envs.conditions`;
                                                                                 values :mod:`~attitude_envs.presets.flight_magnetorquer`)
    ===============================  ============  ==================  ========  ==========================================

    **Presets.** ``"sadigh-2022"`` (default): the paper's spacecraft, orbit and actuators
    (Table 1, eqs. 34, 9), healthy. ``"sadigh-2022-faults"``: the same with the paper's
    magnetorquer faults of eq. (40), ``E = diag(0.9, 0.7, 0.6)`` from t = 50 s.

    **Faults and sensors.** Faults (:mod:`attitude_envs.faults`) act on the commanded
    outputs, actuator 0–2 the dipoles (A·m²), 3 the wheel torque (N·m); entries with
    ``"target": "sensor"`` act on the sensors. Sensor channels (:mod:`attitude_envs.sensors`):
    ``gyro`` (inertial rate ω_bi, body axes, rad/s), ``star_tracker`` (attitude relative to
    the orbital frame), ``tachometer`` (wheel speed, rad/s), ``magnetometer`` (body field, T).

    **Info** (:mod:`attitude_envs.info`). ``info["truth"]``: ``state`` (``attitude`` q,
    ``rate_rad_s`` ω_bo, ``inertial_rate_rad_s`` ω_bi, ``wheel_speed_rad_s`` (1),
    ``wheel_momentum_nms`` J_w(Ω + ω_bi,y)), ``applied`` (4: dipoles after faults, wheel
    torque after faults and the momentum limit; step means), ``faults``,
    ``error_angle_deg``, ``disturbance_torque_nm`` (disturbance + gravity gradient),
    ``true_inertia_kg_m2``, ``magnetic_torque_nm`` and ``control_torque_nm`` (step means),
    ``magnetic_field_body_t`` (the true body field) and, with sensors, ``sensor_bias``.
    ``info["measured"]``: the keys of ``truth["state"]`` **plus** ``magnetic_field_body_t``,
    from the star tracker, gyro, tachometer and magnetometer readings when sensors are on
    (ω_bo = gyro − R ω_oi of the measured attitude, the momentum from the measured wheel
    speed and gyro), else the truth's arrays. Top level: ``cost``, ``time_s``,
    ``commanded`` (4, before faults), ``reference`` (``attitude``, ``rate_rad_s``,
    ``attitude_rate``: the commanded trajectory), ``orbit`` (``radius_m``,
    ``argument_of_latitude_rad``, ``rate_rad_s``: the known ephemeris),
    ``magnetic_field_orbital_t`` (the field model in the orbital frame) and, with sensors,
    ``sensors`` (raw readings).

    **Public extension interface** (the batched env and tools use only these and the base's
    ``fault_layer``, ``sensor_layer``, ``disturbance``): :attr:`kernel_constants`,
    :attr:`episode_constants`, :attr:`snapshot`, :attr:`state_row`,
    :attr:`observation_size`, :attr:`field`, :meth:`advance_disturbance`,
    :meth:`true_inertia_at`, :meth:`external_torque_at`, :meth:`error_state`.

    **Success** (:mod:`attitude_envs.evaluation.success`): ``success_metric`` is
    ``FINAL_ERROR_DEG``, the final attitude error angle to the reference (deg, default
    threshold 2°).

    **Version history.** v1 (``attitude_envs/Magnetorquer-v1``, 2026-11-27): the learning task — decisions every 10 s over 0.5 s RK4 sub-steps, 300 s of the slew (30 decisions), the geomagnetic field in the observation (``observe_field``: the only torque is m × b) and a limit crossing charged ``T·xᵀQx`` (``termination_cost="episode"``); the plant, orbit, field and J are v0's. v0: a limit crossing charged the terminal running cost over the rest of the episode (``termination_cost``, 2026-11); the plant, orbit, field and reference of the paper; ``info``
    split into ``truth`` and ``measured`` (:mod:`attitude_envs.info`), the paper's values
    as presets.
    """

    env_name = "Magnetorquer-v0"
    default_preset = "sadigh-2022"
    success_metric = FINAL_ERROR_DEG
    metadata = {"render_modes": []}

    task_keywords = AttitudeEnv.task_keywords | {"observe_field"}

    def __init__(
        self,
        task: str = "tracking",
        reference: dict | None = None,
        target_euler_deg=(0.0, 0.0, 0.0),
        initial_angle_deg: float = 10.0,
        initial_rate_max_rad_s: float | None = None,
        inertia_kg_m2=None,
        wheel_inertia_kg_m2: float | None = None,
        max_dipole_am2: float | None = None,
        max_wheel_torque_nm: float | None = None,
        max_wheel_momentum_nms: float | None = None,
        orbit: dict | None = None,
        field_model: str | None = None,
        dipole_strength_t_m3: float | None = None,
        field_epoch: str = "2020-01-01T00:00:00",
        observe_field: bool = False,
        disturbance: str | dict | None = "paper",
        disturbance_scale: float = 1.0,
        disturbance_second_harmonic: bool = False,
        gravity_gradient: bool = False,
        time_varying_inertia: str | dict | None = "paper",
        inertia_uncertainty: dict | None = None,
        control_dt_s: float | None = None,
        integrator_dt_s: float | None = None,
        episode_duration_s: float | None = None,
        Q=None,
        R=None,
        max_rate_rad_s: float = 1.0,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        termination_cost: str = "hold",
        conditions=None,
        render_mode: str | None = None,
        preset: str | None = None,  # last: positional callers of the earlier signature keep working
    ) -> None:
        cfg = configure(type(self), preset, locals())
        self.preset = cfg.preset
        self.task = cfg.task
        self._orbit_cfg = cfg.orbit_config
        self._random_anomaly = cfg.random_anomaly
        self.orbit = cfg.orbit
        #: the Earth field model along the orbit (its ``table`` is the episode's IGRF table)
        self.field = cfg.field
        self.observe_field = cfg.observe_field
        #: True when the disturbance is the paper's eq. (39) (compiled; ``disturbance`` is then None)
        self.paper_disturbance = cfg.paper_disturbance
        self.disturbance_scale = cfg.disturbance_scale
        self.disturbance_second_harmonic = cfg.disturbance_second_harmonic
        self.gravity_gradient = cfg.gravity_gradient
        #: ΔJ(t) added to the true inertia (:class:`~attitude_envs.plants.magnetorquer.TimeVaryingInertia`), or None
        self.time_varying_inertia = cfg.time_varying_inertia
        self._uncertainty = cfg.inertia_uncertainty
        self.control_dt_s = cfg.control_dt_s
        self.integrator_dt_s = cfg.integrator_dt_s
        self._substeps = cfg.n_substeps
        self.episode_duration_s = cfg.episode_duration_s
        self._initial_angle = cfg.initial_angle_deg
        self._rate_max = cfg.initial_rate_max_rad_s
        self.model = cfg.model
        self._use_layers(cfg.layers)
        self._flight_inertia = cfg.flight_inertia
        self.max_rate_rad_s = cfg.max_rate_rad_s
        self._init_termination_cost(cfg.termination_cost, cfg.model.cost.Q, self.episode_duration_s)
        self.render_mode = None
        params = cfg.model.params

        self.observation_space = spaces.Box(*observation_bounds(cfg), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)

        self._inertia = params.inertia_kg_m2
        self._y = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
        self._t = 0.0
        self._meas: dict[str, np.ndarray] = {}
        self._meas_state: dict[str, Any] = {}
        self._steps = 0
        self._shared = pack_shared(cfg)
        self._env_vec = self._pack_env()
        self._work = np.zeros(kernels.WORK_SIZE)
        self._step_out = np.zeros(kernels.STEP_OUT_SIZE)
        self._snap = np.zeros(kernels.SNAPSHOT_SIZE)
        self._n_obs = 10 if self.observe_field else 7
        self._limits = params.limits

    # ------------------------------------------------------------------ construction helpers
    def _disturbance_vector(self) -> np.ndarray:
        """The per-episode disturbance entry of the compiled step: the held torque (constant,
        random walk) or the sinusoid's phases."""
        dist = self._disturbance
        if dist is None:
            return np.zeros(3)
        if dist.kind == "sinusoidal":
            return dist.episode_phase_rad
        return dist.torque_nm if dist.kind == "constant" else dist.walk_nm

    def _pack_env(self) -> np.ndarray:
        """This episode's draws in the compiled step's layout (:func:`kernels.pack_env`)."""
        eff = self._inertia.copy()
        eff[1, 1] -= self.model.params.wheel_inertia_kg_m2
        return kernels.pack_env(self._inertia, np.linalg.inv(eff), self.orbit.packed, self._disturbance_vector())

    # ------------------------------------------------------------------ public interface
    @property
    def kernel_constants(self) -> np.ndarray:
        """The compiled step's configuration (:func:`~attitude_envs.plants.magnetorquer_kernels.pack_shared`:
        wheel, limits, step sizes, field and disturbance models, cost weights, reference);
        the same for every env built with the same keywords. Do not modify."""
        return self._shared

    @property
    def episode_constants(self) -> np.ndarray:
        """This episode's draws in the compiled step's layout
        (:func:`~attitude_envs.plants.magnetorquer_kernels.pack_env`: true inertia, its
        effective inverse, the orbit, the disturbance entry), a read-only view (it follows
        the env: copy it to keep it)."""
        view = self._env_vec.view()
        view.setflags(write=False)
        return view

    @property
    def snapshot(self) -> np.ndarray:
        """The observation and info quantities at the current state (layout ``SN_*`` of
        :mod:`~attitude_envs.plants.magnetorquer_kernels`), a read-only view."""
        view = self._snap.view()
        view.setflags(write=False)
        return view

    def batch_termination(self, states: np.ndarray) -> np.ndarray:
        """The tumbling limit :meth:`step` terminates on (the plant definition's limit rows) for
        rows of states ``[q, ω_bo, Ω]`` (E × 8); the batched env's hook (it checks finiteness)."""
        states = np.asarray(states, dtype=float)
        out = np.empty(states.shape[0], dtype=bool)
        kernels.tumbling_rows(states, self.max_rate_rad_s, out)
        return out

    @property
    def state_row(self) -> np.ndarray:
        """The true physical state ``[q (4, body rel. orbital frame, scalar last), ω_bo (3,
        rad/s), Ω (1, rad/s)]``, a read-only view (it follows the env: copy it to keep it)."""
        view = self._y.view()
        view.setflags(write=False)
        return view

    @property
    def reset_distribution(self) -> dict[str, Any]:
        """How :meth:`reset` draws an episode (read only): ``task``, ``initial_angle_deg``
        (regulation: the start within this angle of the target, deg),
        ``initial_rate_max_rad_s`` (ω_bo uniform in ±this, rad/s), ``mean_anomaly_deg`` (a
        number, deg, or ``"random"``: uniform in [0, 360)) and ``inertia_uncertainty`` (an
        :class:`~attitude_envs.uncertainty.InertiaUncertainty`, or None)."""
        return {
            "task": self.task,
            "initial_angle_deg": self._initial_angle,
            "initial_rate_max_rad_s": self._rate_max,
            "mean_anomaly_deg": self._orbit_cfg["mean_anomaly_deg"],
            "inertia_uncertainty": self._uncertainty,
        }

    @property
    def steps_taken(self) -> int:
        """Control steps taken in the current episode (``time_s = steps_taken · control_dt_s``)."""
        return self._steps

    @property
    def observation_size(self) -> int:
        """Entries of the observation the compiled step builds (7, or 10 with
        ``observe_field``; without the ``fault_hint`` flags)."""
        return self._n_obs

    def advance_disturbance(self) -> None:
        """Move the disturbance one control period on (a random walk draws from the env's
        generator) and store its new entry in :attr:`episode_constants` (entries
        ``EN_DIST:EN_DIST + 3``). The env's ``step`` calls it; the batched env calls it per
        sub-env. Needs a :attr:`disturbance` (not the compiled "paper" one)."""
        self._disturbance.advance(self.np_random, self.control_dt_s)
        self._env_vec[kernels.EN_DIST : kernels.EN_DIST + 3] = self._disturbance_vector()

    def true_inertia_at(self, t_s: float) -> np.ndarray:
        """The true inertia ``I + ΔJ(t)`` of the plant at ``t_s``, kg·m² (evaluation truth)."""
        return self._snapshot(t_s, self._y)[kernels.SN_I : kernels.SN_I + 9].reshape(3, 3)

    def external_torque_at(self, t_s: float, q: np.ndarray) -> np.ndarray:
        """Disturbance (+ gravity gradient when enabled) on the body at attitude ``q``, N·m."""
        y = self._y.copy()
        y[:4] = q
        return self._snapshot(t_s, y)[kernels.SN_EXT : kernels.SN_EXT + 3]

    def error_state(self) -> np.ndarray:
        """The true error state ``x = [q_e,vec, ω_e]`` (float64) now."""
        return self._snapshot(self._t, self._y)[kernels.SN_X : kernels.SN_X + 6]

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        rng = self.np_random
        nominal = self.model.params.inertia_kg_m2
        flight_rng = self._flight_rng(rng)  # spawned: rng's stream is the lab's
        self._inertia = nominal if self._uncertainty is None else self._uncertainty.draw(nominal, rng)
        if self._flight_inertia is not None:
            self._inertia = self._flight_inertia.draw(nominal, flight_rng)
        if self.conditions.parameters > 0:  # the true inertia (drawn by inertia_uncertainty when given)
            self._drawn["inertia_kg_m2"] = self._inertia.copy()
        if self.time_varying_inertia is not None and self._inertia is not nominal:
            self.time_varying_inertia.check_against(self._inertia)
        if "mean_anomaly_deg" in options:
            anomaly = float(validation.finite_array("options['mean_anomaly_deg']", options["mean_anomaly_deg"], ()))
        else:
            anomaly = (
                float(rng.uniform(0.0, 360.0)) if self._random_anomaly else float(self._orbit_cfg["mean_anomaly_deg"])
            )
        self.orbit = make_orbit(self._orbit_cfg, anomaly)
        self.field.prepare(self.orbit, self.episode_duration_s + self.control_dt_s)
        q_d, _, _ = self.model.reference.attitude(0.0)
        if self.task == "tracking":
            q0 = q_d.copy()
        else:
            q0 = quaternion.multiply(q_d, quaternion.random_within_angle(rng, self._initial_angle))
        rate = rng.uniform(-self._rate_max, self._rate_max, 3) if self._rate_max > 0 else np.zeros(3)
        wheel = np.zeros(1)
        if "attitude" in options:
            q0 = validation.unit_quaternion("options['attitude']", options["attitude"])
        if "rate_rad_s" in options:
            rate = validation.finite_array("options['rate_rad_s']", options["rate_rad_s"], (3,))
        if "wheel_speed_rad_s" in options:
            wheel = validation.finite_array("options['wheel_speed_rad_s']", options["wheel_speed_rad_s"], (1,))
        self._y = np.concatenate([q0, rate, wheel])
        self._t = 0.0
        self._steps = 0
        self._reset_layers(rng, options, flight_rng)  # disturbance, sensors (own spawned generator), faults
        self._env_vec = self._pack_env()
        self._work[kernels.WK_TAG] = np.nan  # new draws: no context to reuse
        kernels.snapshot_into(
            self._y,
            0.0,
            self._shared,
            self._env_vec,
            self.field.table,
            self._work[kernels.WK_C0 : kernels.WK_C0 + kernels.CONTEXT_SIZE],
            self._snap,
        )
        self._step_out[:] = 0.0
        if self._sensor_layer.enabled:
            self._measure()
        return self._observation(), self._info(np.zeros(4), 0.0)

    def step(self, action):
        a = validation.action(action, 4)
        commanded = np.minimum(np.maximum(a, -1.0), 1.0) * self._limits
        delivered = self._deliver(commanded, self._t, self._friction_speeds())
        if self._disturbance is not None:  # the held torque may change between steps
            self.advance_disturbance()
        t0 = self._t
        self._steps += 1
        self._t = self._steps * self.control_dt_s  # from the step count: onsets and the time limit do not drift
        cost = kernels.advance(
            self._y,
            delivered,
            t0,
            self._t,
            self._shared,
            self._env_vec,
            self.field.table,
            self._step_out,
            self._snap,
            self._work,
        )
        finite = self._step_out[kernels.ST_FINITE] == 1.0
        terminated = not finite or kernels.tumbling(self._y, self.max_rate_rad_s)
        if terminated and finite:  # tumbling: the rest of the horizon is charged
            cost += self._termination_charge(self._snap[kernels.SN_X : kernels.SN_X + 6], self._t)
        truncated = bool(self._t >= self.episode_duration_s - 1e-9 * self.control_dt_s) and not terminated
        if self._sensor_layer.enabled:
            self._measure()
        obs = self._observation() if finite else np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, self._info(commanded, cost)

    # ------------------------------------------------------------------ internals
    def _friction_speeds(self) -> np.ndarray | None:
        """The speeds the wheel friction of the actuator dynamics acts against, one per
        actuator (None without actuator dynamics): zeros for the dipoles, and the wheel's
        speed negated, because ``T_w`` is the torque on the body (the wheel receives −T_w),
        so friction that opposes the wheel's spin adds ``+coulomb·sign(Ω)`` to ``T_w``."""
        if self._actuator_chain is None or self._actuator_chain.model is None:
            return None
        return np.array([0.0, 0.0, 0.0, -self._y[7]])

    def _snapshot(self, t_s: float, y: np.ndarray) -> np.ndarray:
        """A fresh :func:`kernels.snapshot_into` of state ``y`` at ``t_s`` (layout ``SN_*``)."""
        out = np.empty(kernels.SNAPSHOT_SIZE)
        ctx = np.empty(kernels.CONTEXT_SIZE)
        kernels.snapshot_into(y, float(t_s), self._shared, self._env_vec, self.field.table, ctx, out)
        return out

    def _error_state(self, q: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """``[q_e,vec, ω_e]`` of ``q``, ``rate`` against the reference of the last snapshot."""
        x, y, z, w = (float(v) for v in q)
        r0, r1, r2 = (float(v) for v in rate)
        return np.array(kernels.error_state(x, y, z, w, r0, r1, r2, self._snap, kernels.SN_QD, True)[:6])

    def _measure(self) -> None:
        """Read the sensors at the current state (when they are modelled): the raw readings
        and the measured state of ``info["measured"]``."""
        snap = self._snap
        truth = {
            "gyro": snap[kernels.SN_WBI : kernels.SN_WBI + 3].copy(),
            "star_tracker": self._y[:4],
            "tachometer": self._y[7:],
            "magnetometer": snap[kernels.SN_BBODY : kernels.SN_BBODY + 3].copy(),
        }
        meas = self._sensor_layer.measure(truth, self._t)
        self._meas = meas
        q, gyro, wheel = meas["star_tracker"], meas["gyro"], meas["tachometer"]
        rate = gyro - mt.inertial_rate(q, np.zeros(3), float(snap[_SN_RATE]))  # ω_bo from the measured q
        self._meas_state = {
            "attitude": q,
            "rate_rad_s": rate,
            "inertial_rate_rad_s": gyro,
            "wheel_speed_rad_s": wheel,
            "wheel_momentum_nms": float(self.model.params.wheel_inertia_kg_m2 * (wheel[0] + gyro[1])),
            "magnetic_field_body_t": meas["magnetometer"],
        }

    def _observation(self) -> np.ndarray:
        snap = self._snap
        if not self._sensor_layer.enabled:
            return self._with_hint(snap[: self._n_obs], self._t)
        m = self._meas_state
        parts = [self._error_state(m["attitude"], m["rate_rad_s"]), m["wheel_speed_rad_s"] / WHEEL_SPEED_SCALE_RAD_S]
        if self.observe_field:
            parts.append(m["magnetic_field_body_t"] / FIELD_SCALE_T)
        return self._with_hint(np.concatenate(parts), self._t)

    def _info(self, commanded, cost: float) -> dict:
        # one fresh array (state, step outputs, snapshot) whose slices the info hands out
        v = np.concatenate([self._y, self._step_out, self._snap])
        v.setflags(write=False)  # measured shares these views with the truth: nobody edits them
        snap = self._snap
        field_body = v[_V_BBODY]
        state = {
            "attitude": v[:4],
            "rate_rad_s": v[4:7],
            "inertial_rate_rad_s": v[_V_WBI],
            "wheel_speed_rad_s": v[7:8],
            "wheel_momentum_nms": float(snap[_SN_HW]),
        }
        truth = {
            "state": state,
            "applied": v[_V_APPLIED],
            "faults": self._fault_truth(self._t),
            "error_angle_deg": float(snap[_SN_ANGLE]),
            "disturbance_torque_nm": v[_V_EXT],
            "true_inertia_kg_m2": v[_V_INERTIA].reshape(3, 3),
            "magnetic_torque_nm": v[_V_TAU],
            "control_torque_nm": v[_V_CONTROL],
            "magnetic_field_body_t": field_body,
        }
        sensors = self._sensor_layer.enabled
        info = self._make_info(
            truth=truth,
            measured=self._meas_state if sensors else {**state, "magnetic_field_body_t": field_body},
            cost=cost,
            time_s=self._t,
            commanded=commanded,
            reference={"attitude": v[_V_QD], "rate_rad_s": v[_V_WD], "attitude_rate": v[_V_QDOT]},
            orbit={
                "radius_m": float(snap[_SN_R]),
                "argument_of_latitude_rad": float(snap[_SN_U]),
                "rate_rad_s": float(snap[_SN_RATE]),
            },
            magnetic_field_orbital_t=v[_V_BORB],
        )
        if sensors:
            info["sensors"] = {key: val.copy() for key, val in self._meas.items()}
        return info


def _completed(name: str, given: Mapping | None, base: Mapping | None, keys: tuple[str, ...]) -> dict:
    """The dict keyword ``name``: ``given``'s entries over the preset's ``base``; every one
    of ``keys`` must be set and no other."""
    if given is not None and not isinstance(given, Mapping):
        raise ValueError(f"{name} must be a dict or None, got {given!r}")
    unknown = set(given or {}) - set(keys)
    if unknown:
        raise ValueError(f"{name} has unknown keys {sorted(unknown)}")
    cfg = {**(base or {}), **(given or {})}
    missing = [k for k in keys if k not in cfg]
    if missing:
        raise ValueError(f"{name} needs the keys {list(keys)}, missing {missing}")
    return cfg


@dataclass(frozen=True)
class MagnetorquerConfig:
    """The validated keywords of a :class:`MagnetorquerEnv` and what follows from them: the
    nominal ``model``, the completed ``orbit_config`` (its ``mean_anomaly_deg`` a number or
    ``"random"``) and its ``orbit`` (at that anomaly, or 0 when drawn), the ``field``, the
    disturbance settings, ΔJ(t) (``time_varying_inertia``), the ``inertia_uncertainty``, the
    step sizes (s; ``n_substeps`` RK4 sub-steps a decision), the start's bounds, the env's
    ``layers`` (faults, sensors, flight conditions, a non-paper disturbance) and the flight
    conditions' ``flight_inertia`` draw (None: none). The numba env and the JAX plant
    (:mod:`attitude_envs.jax.magnetorquer`) are both built from it."""

    preset: str | None
    task: str
    orbit_config: dict
    random_anomaly: bool
    orbit: KeplerOrbit
    field: FieldModel
    observe_field: bool
    paper_disturbance: bool
    disturbance_scale: float
    disturbance_second_harmonic: bool
    gravity_gradient: bool
    time_varying_inertia: mt.TimeVaryingInertia | None
    inertia_uncertainty: InertiaUncertainty | None
    control_dt_s: float
    integrator_dt_s: float
    n_substeps: int
    episode_duration_s: float
    initial_angle_deg: float
    initial_rate_max_rad_s: float
    model: MagnetorquerModel
    layers: Layers
    flight_inertia: InertiaUncertainty | None
    max_rate_rad_s: float
    termination_cost: str


def configure(cls: type[MagnetorquerEnv], preset: str | None, given: Mapping[str, Any]) -> MagnetorquerConfig:
    """The keywords ``given`` of env class ``cls`` (every one: the constructor's ``locals()``,
    or :func:`~attitude_envs.envs.base.keyword_defaults` updated with the keywords passed)
    resolved (``preset``, None: the class's default, then every keyword that is not None) and
    validated in the constructor's order, with the same ``ValueError`` for a bad one."""
    preset = cls.default_preset if preset is None else preset
    skip = ("self", "__class__", "preset", "render_mode")
    overrides = {k: v for k, v in given.items() if k not in skip and not k.startswith("_")}
    cfg = presets.resolve(cls.env_name, preset, overrides, constructor_keywords(cls))
    missing = [k for k in _REQUIRED if cfg.get(k) is None]
    if missing:
        raise ValueError(f"{cls.env_name} preset {preset!r} sets no {missing[0]!r}; pass {missing[0]}=...")
    preset_values = presets.get(cls.env_name, preset).params()
    task = validation.choice("task", given["task"], {"tracking", "regulation"})
    params = mt.MagnetorquerParams(
        cfg["inertia_kg_m2"],
        cfg["wheel_inertia_kg_m2"],
        cfg["max_dipole_am2"],
        cfg["max_wheel_torque_nm"],
        cfg["max_wheel_momentum_nms"],
    )
    orbit_cfg = _completed("orbit", given["orbit"], preset_values.get("orbit"), _ORBIT_KEYS)
    random_anomaly = isinstance(orbit_cfg["mean_anomaly_deg"], str)
    if random_anomaly:
        validation.choice("orbit.mean_anomaly_deg", orbit_cfg["mean_anomaly_deg"], {"random"})
    orbit = make_orbit(orbit_cfg, 0.0 if random_anomaly else float(orbit_cfg["mean_anomaly_deg"]))
    field = FieldModel(cfg["field_model"], cfg["dipole_strength_t_m3"], given["field_epoch"])
    observe_field = validation.flag("observe_field", given["observe_field"])
    disturbance = given["disturbance"]
    if isinstance(disturbance, str):
        validation.choice("disturbance", disturbance, {"paper"})
    paper_disturbance = isinstance(disturbance, str)
    disturbance_scale = validation.nonnegative("disturbance_scale", given["disturbance_scale"])
    second_harmonic = validation.flag("disturbance_second_harmonic", given["disturbance_second_harmonic"])
    gravity_gradient = validation.flag("gravity_gradient", given["gravity_gradient"])
    time_varying = given["time_varying_inertia"]
    if isinstance(time_varying, str):
        validation.choice("time_varying_inertia", time_varying, {"paper"})
        time_varying = {}
    delta_j = mt.TimeVaryingInertia.from_config(time_varying, TIME_VARYING_INERTIA.value)
    if delta_j is not None:
        delta_j.check_against(params.inertia_kg_m2)
    uncertainty = InertiaUncertainty.from_config(given["inertia_uncertainty"])
    control_dt_s = validation.positive("control_dt_s", cfg["control_dt_s"])
    integrator_dt_s = validation.positive("integrator_dt_s", cfg.get("integrator_dt_s", control_dt_s))
    n_substeps = substeps(control_dt_s, integrator_dt_s)
    duration = validation.positive("episode_duration_s", cfg.get("episode_duration_s", 2.0 * orbit.period_s))
    target_euler = validation.finite_array("target_euler_deg", given["target_euler_deg"], (3,))  # either task
    if task == "tracking":
        ref_cfg = _completed("reference", given["reference"], preset_values.get("reference"), _REFERENCE_KEYS)
        ref = SmoothBangBang(ref_cfg["delta_deg"], ref_cfg["t_final_s"], ref_cfg["start_deg"])
    else:
        ref = SmoothBangBang((0.0, 0.0, 0.0), 1.0, target_euler)
    initial_angle = validation.in_range("initial_angle_deg", given["initial_angle_deg"], 0.0, 180.0)
    rate_max = given["initial_rate_max_rad_s"]
    default_rate = 0.0 if task == "tracking" else 1e-3
    rate_max = validation.nonnegative("initial_rate_max_rad_s", default_rate if rate_max is None else rate_max)
    q_mat = validation.psd_matrix("Q", cfg["Q"], 6)
    r_mat = validation.psd_matrix("R", cfg["R"], 3, definite=True)
    model = MagnetorquerModel(
        params, orbit.mean_motion_rad_s, orbit.inclination_rad, ref, QuadraticCost(q_mat, r_mat), control_dt_s
    )
    layers = build_layers(
        *cls._flight_table_key(preset),
        n_actuators=4,
        actuator_limits=params.limits,
        channels=[
            Channel("gyro", 3, units="rad/s"),  # inertial rate ω_bi, body axes
            Channel("star_tracker", 4, "attitude", "rad"),  # attitude relative to the orbital frame
            Channel("tachometer", 1, units="rad/s"),
            Channel("magnetometer", 3, units="T"),  # body-frame field
        ],
        faults=cfg.get("faults"),
        sensors=given["sensors"],
        fault_hint=given["fault_hint"],
        disturbance=None if paper_disturbance else disturbance,
        conditions=cfg.get("conditions"),
        control_dt_s=control_dt_s,
    )
    flight_inertia = None
    scale = layers.conditions.parameters
    if scale > 0 and uncertainty is None:  # else inertia_uncertainty draws the true inertia
        # ±5 % × at most 10 (conditions.MAX_PARAMETER_SCALE): positive moments
        table = flight.table(*cls._flight_table_key(preset))
        moment, axis = table.plant_value("inertia_moment") * scale, table.plant_value("inertia_axis_deg") * scale
        flight_inertia = InertiaUncertainty("random", None, moment, axis)
    max_rate = validation.positive("max_rate_rad_s", given["max_rate_rad_s"])
    termination_cost = validation.choice("termination_cost", given["termination_cost"], TERMINATION_COSTS)
    if given["render_mode"] is not None:
        raise ValueError(f"render_mode must be None (no renderer for Magnetorquer-v0), got {given['render_mode']!r}")
    return MagnetorquerConfig(
        preset=preset,
        task=task,
        orbit_config=orbit_cfg,
        random_anomaly=random_anomaly,
        orbit=orbit,
        field=field,
        observe_field=observe_field,
        paper_disturbance=paper_disturbance,
        disturbance_scale=disturbance_scale,
        disturbance_second_harmonic=second_harmonic,
        gravity_gradient=gravity_gradient,
        time_varying_inertia=delta_j,
        inertia_uncertainty=uncertainty,
        control_dt_s=control_dt_s,
        integrator_dt_s=integrator_dt_s,
        n_substeps=n_substeps,
        episode_duration_s=duration,
        initial_angle_deg=initial_angle,
        initial_rate_max_rad_s=rate_max,
        model=model,
        layers=layers,
        flight_inertia=flight_inertia,
        max_rate_rad_s=max_rate,
        termination_cost=termination_cost,
    )


def observation_bounds(cfg: MagnetorquerConfig) -> tuple[np.ndarray, np.ndarray]:
    """The observation's bounds (float32): the error quaternion's vector part within ±1, the
    rates within twice ``max_rate_rad_s``, the scaled wheel speed within ±1e3, the scaled
    field within ±3 (``observe_field``), then the ``fault_hint`` flags in [0, 1]."""
    high = np.concatenate([np.ones(3), np.full(3, 2.0 * cfg.max_rate_rad_s), [1e3]])
    if cfg.observe_field:
        high = np.concatenate([high, np.full(3, 3.0)])
    low, high = cfg.layers.hint_bounds(-high, high)
    return low.astype(np.float32), high.astype(np.float32)


def make_orbit(orbit_config: Mapping[str, Any], mean_anomaly_deg: float) -> KeplerOrbit:
    """The orbit of the completed ``orbit`` keyword ``orbit_config`` at ``mean_anomaly_deg``
    (deg, at t = 0)."""
    c = orbit_config
    return KeplerOrbit.from_altitudes(
        c["apogee_altitude_km"],
        c["perigee_altitude_km"],
        c["inclination_deg"],
        raan_deg=c["raan_deg"],
        arg_perigee_deg=c["arg_perigee_deg"],
        mean_anomaly_deg=mean_anomaly_deg,
        model=c["model"],
    )


def disturbance_code(cfg: MagnetorquerConfig) -> tuple[int, np.ndarray, float]:
    """The compiled step's disturbance kind (``kernels.DIST_*``), the sinusoid's amplitude
    (3, N·m) and period (s) of ``cfg``'s disturbance (zeros and 1 s for another kind)."""
    dist = cfg.layers.disturbance
    if cfg.paper_disturbance:
        return kernels.DIST_PAPER, np.zeros(3), 1.0
    if dist is None:
        return kernels.DIST_NONE, np.zeros(3), 1.0
    if dist.kind == "sinusoidal":
        return kernels.DIST_SINUSOIDAL, dist.amplitude_nm, dist.period_s
    return kernels.DIST_HELD, np.zeros(3), 1.0  # constant, random walk: a torque held over the control step


def pack_shared(cfg: MagnetorquerConfig) -> np.ndarray:
    """``cfg`` in the compiled step's layout (:func:`kernels.pack_shared`)."""
    p = cfg.model.params
    kind, amplitude, period = disturbance_code(cfg)
    dj = cfg.time_varying_inertia
    return kernels.pack_shared(
        wheel_inertia_kg_m2=p.wheel_inertia_kg_m2,
        max_wheel_momentum_nms=p.max_wheel_momentum_nms,
        integrator_dt_s=cfg.integrator_dt_s,
        substeps=cfg.n_substeps,
        field_model=cfg.field.model,
        dipole_strength_t_m3=cfg.field.strength,
        inclination_rad=cfg.orbit.inclination_rad,
        table_step_s=cfg.field.igrf_step_s,
        disturbance_kind=kind,
        disturbance_scale=cfg.disturbance_scale,
        orbital_rate_rad_s=cfg.model.orbital_rate_rad_s,
        second_harmonic=cfg.disturbance_second_harmonic,
        disturbance_amplitude_nm=amplitude,
        disturbance_period_s=period,
        gravity_gradient=cfg.gravity_gradient,
        delta_j=None if dj is None else (dj.amplitude_kg_m2, dj.frequency_rad_s, dj.phase_rad),
        Q=cfg.model.cost.Q,
        R=cfg.model.cost.R,
        reference=cfg.model.reference.packed,
    )
