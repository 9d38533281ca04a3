"""Magnetorquer-v0: nano-satellite with three magnetorquers and one y-axis wheel (spec 002)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import quaternion, validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.disturbances import Disturbance
from attitude_envs.faults import ActuatorFaults
from attitude_envs.integrators import substeps
from attitude_envs.plants import magnetorquer as mt
from attitude_envs.plants import magnetorquer_kernels as kernels
from attitude_envs.plants.magnetic_field import DIPOLE_STRENGTH_T_M3, FieldModel
from attitude_envs.plants.orbit import KeplerOrbit
from attitude_envs.sensors import Channel, SensorSuite
from attitude_envs.trajectories import SmoothBangBang
from attitude_envs.uncertainty import InertiaUncertainty

_OPTION_KEYS = {"attitude", "rate_rad_s", "wheel_speed_rad_s", "faults", "mean_anomaly_deg"}
# Spec 002 Table 1 [READ]; RAAN and argument of perigee are not printed [ASSUME 0].
PAPER_ORBIT = {
    "model": "keplerian",
    "apogee_altitude_km": 1250.0,
    "perigee_altitude_km": 311.0,
    "inclination_deg": 69.5,
    "raan_deg": 0.0,
    "arg_perigee_deg": 0.0,
    "mean_anomaly_deg": "random",
}
PAPER_REFERENCE = {"delta_deg": [10.0, 20.0, 10.0], "t_final_s": 1200.0, "start_deg": [0.0, 0.0, 0.0]}
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


class MagnetorquerEnv(gym.Env):
    """Attitude tracking/regulation of a nano-satellite with 3 magnetorquers + 1 wheel on y.

    Paper: Sadigh, Kashaninia, Dehghan, J. Control 15(4), 2022 (spec 002). Plant:
    :mod:`attitude_envs.plants.magnetorquer` (exact gyrostat equations with one wheel,
    attitude relative to the orbital LVLH frame), orbit :mod:`attitude_envs.plants.orbit`,
    field :mod:`attitude_envs.plants.magnetic_field`; fixed-step RK4 with the stage cost as
    an extra state, quaternion renormalized after every sub-step. Each step is one compiled
    call (:func:`attitude_envs.plants.magnetorquer_kernels.advance`): integration, then the
    observation and ``info`` quantities at the step's end.

    ================  ==========================================================  ===========
    Quantity          Meaning                                                     Units
    ================  ==========================================================  ===========
    State (truth)     q (body rel. orbital frame, scalar last), ω_bo, wheel       -, rad/s
                      speed Ω relative to the body; orbit (anomaly), time
    Observation       float32 ``[q_e,vec (3), ω_e (3), Ω/1000 (1)]``, q_e =       -, rad/s,
                      q_d*⊗q (w ≥ 0), ω_e = ω_bo − C(q_e)ᵀω_d; ``+ b/5e-5 T``     krad/s, -
                      (body-frame field, 3) if ``observe_field``
    Action            4 in [-1, 1] (clipped): dipoles ``m = a[:3]·max_dipole_am2``  A·m²
                      and the wheel torque on the body about +y                    N·m
                      ``T_w = a[3]·max_wheel_torque_nm`` (spec eq. 7 convention)
    Reward            −∫ (xᵀQx + uᵀRu) dt over the step, x = [q_e,vec, ω_e],       (cost)
                      u = m_applied × b + e_y T_w,applied (body torque, N·m)
    Start state       tracking: q = q_d(0), ω_bo = 0, Ω = 0 (paper); regulation:
                      q within ``initial_angle_deg`` of the target, ω_bo uniform   deg, rad/s
                      in ±``initial_rate_max_rad_s``; orbit anomaly from the seed
    Termination       non-finite state or ``max|ω_bo| > max_rate_rad_s``          rad/s
    Truncation        simulated time reaches ``episode_duration_s`` (default two  s
                      orbital periods, the paper's 12 038 s)
    ================  ==========================================================  ===========

    Parameters: ``task`` (``"tracking"``: spec 002's smooth bang-bang 3-2-1 Euler reference,
    ``reference`` = {delta_deg, t_final_s, start_deg}; ``"regulation"``: hold
    ``target_euler_deg``); ``inertia_kg_m2`` (nominal J_t), ``wheel_inertia_kg_m2``,
    ``max_dipole_am2`` (0.5), ``max_wheel_torque_nm`` (2.3e-4), ``max_wheel_momentum_nms``
    (40 as printed; 0.04 is the spec's likely reading); ``orbit`` (dict, keys of
    ``PAPER_ORBIT``; ``model`` "keplerian"/"circular", ``mean_anomaly_deg`` a number or
    "random"); ``field_model`` ("dipole", "dipole-printed", "igrf"), ``dipole_strength_t_m3``,
    ``field_epoch``, ``observe_field``; ``disturbance`` ("paper": eq. 39 × ``disturbance_scale``,
    ``disturbance_second_harmonic``; a dict of :mod:`attitude_envs.disturbances`; or None);
    ``gravity_gradient``; ``time_varying_inertia`` (eq. 35 by default, dict or None);
    ``inertia_uncertainty`` (random dispersions, :mod:`attitude_envs.uncertainty`);
    ``control_dt_s``, ``integrator_dt_s``, ``episode_duration_s``, ``Q``, ``R``,
    ``max_rate_rad_s``, ``faults`` (actuator indices 0–2 dipoles, 3 wheel; see
    :mod:`attitude_envs.faults`; ``"target": "sensor"`` entries hit the sensors), ``sensors``
    (channels ``gyro`` = inertial rate, ``star_tracker``, ``tachometer``, ``magnetometer`` =
    body field in T; see :mod:`attitude_envs.sensors`: the observation is then built from
    the measurements), ``fault_hint`` (append 4 actuator + 4 sensor active-fault flags);
    the paper's E = diag(0.9, 0.7, 0.6) after 50 s is
    ``PAPER_FAULTS``).

    ``info``: ``state`` (attitude, rate_rad_s = ω_bo, inertial_rate_rad_s, wheel_speed_rad_s,
    wheel_momentum_nms), ``reference`` (attitude, rate_rad_s, attitude_rate), ``time_s``,
    ``magnetic_field_body_t``, ``magnetic_field_orbital_t``, ``orbit`` (radius_m,
    argument_of_latitude_rad, rate_rad_s), ``commanded`` and ``applied`` (4: dipoles after
    faults, wheel torque after faults and the momentum limit, step means), ``magnetic_torque_nm``
    and ``control_torque_nm`` (step means), ``disturbance_torque_nm``, ``true_inertia_kg_m2``,
    ``cost``, ``error_angle_deg``, ``faults``.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        task: str = "tracking",
        reference: dict | None = None,
        target_euler_deg=(0.0, 0.0, 0.0),
        initial_angle_deg: float = 10.0,
        initial_rate_max_rad_s: float | None = None,
        inertia_kg_m2=None,
        wheel_inertia_kg_m2: float = mt.PAPER_WHEEL_INERTIA_KG_M2,
        max_dipole_am2: float = mt.PAPER_MAX_DIPOLE_AM2,
        max_wheel_torque_nm: float = mt.PAPER_MAX_WHEEL_TORQUE_NM,
        max_wheel_momentum_nms: float = mt.PAPER_MAX_WHEEL_MOMENTUM_NMS,
        orbit: dict | None = None,
        field_model: str = "dipole",
        dipole_strength_t_m3: float = DIPOLE_STRENGTH_T_M3,
        field_epoch: str = "2020-01-01T00:00:00",
        observe_field: bool = False,
        disturbance: str | dict | None = "paper",
        disturbance_scale: float = 1.0,
        disturbance_second_harmonic: bool = False,
        gravity_gradient: bool = False,
        time_varying_inertia: dict | None = mt.PAPER_DELTA_J,
        inertia_uncertainty: dict | None = None,
        control_dt_s: float = 0.1,
        integrator_dt_s: float | None = None,
        episode_duration_s: float | None = None,
        Q=None,
        R=None,
        max_rate_rad_s: float = 1.0,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        render_mode: str | None = None,
    ) -> None:
        self.task = validation.choice("task", task, {"tracking", "regulation"})
        if inertia_kg_m2 is None:
            inertia_kg_m2 = mt.PAPER_BODY_INERTIA_KG_M2 + wheel_inertia_kg_m2 * np.outer(mt.E_Y, mt.E_Y)
        params = mt.MagnetorquerParams(
            inertia_kg_m2, wheel_inertia_kg_m2, max_dipole_am2, max_wheel_torque_nm, max_wheel_momentum_nms
        )
        self.orbit = self._orbit(orbit)
        self.field = FieldModel(field_model, dipole_strength_t_m3, field_epoch)
        self.observe_field = bool(observe_field)
        if isinstance(disturbance, str):
            validation.choice("disturbance", disturbance, {"paper"})
            self._disturbance = "paper"
        else:
            self._disturbance = None if disturbance is None else Disturbance(disturbance)
        self.disturbance_scale = validation.nonnegative("disturbance_scale", disturbance_scale)
        self.disturbance_second_harmonic = bool(disturbance_second_harmonic)
        self.gravity_gradient = bool(gravity_gradient)
        self._delta_j = mt.TimeVaryingInertia.from_config(time_varying_inertia)
        if self._delta_j is not None:
            self._delta_j.check_against(params.inertia_kg_m2)
        self._uncertainty = InertiaUncertainty.from_config(inertia_uncertainty)
        self.control_dt_s = validation.positive("control_dt_s", control_dt_s)
        self.integrator_dt_s = validation.positive(
            "integrator_dt_s", self.control_dt_s if integrator_dt_s is None else integrator_dt_s
        )
        self._substeps = substeps(self.control_dt_s, self.integrator_dt_s)
        self.episode_duration_s = validation.positive(
            "episode_duration_s", 2.0 * self.orbit.period_s if episode_duration_s is None else episode_duration_s
        )
        if self.task == "tracking":
            ref_cfg = dict(PAPER_REFERENCE, **(reference or {}))
            unknown = set(ref_cfg) - set(PAPER_REFERENCE)
            if unknown:
                raise ValueError(f"reference has unknown keys {sorted(unknown)}")
            ref = SmoothBangBang(ref_cfg["delta_deg"], ref_cfg["t_final_s"], ref_cfg["start_deg"])
        else:
            ref = SmoothBangBang(
                (0.0, 0.0, 0.0), 1.0, validation.finite_array("target_euler_deg", target_euler_deg, (3,))
            )
        self._initial_angle = float(initial_angle_deg)
        if not 0.0 <= self._initial_angle <= 180.0:
            raise ValueError(f"initial_angle_deg must be in [0, 180], got {initial_angle_deg!r}")
        default_rate = 0.0 if self.task == "tracking" else 1e-3
        self._rate_max = validation.nonnegative(
            "initial_rate_max_rad_s", default_rate if initial_rate_max_rad_s is None else initial_rate_max_rad_s
        )
        # [ASSUME] cost weights (the paper defines none): 1 per unit q_e², 1e3 per (rad/s)²,
        # 1e4 per (N·m)² of body torque — a 0.01 attitude error and 1e-3 N·m weigh alike.
        q_mat = validation.psd_matrix("Q", np.diag([1.0] * 3 + [1e3] * 3) if Q is None else Q, 6)
        r_mat = validation.psd_matrix("R", 1e4 * np.eye(3) if R is None else R, 3, definite=True)
        self.model = MagnetorquerModel(
            params,
            self.orbit.mean_motion_rad_s,
            self.orbit.inclination_rad,
            ref,
            QuadraticCost(q_mat, r_mat),
            self.control_dt_s,
        )
        self._faults = ActuatorFaults(faults, 4, params.limits, other_targets={"sensor"})
        channels = [
            Channel("gyro", 3, units="rad/s"),  # inertial rate ω_bi, body axes
            Channel("star_tracker", 4, "attitude", "rad"),  # attitude relative to the orbital frame
            Channel("tachometer", 1, units="rad/s"),
            Channel("magnetometer", 3, units="T"),  # body-frame field
        ]
        self._sensors = SensorSuite(sensors, channels, faults)
        self.fault_hint = bool(fault_hint)
        self.max_rate_rad_s = validation.positive("max_rate_rad_s", max_rate_rad_s)
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (no renderer for Magnetorquer-v0), got {render_mode!r}")
        self.render_mode = None

        high = np.concatenate([np.ones(3), np.full(3, 2.0 * self.max_rate_rad_s), [1e3]])
        if self.observe_field:
            high = np.concatenate([high, np.full(3, 3.0)])
        low = -high
        if self.fault_hint:  # 4 actuator flags + 4 sensor-channel flags in [0, 1]
            low, high = np.concatenate([low, np.zeros(8)]), np.concatenate([high, np.ones(8)])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)

        self._inertia = params.inertia_kg_m2
        self._y = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
        self._t = 0.0
        self._meas: dict[str, np.ndarray] = {}
        self._steps = 0
        self._shared = self._pack_shared(q_mat, r_mat)
        self._env_vec = self._pack_env()
        self._work = np.zeros(kernels.WORK_SIZE)
        self._step_out = np.zeros(kernels.STEP_OUT_SIZE)
        self._snap = np.zeros(kernels.SNAPSHOT_SIZE)
        self._n_obs = 10 if self.observe_field else 7
        self._limits = params.limits

    # ------------------------------------------------------------------ construction helpers
    def _orbit(self, config: dict | None) -> KeplerOrbit:
        cfg = dict(PAPER_ORBIT)
        if config is not None:
            if not isinstance(config, dict):
                raise ValueError(f"orbit must be a dict or None, got {config!r}")
            unknown = set(config) - set(PAPER_ORBIT)
            if unknown:
                raise ValueError(f"orbit has unknown keys {sorted(unknown)}")
            cfg.update(config)
        self._random_anomaly = isinstance(cfg["mean_anomaly_deg"], str)
        if self._random_anomaly:
            validation.choice("orbit.mean_anomaly_deg", cfg["mean_anomaly_deg"], {"random"})
        self._orbit_cfg = cfg
        return self._make_orbit(0.0 if self._random_anomaly else float(cfg["mean_anomaly_deg"]))

    def _make_orbit(self, mean_anomaly_deg: float) -> KeplerOrbit:
        c = self._orbit_cfg
        return KeplerOrbit.from_altitudes(
            c["apogee_altitude_km"],
            c["perigee_altitude_km"],
            c["inclination_deg"],
            raan_deg=c["raan_deg"],
            arg_perigee_deg=c["arg_perigee_deg"],
            mean_anomaly_deg=mean_anomaly_deg,
            model=c["model"],
        )

    def _pack_shared(self, q_mat: np.ndarray, r_mat: np.ndarray) -> np.ndarray:
        """The configuration in the compiled step's layout (:func:`kernels.pack_shared`)."""
        p = self.model.params
        dist = self._disturbance
        amplitude, period = np.zeros(3), 1.0
        if dist == "paper":
            kind = kernels.DIST_PAPER
        elif dist is None:
            kind = kernels.DIST_NONE
        elif dist.kind == "sinusoidal":
            kind, amplitude, period = kernels.DIST_SINUSOIDAL, dist.amplitude_nm, dist.period_s
        else:  # constant, random walk: a torque held over the control step
            kind = kernels.DIST_HELD
        dj = self._delta_j
        return kernels.pack_shared(
            wheel_inertia_kg_m2=p.wheel_inertia_kg_m2,
            max_wheel_momentum_nms=p.max_wheel_momentum_nms,
            integrator_dt_s=self.integrator_dt_s,
            substeps=self._substeps,
            field_model=self.field.model,
            dipole_strength_t_m3=self.field.strength,
            inclination_rad=self.orbit.inclination_rad,
            table_step_s=self.field.igrf_step_s,
            disturbance_kind=kind,
            disturbance_scale=self.disturbance_scale,
            orbital_rate_rad_s=self.model.orbital_rate_rad_s,
            second_harmonic=self.disturbance_second_harmonic,
            disturbance_amplitude_nm=amplitude,
            disturbance_period_s=period,
            gravity_gradient=self.gravity_gradient,
            delta_j=None if dj is None else (dj.amplitude_kg_m2, dj.frequency_rad_s, dj.phase_rad),
            Q=q_mat,
            R=r_mat,
            reference=self.model.reference.packed,
        )

    def _disturbance_vector(self) -> np.ndarray:
        """The per-episode disturbance entry of the compiled step: the held torque (constant,
        random walk) or the sinusoid's phases."""
        dist = self._disturbance
        if isinstance(dist, Disturbance):
            if dist.kind == "sinusoidal":
                return dist._phase
            return dist.torque_nm if dist.kind == "constant" else dist._walk
        return np.zeros(3)

    def _pack_env(self) -> np.ndarray:
        """This episode's draws in the compiled step's layout (:func:`kernels.pack_env`)."""
        eff = self._inertia.copy()
        eff[1, 1] -= self.model.params.wheel_inertia_kg_m2
        return kernels.pack_env(self._inertia, np.linalg.inv(eff), self.orbit.packed, self._disturbance_vector())

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, _OPTION_KEYS)
        rng = self.np_random
        nominal = self.model.params.inertia_kg_m2
        self._inertia = nominal if self._uncertainty is None else self._uncertainty.draw(nominal, rng)
        if self._delta_j is not None and self._uncertainty is not None:
            self._delta_j.check_against(self._inertia)
        if "mean_anomaly_deg" in options:
            anomaly = float(validation.finite_array("options['mean_anomaly_deg']", options["mean_anomaly_deg"], ()))
        else:
            anomaly = (
                float(rng.uniform(0.0, 360.0)) if self._random_anomaly else float(self._orbit_cfg["mean_anomaly_deg"])
            )
        self.orbit = self._make_orbit(anomaly)
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
        if isinstance(self._disturbance, Disturbance):
            self._disturbance.reset(rng)
        self._sensors.reset(rng, options.get("faults"))  # own spawned generator
        self._faults.reset(rng, options.get("faults"))
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
        return self._observation(), self._info(np.zeros(4), 0.0)

    def step(self, action):
        a = validation.action(action, 4)
        commanded = np.minimum(np.maximum(a, -1.0), 1.0) * self._limits
        delivered = self._faults.apply(commanded, self._t)
        dist = self._disturbance
        if isinstance(dist, Disturbance):  # the held torque may change between steps
            dist.advance(self.np_random, self.control_dt_s)
            self._env_vec[kernels.EN_DIST : kernels.EN_DIST + 3] = self._disturbance_vector()
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
        terminated = not finite or bool(self._step_out[kernels.ST_MAX_RATE] > self.max_rate_rad_s)
        truncated = bool(self._t >= self.episode_duration_s - 1e-9 * self.control_dt_s) and not terminated
        obs = self._observation() if finite else np.zeros(self.observation_space.shape, np.float32)
        return obs, -cost, terminated, truncated, self._info(commanded, cost)

    # ------------------------------------------------------------------ internals
    def _snapshot(self, t_s: float, y: np.ndarray) -> np.ndarray:
        """A fresh :func:`kernels.snapshot_into` of state ``y`` at ``t_s`` (layout ``SN_*``)."""
        out = np.empty(kernels.SNAPSHOT_SIZE)
        ctx = np.empty(kernels.CONTEXT_SIZE)
        kernels.snapshot_into(y, float(t_s), self._shared, self._env_vec, self.field.table, ctx, out)
        return out

    def true_inertia_at(self, t_s: float) -> np.ndarray:
        """The true inertia ``I + ΔJ(t)`` of the plant at ``t_s``, kg·m² (evaluation truth)."""
        return self._snapshot(t_s, self._y)[kernels.SN_I : kernels.SN_I + 9].reshape(3, 3)

    def external_torque_at(self, t_s: float, q: np.ndarray) -> np.ndarray:
        """Disturbance (+ gravity gradient when enabled) on the body at attitude ``q``, N·m."""
        y = self._y.copy()
        y[:4] = q
        return self._snapshot(t_s, y)[kernels.SN_EXT : kernels.SN_EXT + 3]

    def _error_state(self, q: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """``[q_e,vec, ω_e]`` of ``q``, ``rate`` against the reference of the last snapshot."""
        x, y, z, w = (float(v) for v in q)
        r0, r1, r2 = (float(v) for v in rate)
        return np.array(kernels.error_state(x, y, z, w, r0, r1, r2, self._snap, kernels.SN_QD)[:6])

    def error_state(self) -> np.ndarray:
        """The true error state ``x = [q_e,vec, ω_e]`` (float64) now."""
        return self._snapshot(self._t, self._y)[kernels.SN_X : kernels.SN_X + 6]

    def _observation(self) -> np.ndarray:
        snap = self._snap
        if not self._sensors.enabled and not self.fault_hint:
            return snap[: self._n_obs].astype(np.float32)
        parts = [snap[: self._n_obs]]
        if self._sensors.enabled:
            q, rate, wheel = self._y[:4], self._y[4:7], self._y[7:]
            n = float(snap[kernels.SN_RATE])
            truth = {
                "gyro": snap[kernels.SN_WBI : kernels.SN_WBI + 3].copy(),
                "star_tracker": q,
                "tachometer": wheel,
                "magnetometer": snap[kernels.SN_BBODY : kernels.SN_BBODY + 3].copy(),
            }
            self._meas = self._sensors.measure(truth, self._t)
            q, wheel, field = self._meas["star_tracker"], self._meas["tachometer"], self._meas["magnetometer"]
            rate = self._meas["gyro"] - mt.inertial_rate(q, np.zeros(3), n)  # ω_bo from the measured attitude
            parts = [self._error_state(q, rate), wheel / WHEEL_SPEED_SCALE_RAD_S]
            if self.observe_field:
                parts.append(field / FIELD_SCALE_T)
        if self.fault_hint:
            parts += [self._faults.active_flags(self._t), self._sensors.active_flags(self._t)]
        return np.concatenate(parts).astype(np.float32)

    def _info(self, commanded, cost: float) -> dict:
        # one fresh array (state, step outputs, snapshot) whose slices the info hands out
        v = np.concatenate([self._y, self._step_out, self._snap])
        k = kernels
        st, sn = 8, 8 + k.STEP_OUT_SIZE
        snap = self._snap
        info = {
            "state": {
                "attitude": v[:4],
                "rate_rad_s": v[4:7],
                "inertial_rate_rad_s": v[sn + k.SN_WBI : sn + k.SN_WBI + 3],
                "wheel_speed_rad_s": v[7:8],
                "wheel_momentum_nms": float(snap[k.SN_HW]),
            },
            "reference": {
                "attitude": v[sn + k.SN_QD : sn + k.SN_QD + 4],
                "rate_rad_s": v[sn + k.SN_WD : sn + k.SN_WD + 3],
                "attitude_rate": v[sn + k.SN_QDOT : sn + k.SN_QDOT + 4],
            },
            "time_s": self._t,
            "magnetic_field_body_t": v[sn + k.SN_BBODY : sn + k.SN_BBODY + 3],
            "magnetic_field_orbital_t": v[sn + k.SN_BORB : sn + k.SN_BORB + 3],
            "orbit": {
                "radius_m": float(snap[k.SN_R]),
                "argument_of_latitude_rad": float(snap[k.SN_U]),
                "rate_rad_s": float(snap[k.SN_RATE]),
            },
            "commanded": commanded,
            "applied": v[st + k.ST_APPLIED : st + k.ST_APPLIED + 4],
            "magnetic_torque_nm": v[st + k.ST_TAU : st + k.ST_TAU + 3],
            "control_torque_nm": v[st + k.ST_CONTROL : st + k.ST_CONTROL + 3],
            "disturbance_torque_nm": v[sn + k.SN_EXT : sn + k.SN_EXT + 3],
            "true_inertia_kg_m2": v[sn + k.SN_I : sn + k.SN_I + 9].reshape(3, 3),
            "cost": cost,
            "error_angle_deg": float(snap[k.SN_ANGLE]),
            "faults": self._faults.info(self._t) + self._sensors.info(self._t),
        }
        if self._sensors.enabled:
            info["sensors"] = {key: val.copy() for key, val in self._meas.items()}
        return info


# Spec 002 eq. (40): magnetorquer effectiveness E = diag(0.9, 0.7, 0.6) for t > 50 s, through
# the shared fault layer (actuators 0–2 are the dipoles).
PAPER_FAULTS = [
    {"kind": "loss_of_effectiveness", "index": i, "value": v, "onset_s": 50.0} for i, v in enumerate((0.1, 0.3, 0.4))
]
