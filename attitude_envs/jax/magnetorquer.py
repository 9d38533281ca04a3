"""Magnetorquer-v0/-v1 in JAX: the nano-satellite of Sadigh, Kashaninia & Dehghan (2022) with
three magnetorquers and one reaction wheel on body y, on a Keplerian orbit through the
geomagnetic field (:class:`attitude_envs.envs.magnetorquer.MagnetorquerEnv`).

The step is the numba kernel's (:mod:`attitude_envs.plants.magnetorquer_kernels`), the same
operations in the same order (but for the 3-vector products, which XLA may sum in another
order: the two agree to ~1e-15 per step under ``jax_enable_x64``): per control step the delivered command ``[m (3, A·m²), T_w (N·m)]`` is held
over ``n_substeps`` classical RK4 sub-steps of ``integrator_dt_s`` with the stage cost
``xᵀQx + uᵀRu`` as a ninth state, the quaternion renormalized after every sub-step and the
wheel torque zeroed on a sub-step whose start has ``|h_w| ≥ max_wheel_momentum_nms`` and the
torque would raise it. The dynamics are the exact gyrostat equations with one wheel on
``e_y`` (:mod:`attitude_envs.plants.magnetorquer`; the paper's eqs. 1–8 with consistent
wheel bookkeeping):

    I_eff ω̇_bi = −ω_bi × (I ω_bi + J_w e_y Ω) + e_y T_w + m × b + τ_ext,   I_eff = I − J_w e_y e_yᵀ
    J_w (Ω̇ + ω̇_bi,y) = −T_w,   ω_bi = ω_bo + R ω_oi,   ω_oi = [0, −ν̇, 0]      (eq. 3)
    ω̇_bo = ω̇_bi + ω_bo × R ω_oi − R ω̇_oi,   q̇ = ½ q ⊗ [ω_bo, 0]             (eqs. 12, 1)

with ``R`` (orbital → body) of eq. (4), the field ``b = R b_o`` of eq. (9) (the axial dipole at
the actual position, or the as-printed orbital-frame formula), the disturbance of eq. (39)
(or a constant, sinusoidal or random-walk torque), the optional gravity gradient and the
time-varying inertia ΔJ(t) of eq. (35). Everything that depends on time only (orbit by
Kepler's equation, field, reference slew of eqs. 36–38, inertia, disturbance) is evaluated
once per step at the 2·n_substeps + 1 stage times, then the sub-steps scan over it.

Time is counted as the numba env counts it: ``state.time`` decisions, ``t = time ·
control_dt_s`` s; the actuator faults (:func:`attitude_envs.jax.faults.apply`) act at the
step's start time and are held over it; the episode is truncated when ``t ≥
episode_duration_s − 1e-9·control_dt_s`` (``max_steps_in_episode``) and terminated on a
non-finite state or ``max|ω_bo| > max_rate_rad_s``, the latter charged
:func:`attitude_envs.jax.cost.termination_charge` at the step's end time.

Flight conditions (``conditions=``, :mod:`attitude_envs.conditions`) as the numba env models
them: the delay and the actuator dynamics (the dipoles' 8-bit resolution and 80 % duty cycle,
the magnetometer sampling while the torquers are off; the wheel's resolution, lag and
friction against its speed, which adds to the body torque ``T_w``) act between the command
and the plant as :meth:`attitude_envs.actuator_dynamics.ActuatorChain.deliver`
(:mod:`attitude_envs.jax.actuators`; the faults between its command and output stages, the
chain's runtime state in ``EnvState.flight``). ``reset_env`` draws the episode's true inertia
(principal moments and axes within the flight tolerances, unless ``inertia_uncertainty``
draws it) and the actuators' scale factors from a key folded off its own, so the start,
orbit phase, disturbance and faults are the lab episode's of the same key (the numba env's
law, not its draws); the inertia goes into ``EnvState.inertia_kg_m2`` as the lab's dispersion
does, the gains into ``EnvState.flight``. The flight sensors (gyro: ω_bi; star tracker: the
attitude; tachometer; magnetometer: the body field) sample at reset and at each step's end
(:mod:`attitude_envs.jax.sensors`, from keys folded off the reset's and the step's); the
observation is then built from the readings (``ω_bo = gyro − R(q_m) ω_oi``, the measured field
with ``observe_field``), as the numba env's, while the cost, the limits and ``info`` stay the
truth's. :func:`with_drawn_parameters` gives a numba episode's draws to the reset instead (the
x64 equality tests). In the lab ``flight`` and ``sensors`` are None in the env, its params and
its state, and the compiled step is the lab's.

Modeled: every keyword of the numba env except a ``sensors`` keyword in the lab (sensors
only as flight conditions' sensors, which an explicit ``sensors`` dict may replace),
sensor faults outside flight conditions' sensors
(:func:`attitude_envs.jax.sensors.channel_faults`; the others are modeled, draws and ``fault_hint`` flags included), ``field_model="igrf"`` (the IGRF table needs ``ppigrf`` on the host per
episode) and an ``inertia_uncertainty`` or flight inertia draw that could make ``I + ΔJ(t)``
indefinite (the numba env raises at such a reset); :func:`from_keywords` raises a ``ValueError``
naming them. Episode draws (orbit
start, regulation attitude and rate, inertia dispersion, sinusoid phases, fault draws) follow
the numba env's laws with ``jax.random`` (the same laws, not the same draws; the inertia
dispersion takes the first of :data:`MOMENT_CANDIDATES` draws that meets the triangle
inequality, where the numba env redraws up to 1000 times); so do a random-walk
disturbance's increments and intermittent faults' dwell times. A non-finite action is not
rejected (the numba env raises): it makes the state non-finite, which terminates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.envs.base import check_keywords, keyword_defaults
from attitude_envs.envs.magnetorquer import MagnetorquerConfig, configure, observation_bounds, pack_shared
from attitude_envs.envs.magnetorquer import MagnetorquerEnv as NumbaMagnetorquerEnv
from attitude_envs.faults import ActuatorFaults
from attitude_envs.jax import actuators as jact
from attitude_envs.jax import cost as jcost
from attitude_envs.jax import faults as jfaults
from attitude_envs.jax import quaternion as jq
from attitude_envs.jax import sensors as jsens
from attitude_envs.jax.environment import (
    Environment,
    check_state_from,
    drawn_arrays,
    episode_decisions,
    preset_defaults,
)
from attitude_envs.jax.ops import JAX
from attitude_envs.jax.spaces import Box
from attitude_envs.plants import magnetorquer_kernels as K
from attitude_envs.plants.magnetorquer_definition import COMPACT_LAYOUT, define

N_ACTUATORS = 4  # m_x, m_y, m_z (A·m²), wheel torque (N·m)
_PLANT = define(JAX)
N_SENSOR_FLAGS = 4  # gyro, star tracker, tachometer, magnetometer
_UNCERTAINTY_CODES = {None: 0, "fixed": 1, "random": 2}
#: the sensor channels, in the numba env's order: name → axes of its error
_AXES = {"gyro": 3, "star_tracker": 3, "tachometer": 1, "magnetometer": 3}


@dataclass(frozen=True)
class FlightLayout:
    """What the flight conditions (:mod:`attitude_envs.conditions`) switch on in the compiled
    program (static): the ``actuators`` chain's layout
    (:class:`attitude_envs.jax.actuators.ActuatorLayout`: delay, actuator dynamics, gains),
    ``parameters`` (the true parameters are drawn per episode: the reset takes given draws,
    :func:`with_drawn_parameters`) and ``draw_inertia`` (the flight tolerances draw the true
    inertia: not with an ``inertia_uncertainty``, which then draws it)."""

    actuators: jact.ActuatorLayout
    parameters: bool = False
    draw_inertia: bool = False


@struct.dataclass
class FlightParams:
    """The flight conditions' numbers: the ``actuators`` chain
    (:class:`attitude_envs.jax.actuators.ActuatorParams`; m_x, m_y, m_z in A·m², the wheel in
    N·m), the tolerances the true inertia is drawn within (``inertia_moment``: relative, on
    each principal moment; ``inertia_axis_deg``: the principal axes' rotation, deg) and each
    actuator's scale-factor ``gain_tolerance`` (relative). ``given``: the reset takes the
    ``given_*`` draws (a numba episode's: :func:`with_drawn_parameters`) instead: the true
    ``given_inertia_kg_m2`` (kg·m²), its ``given_inertia_eff_inv`` (1/(kg·m²)), ``given_gain``."""

    actuators: jact.ActuatorParams
    inertia_moment: jax.Array
    inertia_axis_deg: jax.Array
    gain_tolerance: jax.Array
    given: jax.Array
    given_inertia_kg_m2: jax.Array
    given_inertia_eff_inv: jax.Array
    given_gain: jax.Array


@struct.dataclass
class FlightState:
    """An episode's flight state: the actuator chain's runtime state ``actuators`` (delay
    line, rate limiter, lag) and the actuators' scale-factor ``gain`` (4; None: ones)."""

    actuators: jact.ActuatorState
    gain: jax.Array | None = None


@struct.dataclass
class EnvState:
    """One episode's state.

    * ``time``: decisions taken (``t = time · control_dt_s`` s);
    * ``attitude`` (4, scalar last: body relative to the orbital frame), ``rate_rad_s`` (3,
      ω_bo, rad/s, body axes), ``wheel_speed_rad_s`` (1, Ω relative to the body, rad/s);
    * ``mean_anomaly0_rad``: the orbit phase (mean anomaly at t = 0, rad);
    * ``inertia_kg_m2`` (3×3, the episode's true inertia without ΔJ(t), kg·m²) and
      ``inertia_eff_inv`` (its ``(I − J_w e_y e_yᵀ)⁻¹``, 1/(kg·m²));
    * ``disturbance`` (3): the held torque (constant, random walk; N·m) or the sinusoid's
      phases (rad) this episode;
    * ``faults``: the episode's realized actuator faults, ``fault_state`` their runtime state;
    * ``flight``: the flight conditions' actuator chain and gains (None in the lab);
      ``sensors``: the flight sensors' state (None: the truth is observed).
    """

    time: jax.Array
    attitude: jax.Array
    rate_rad_s: jax.Array
    wheel_speed_rad_s: jax.Array
    mean_anomaly0_rad: jax.Array
    inertia_kg_m2: jax.Array
    inertia_eff_inv: jax.Array
    disturbance: jax.Array
    faults: jfaults.FaultParams
    fault_state: jfaults.FaultState
    flight: FlightState | None = None
    sensors: jsens.SuiteState | None = None


#: a params field whose default is that group of the default preset's params
_default = preset_defaults(
    lambda: configure(NumbaMagnetorquerEnv, None, keyword_defaults(NumbaMagnetorquerEnv)), lambda cfg: params_of(cfg)
)


@struct.dataclass
class PlantParams:
    """The spacecraft: ``inertia_kg_m2`` (nominal J_t with the wheel, 3×3) and its
    ``inertia_eff_inv`` (``(J_t − J_w e_y e_yᵀ)⁻¹``), ``wheel_inertia_kg_m2``,
    ``max_dipole_am2`` (per axis, A·m²), ``max_wheel_torque_nm``, ``max_wheel_momentum_nms``."""

    inertia_kg_m2: jax.Array
    inertia_eff_inv: jax.Array
    wheel_inertia_kg_m2: jax.Array
    max_dipole_am2: jax.Array
    max_wheel_torque_nm: jax.Array
    max_wheel_momentum_nms: jax.Array


@struct.dataclass
class OrbitParams:
    """The orbit (:class:`attitude_envs.plants.orbit.KeplerOrbit`): ``circular`` (the paper's
    circular approximation), ``semi_major_axis_m``, ``eccentricity``, ``mean_motion_rad_s``,
    ``semi_latus_rectum_m``, ``angular_momentum_m2_s``, ``mu_m3_s2``, the unit vectors
    ``node``, ``in_plane``, ``normal`` (ECI), ``arg_perigee_rad``, ``inclination_rad``."""

    circular: jax.Array
    semi_major_axis_m: jax.Array
    eccentricity: jax.Array
    mean_motion_rad_s: jax.Array
    semi_latus_rectum_m: jax.Array
    angular_momentum_m2_s: jax.Array
    mu_m3_s2: jax.Array
    node: jax.Array
    in_plane: jax.Array
    normal: jax.Array
    arg_perigee_rad: jax.Array
    inclination_rad: jax.Array


@struct.dataclass
class FieldParams:
    """The geomagnetic field: ``printed`` (eq. 9 as printed in the orbital frame, else the
    axial dipole at the position) and ``dipole_strength_t_m3`` (μ_e, T·m³)."""

    printed: jax.Array
    dipole_strength_t_m3: jax.Array


@struct.dataclass
class TimingParams:
    """``control_dt_s`` (s, the decision period) and ``integrator_dt_s`` (s, the RK4 sub-step;
    the env's static ``n_substeps`` times it is ``control_dt_s``)."""

    control_dt_s: jax.Array
    integrator_dt_s: jax.Array


@struct.dataclass
class CostParams:
    """``Q`` (6×6 on ``[q_e,vec, ω_e]``), ``R`` (3×3 on the body torque, 1/(N·m)²), the
    tumbling limit ``max_rate_rad_s`` (rad/s, on each of ``|ω_bo|``), ``termination_mode``
    (:func:`attitude_envs.jax.cost.mode_code`) and ``horizon_s`` (s, the charge's horizon T:
    ``episode_duration_s``)."""

    Q: jax.Array
    R: jax.Array
    max_rate_rad_s: jax.Array
    termination_mode: jax.Array
    horizon_s: jax.Array


@struct.dataclass
class StartParams:
    """The task and an episode's start: ``reference`` (the smooth bang-bang slew of eqs.
    36–38 in the kernel's packed layout, :func:`attitude_envs.plants.magnetorquer_kernels.pack_reference`),
    ``regulation`` (else tracking: q = q_d(0)), ``initial_angle_deg``, ``initial_rate_max_rad_s``,
    ``mean_anomaly_random`` (uniform in [0°, 360°)) or ``mean_anomaly_deg``."""

    reference: jax.Array
    regulation: jax.Array
    initial_angle_deg: jax.Array
    initial_rate_max_rad_s: jax.Array
    mean_anomaly_random: jax.Array
    mean_anomaly_deg: jax.Array


@struct.dataclass
class DisturbanceParams:
    """The external torque: ``code`` (the kernel's ``DIST_*``), ``scale``, ``rate_rad_s`` (ω0
    of eq. 39), ``harmonic`` (k = 1, or 2 with the second harmonic), ``amplitude_nm`` (3) and
    ``period_s`` (the sinusoid), ``initial`` (3: the constant torque or the walk's start, N·m,
    or the sinusoid's fixed phases, rad), ``random_phase``, ``walk_std`` (N·m/√s); and
    ``gravity_gradient`` (on or off)."""

    code: jax.Array
    scale: jax.Array
    rate_rad_s: jax.Array
    harmonic: jax.Array
    amplitude_nm: jax.Array
    period_s: jax.Array
    initial: jax.Array
    random_phase: jax.Array
    walk_std: jax.Array
    gravity_gradient: jax.Array


@struct.dataclass
class InertiaChangeParams:
    """ΔJ(t) of eq. (35), added to the true inertia when ``on``: ``amplitude_kg_m2``,
    ``frequency_rad_s``, ``phase_rad`` (3 each, on the diagonal)."""

    on: jax.Array
    amplitude_kg_m2: jax.Array
    frequency_rad_s: jax.Array
    phase_rad: jax.Array


@struct.dataclass
class UncertaintyParams:
    """The true inertia each episode (:class:`attitude_envs.uncertainty.InertiaUncertainty`):
    ``code`` (0 nominal, 1 fixed, 2 random), the fixed ``inertia_kg_m2`` and its ``eff_inv``,
    and for a random draw the nominal ``principal_moments`` and ``principal_axes``, the
    relative ``moment_scale`` and the axes' ``axis_angle_deg``."""

    code: jax.Array
    inertia_kg_m2: jax.Array
    eff_inv: jax.Array
    principal_moments: jax.Array
    principal_axes: jax.Array
    moment_scale: jax.Array
    axis_angle_deg: jax.Array


@struct.dataclass
class EnvParams:
    """Every number of the plant and the task (a pytree: ``jax.vmap`` over it randomizes
    plants, orbits, faults and tasks in one compiled program; SI units), in groups that
    default to the default preset's (Magnetorquer-v0's): ``plant``, ``orbit``, ``field``,
    ``timing``, ``cost`` (with the tumbling limit and the termination charge), ``start`` (the
    reference and the start's draws), ``disturbance``, ``inertia_change`` (ΔJ(t)),
    ``uncertainty`` (the true inertia's draw), ``faults`` (the actuator faults of every
    episode; an env with ``redraw_faults`` draws each episode's from its fault configs
    instead, as the numba env does), ``max_steps_in_episode`` (the time limit in decisions),
    ``flight`` (the flight conditions' actuator chain and draws, None in the lab) and
    ``sensors`` (the flight sensors, None: the truth is observed)."""

    plant: PlantParams = _default("plant")
    orbit: OrbitParams = _default("orbit")
    field: FieldParams = _default("field")
    timing: TimingParams = _default("timing")
    cost: CostParams = _default("cost")
    start: StartParams = _default("start")
    disturbance: DisturbanceParams = _default("disturbance")
    inertia_change: InertiaChangeParams = _default("inertia_change")
    uncertainty: UncertaintyParams = _default("uncertainty")
    faults: jfaults.FaultParams = struct.field(default_factory=jfaults.no_faults)
    max_steps_in_episode: jax.Array = _default("max_steps_in_episode")
    flight: FlightParams | None = None
    sensors: jsens.SuiteParams | None = None


class Context(NamedTuple):
    """What depends on time only, at one time: orbit rate ν̇ (rad/s), ν̈ (rad/s²), radius (m),
    field in the orbital frame (3, T), reference ``q_d`` (4) and ``ω_d`` (3, rad/s), true
    inertia ``I + ΔJ(t)`` and its ``I_eff⁻¹`` (3×3), disturbance torque (3, N·m, without
    gravity gradient)."""

    rate: jax.Array
    rate_dot: jax.Array
    radius: jax.Array
    field: jax.Array
    q_d: jax.Array
    w_d: jax.Array
    inertia: jax.Array
    eff_inv: jax.Array
    disturbance: jax.Array


# ----------------------------------------------------------------------------- time context
def true_anomaly(mean_anomaly0_rad: jax.Array, params: EnvParams, t_s: jax.Array) -> jax.Array:
    """ν(t), rad, from Kepler's equation ``M = E − e sin E`` (Newton until ``|ΔE| < 1e-13``,
    at most 30 iterations, as :func:`~attitude_envs.plants.magnetorquer_kernels.true_anomaly`)."""
    mean = mean_anomaly0_rad + params.orbit.mean_motion_rad_s * t_s
    e = params.orbit.eccentricity

    def cond(carry):
        _, i, done = carry
        return jnp.logical_and(jnp.logical_not(done), i < 30)

    def body(carry):
        ecc, i, _ = carry
        step = (ecc - e * jnp.sin(ecc) - mean) / (1.0 - e * jnp.cos(ecc))
        return ecc - step, i + 1, jnp.abs(step) < 1e-13

    ecc, _, _ = jax.lax.while_loop(cond, body, (mean + e * jnp.sin(mean), 0, jnp.asarray(False)))
    nu = 2.0 * jnp.arctan2(jnp.sqrt(1 + e) * jnp.sin(ecc / 2), jnp.sqrt(1 - e) * jnp.cos(ecc / 2))
    return jnp.where(e == 0.0, mean, nu)


def orbital_to_body(q: jax.Array) -> jax.Array:
    """``R`` (orbital → body) of Sadigh et al. 2022 eq. (4) of a scalar-last ``q`` (3×3)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return jnp.stack(
        [
            jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)]),
            jnp.stack([2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)]),
            jnp.stack([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)]),
        ]
    )


def _field_orbital(params: EnvParams, r, u, pos, frame_t) -> jax.Array:
    """The field in the orbital frame (T): eq. (9) as printed (``field_printed``), or the axial
    dipole ``μ_e/r³ [3(m̂·r̂)r̂ − m̂]``, ``m̂ = −z``, at the ECI position rotated to the frame."""
    printed = jnp.stack(_PLANT.printed_field(r, u, params.field.dipole_strength_t_m3, params.orbit.inclination_rad))
    b = jnp.stack(_PLANT.dipole_eci(pos[0], pos[1], pos[2], params.field.dipole_strength_t_m3))
    dipole = frame_t @ b  # eci_from_orbitalᵀ b
    return jnp.where(params.field.printed, printed, dipole)


def reference(ref: jax.Array, t_s: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Desired quaternion ``q_d`` (scalar last, w ≥ 0) and body rate ``ω_d`` (rad/s) of the
    smooth bang-bang 3-2-1 slew (Sadigh et al. 2022 eqs. 36–38) at ``t_s``; held at t ≤ 0 and
    t ≥ t_f (:func:`~attitude_envs.plants.magnetorquer_kernels.reference_into`)."""
    # profile (∫∫f, ∫f) of the piece t falls in (Horner, highest power first), else the
    # linear continuation after t_f
    pieces = ref[K.REF_PIECES : K.REF_PIECES + 3 * K.REF_PIECE_SIZE].reshape(3, K.REF_PIECE_SIZE)
    coefs = pieces[:, 2 + K.REF_COEFS : 2 + 3 * K.REF_COEFS].reshape(3, 2, K.REF_COEFS)  # [∫f, ∫∫f]
    acc = jnp.zeros((3, 2), ref.dtype)
    for i in range(K.REF_COEFS):
        acc = acc * t_s + coefs[:, :, i]
    p = ref[K.REF_FINAL_P] + ref[K.REF_FINAL_V] * (t_s - ref[K.REF_TF])
    v = ref[K.REF_FINAL_V]
    for k in (2, 1, 0):
        inside = t_s <= pieces[k, 1]
        p, v = jnp.where(inside, acc[k, 1], p), jnp.where(inside, acc[k, 0], v)
    start, gain = ref[K.REF_START : K.REF_START + 3], ref[K.REF_GAIN : K.REF_GAIN + 3]
    qw = jnp.stack(_PLANT.euler_reference(p, v, start[0], start[1], start[2], gain[0], gain[1], gain[2]))
    held_start = ref[K.REF_HELD_START : K.REF_HELD_START + 7]
    held_end = ref[K.REF_HELD_END : K.REF_HELD_END + 7]
    qw = jnp.where(t_s >= ref[K.REF_TF], held_end, qw)
    qw = jnp.where(jnp.logical_or(ref[K.REF_CONST] != 0.0, t_s <= 0.0), held_start, qw)
    return qw[:4], qw[4:]


def _orbit_rate_in_body(q: jax.Array, orbit_rate: jax.Array) -> jax.Array:
    """``R ω_oi`` (rad/s, body axes) with ``ω_oi = [0, −ν̇, 0]`` (eq. 3) for the attitude ``q``
    and the orbit rate ν̇ ``orbit_rate``: ``R``'s second column times −ν̇ (the numba kernel's
    snapshot)."""
    return orbital_to_body(q)[:, 1] * (-orbit_rate)


def _inverse3(m):
    """``inv(m)`` of a 3×3 matrix by its adjugate (the plant definition's ``inverse3``)."""
    return jnp.stack(_PLANT.inverse3(m.reshape(9), 0)).reshape(3, 3)


def disturbance_torque(params: EnvParams, disturbance: jax.Array, t_s: jax.Array) -> jax.Array:
    """The external torque at ``t_s`` (N·m, body axes, without gravity gradient): Sadigh et
    al. 2022 eq. (39) ``d_j = d0 + d1 sin(ω0 t + φ_j1) + d2 sin(k ω0 t + φ_j2)`` (d0 = 1e-7,
    d1 = d2 = 1e-5), the held ``disturbance`` torque, or a sinusoid with the phases
    ``disturbance``; times ``disturbance_scale``."""
    scale = params.disturbance.scale
    a = params.disturbance.rate_rad_s * t_s
    b = params.disturbance.harmonic * params.disturbance.rate_rad_s * t_s
    q = math.pi / 4
    sines = (jnp.sin(a + q), jnp.sin(a - q), jnp.sin(b - q), jnp.sin(b + q), jnp.sin(a), jnp.sin(b + 2 * q))
    paper = jnp.stack(_PLANT.paper_disturbance(scale, *sines))
    held = scale * disturbance
    arg = 2 * math.pi * t_s / params.disturbance.period_s
    sinusoid = scale * (params.disturbance.amplitude_nm * jnp.sin(arg + disturbance))
    code = params.disturbance.code
    return jnp.select(
        [code == K.DIST_PAPER, code == K.DIST_HELD, code == K.DIST_SINUSOIDAL],
        [paper, held, sinusoid],
        jnp.zeros_like(paper),
    )


def orbit_field(
    params: EnvParams, mean_anomaly0_rad: jax.Array, t_s: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """The orbit's ν̇ (rad/s), ν̈ (rad/s²) and radius (m) and the field in the orbital frame
    (3, T) at ``t_s`` (s): Keplerian, or the circular approximation
    (:func:`~attitude_envs.plants.magnetorquer_kernels.orbit_state_into`, ``field_orbital_into``)."""
    nu = true_anomaly(mean_anomaly0_rad, params, t_s)
    r_k, nd_k, _, ndd_k = _PLANT.kepler_rates(
        nu,
        params.orbit.eccentricity,
        params.orbit.angular_momentum_m2_s,
        params.orbit.semi_latus_rectum_m,
        params.orbit.mu_m3_s2,
    )
    u_c = params.orbit.arg_perigee_rad + mean_anomaly0_rad + params.orbit.mean_motion_rad_s * t_s
    circ = params.orbit.circular
    u = jnp.where(circ, u_c, params.orbit.arg_perigee_rad + nu)
    r = jnp.where(circ, params.orbit.semi_major_axis_m, r_k)
    nd = jnp.where(circ, params.orbit.mean_motion_rad_s, nd_k)
    ndd = jnp.where(circ, 0.0, ndd_k)
    cu, su = jnp.cos(u), jnp.sin(u)
    r_hat = params.orbit.node * cu + params.orbit.in_plane * su
    t_hat = -params.orbit.node * su + params.orbit.in_plane * cu
    pos = r * r_hat
    # LVLH: x = t̂, y = −ĥ (anti-normal), z = −r̂ (nadir)
    field = _field_orbital(params, r, u, pos, jnp.stack([t_hat, -params.orbit.normal, -r_hat]))
    return nd, ndd, r, field


def context(params: EnvParams, state: EnvState, t_s: jax.Array) -> Context:
    """Everything that depends on time only at ``t_s`` (s): the orbit and the field
    (:func:`orbit_field`), the reference, ``I + ΔJ(t)`` (eq. 35) with its ``I_eff⁻¹``, the
    disturbance (:func:`~attitude_envs.plants.magnetorquer_kernels.context_into`)."""
    nd, ndd, r, field = orbit_field(params, state.mean_anomaly0_rad, t_s)
    q_d, w_d = reference(params.start.reference, t_s)
    # true inertia I + ΔJ(t) (eq. 35) and its I_eff⁻¹
    dj = params.inertia_change.amplitude_kg_m2 * jnp.sin(
        params.inertia_change.frequency_rad_s * t_s + params.inertia_change.phase_rad
    )
    diagonal = jnp.diagonal(state.inertia_kg_m2) + dj
    inertia_t = jnp.where(jnp.eye(3, dtype=bool), jnp.diag(diagonal), state.inertia_kg_m2)
    eff = inertia_t.at[1, 1].add(-params.plant.wheel_inertia_kg_m2)
    tv = params.inertia_change.on
    inertia = jnp.where(tv, inertia_t, state.inertia_kg_m2)
    eff_inv = jnp.where(tv, _inverse3(eff), state.inertia_eff_inv)
    return Context(
        rate=nd,
        rate_dot=ndd,
        radius=r,
        field=field,
        q_d=q_d,
        w_d=w_d,
        inertia=inertia,
        eff_inv=eff_inv,
        disturbance=disturbance_torque(params, state.disturbance, t_s),
    )


# ----------------------------------------------------------------------------- plant
def error_state(q: jax.Array, rate: jax.Array, q_d: jax.Array, w_d: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``x = [q_e,vec, ω_e]`` (6) and ``q_e,w``: ``q_e = q_d* ⊗ q`` (w ≥ 0), ``ω_e = ω − C(q_e)ᵀ ω_d``
    (the plant definition's error state)."""
    e = _PLANT.error_state(q[0], q[1], q[2], q[3], rate[0], rate[1], rate[2], jnp.concatenate([q_d, w_d]), 0, True)
    return jnp.stack(e[:6]), e[6]


def _flat(ctx: Context) -> jax.Array:
    """The context in the definition's compact layout
    (:data:`~attitude_envs.plants.magnetorquer_definition.COMPACT_LAYOUT`)."""
    return jnp.concatenate(
        [
            jnp.stack([ctx.rate, ctx.rate_dot, ctx.radius]),
            ctx.field,
            ctx.q_d,
            ctx.w_d,
            ctx.inertia.reshape(9),
            ctx.eff_inv.reshape(9),
            ctx.disturbance,
        ]
    )


def derivative(aug: jax.Array, m: jax.Array, t_w: jax.Array, params: EnvParams, ctx: Context) -> jax.Array:
    """``d/dt [q, ω_bo, Ω, cost]`` (the plant definition's augmented derivative) with the
    dipoles ``m`` (A·m²) and the wheel torque on the body ``t_w`` (N·m) held; the stage cost's
    full quadratic forms (equal to the kernel's diagonal path for a diagonal Q, R)."""
    dz = _PLANT.augmented(
        aug,
        0,
        m,
        t_w,
        _flat(ctx),
        0,
        COMPACT_LAYOUT,
        params.plant.wheel_inertia_kg_m2,
        params.disturbance.gravity_gradient,
        params.cost.Q,
        params.cost.R,
        False,
        True,
    )
    return jnp.stack(dz)


class MagnetorquerEnv(Environment):
    """The JAX plant of Magnetorquer-v0/-v1 (module docstring). Static (fixed at
    construction, part of the compiled program): ``n_substeps`` (RK4 sub-steps per control
    step), ``observe_field`` (the observation appends the body field / 5e-5 T), ``fault_hint``
    (it appends 8 active-fault flags: m_x, m_y, m_z, wheel, then 4 sensor channels, never
    faulted here), ``random_walk`` (the held disturbance torque takes a random-walk
    increment per step, drawn from the step's key), the fault configs (``fault_configs``;
    ``redraw_faults``: draw each episode's faults from them), the observation bounds,
    ``flight`` (:class:`FlightLayout`, None in the lab) and ``sensors`` (the modeled sensor
    channels; empty: the truth is observed).

    Action: ``Box(-1, 1, (4,))``, clipped: ``m = a[:3] · max_dipole_am2`` (A·m²),
    ``T_w = a[3] · max_wheel_torque_nm`` (N·m, on the body about +y). Observation (compute
    dtype): ``[q_e,vec (3), ω_e (3, rad/s), Ω/1000 (krad/s)]``, then ``b_body / 5e-5 T`` (3)
    with ``observe_field``, then the hint flags; zeros when the state is not finite. With
    sensors, of the readings. Reward ``−∫ (xᵀQx + uᵀRu) dt`` over the step, minus the termination charge."""

    def __init__(
        self,
        default_params: EnvParams,
        *,
        n_substeps: int = 1,
        observe_field: bool = False,
        fault_hint: bool = False,
        random_walk: bool = False,
        fault_configs: tuple[dict, ...] = (),
        redraw_faults: bool = False,
        obs_low: np.ndarray | None = None,
        obs_high: np.ndarray | None = None,
        flight: FlightLayout | None = None,
        sensors: tuple[str, ...] = (),
    ) -> None:
        self.n_substeps = int(n_substeps)
        self.observe_field = bool(observe_field)
        self.fault_hint = bool(fault_hint)
        self.random_walk = bool(random_walk)
        self.fault_configs = tuple(dict(c) for c in fault_configs)
        self.redraw_faults = bool(redraw_faults)
        self.n_faults = int(default_params.faults.kind.shape[-1])
        self.obs_size = 7 + (3 if self.observe_field else 0) + (N_ACTUATORS + N_SENSOR_FLAGS if self.fault_hint else 0)
        self.obs_low = np.full(self.obs_size, -np.inf) if obs_low is None else np.asarray(obs_low, float)
        self.obs_high = np.full(self.obs_size, np.inf) if obs_high is None else np.asarray(obs_high, float)
        #: the flight conditions' static layout (None: the lab, the step and reset unchanged)
        self.flight = flight
        #: the sensor channels modeled (empty: the truth is observed)
        self.sensors = tuple(sensors)
        self._default_params = default_params

    @property
    def name(self) -> str:
        return "Magnetorquer"

    # ------------------------------------------------------------------ observation
    def _observe(
        self,
        state: EnvState,
        q_d: jax.Array,
        w_d: jax.Array,
        field,
        t_s: jax.Array,
        body_field=None,
        sensor_params: jsens.SuiteParams | None = None,
    ) -> jax.Array:
        """The observation of ``state`` at ``t_s`` with the reference ``q_d``, ``w_d`` and the
        orbital-frame ``field`` (T; read with ``observe_field`` only) of that time, or the
        ``body_field`` (T) when given (a magnetometer's reading); the ``fault_hint`` flags of
        the sensors' faults from ``sensor_params`` and the state's sensors."""
        x, _ = error_state(state.attitude, state.rate_rad_s, q_d, w_d)
        parts = [x, state.wheel_speed_rad_s / K.WHEEL_SPEED_SCALE_RAD_S]
        if self.observe_field:
            if body_field is None:
                q = state.attitude
                b = jnp.stack(_PLANT.body_vector(q[0], q[1], q[2], q[3], field[0], field[1], field[2]))
            else:
                b = body_field
            parts.append(b / K.FIELD_SCALE_T)
        if self.fault_hint:
            flags = jfaults.active_flags(state.faults, t_s, N_ACTUATORS).astype(x.dtype)
            parts += [flags, jsens.suite_flags(sensor_params, state.sensors, jsens.SUITE_CHANNELS, t_s, x.dtype)]
        return jnp.concatenate(parts)

    def observation(self, state: EnvState, params: EnvParams) -> jax.Array:
        """The observation of ``state`` at its time ``time · control_dt_s`` (with sensors, of
        their last readings)."""
        t_s = state.time.astype(state.rate_rad_s.dtype) * params.timing.control_dt_s
        q_d, w_d = reference(params.start.reference, t_s)
        if self.sensors:
            rate, _, _, field = orbit_field(params, state.mean_anomaly0_rad, t_s)
            readings = self.readings(state, rate, field)
            return self._observe_readings(state, readings, q_d, w_d, rate, t_s, params.sensors)
        field = orbit_field(params, state.mean_anomaly0_rad, t_s)[3] if self.observe_field else None
        return self._observe(state, q_d, w_d, field, t_s)

    # ------------------------------------------------------------------ sensors
    def _truths(self, state: EnvState, orbit_rate: jax.Array, field: jax.Array) -> dict[str, jax.Array]:
        """What each sensor channel measures in ``state``, given the orbit rate ν̇ (rad/s) and
        the orbital-frame field (3, T) of its time: ω_bi = ω_bo + R ω_oi (rad/s), the attitude,
        Ω (rad/s), the body field ``R b_o`` (T) (the numba kernel's snapshot)."""
        q = state.attitude
        x, y, z, w = q[0], q[1], q[2], q[3]
        return {
            "gyro": state.rate_rad_s + _orbit_rate_in_body(q, orbit_rate),
            "star_tracker": q,
            "tachometer": state.wheel_speed_rad_s,
            "magnetometer": jnp.stack(_PLANT.body_vector(x, y, z, w, field[0], field[1], field[2])),
        }

    def readings(self, state: EnvState, orbit_rate: jax.Array, field: jax.Array) -> dict[str, jax.Array]:
        """The sensors' last readings of ``state`` (a channel not modeled reads the truth,
        :meth:`_truths`, at the state's orbit rate ν̇ and orbital-frame field)."""
        truths = self._truths(state, orbit_rate, field)
        if state.sensors is None:
            return truths
        return {
            name: truths[name] if getattr(state.sensors, name) is None else getattr(state.sensors, name).last
            for name in _AXES
        }

    def _observe_readings(
        self,
        state: EnvState,
        readings: dict[str, jax.Array],
        q_d: jax.Array,
        w_d: jax.Array,
        orbit_rate: jax.Array,
        t_s: jax.Array,
        sensor_params: jsens.SuiteParams | None = None,
    ) -> jax.Array:
        """The observation built from sensor ``readings`` as the numba env's: the error state of
        the star tracker's attitude and ``ω_bo = gyro − R(q_m) ω_oi`` (ν̇ ``orbit_rate``), the
        tachometer's Ω and the magnetometer's field."""
        q_m = readings["star_tracker"]
        rate = readings["gyro"] - _orbit_rate_in_body(q_m, orbit_rate)
        measured = state.replace(attitude=q_m, rate_rad_s=rate, wheel_speed_rad_s=readings["tachometer"])
        return self._observe(measured, q_d, w_d, None, t_s, readings["magnetometer"], sensor_params)

    # ------------------------------------------------------------------ dynamics
    def control_step(
        self, state: EnvState, delivered: jax.Array, t0_s: jax.Array, t1_s: jax.Array, params: EnvParams
    ) -> tuple[jax.Array, jax.Array, jax.Array, Context]:
        """Advance the physical state from ``t0_s`` to ``t1_s`` with ``delivered`` (``[m (3),
        T_w]``) held over ``n_substeps`` RK4 sub-steps of ``integrator_dt_s`` (the last ends at
        ``t1_s``): ``(y = [q, ω_bo, Ω] (8), cost ∫ (xᵀQx + uᵀRu) dt, applied (4: the dipoles,
        the mean wheel torque after the momentum limit), the time context at t1_s)``."""
        dtype = state.rate_rad_s.dtype
        t0_s, t1_s = jnp.asarray(t0_s, dtype), jnp.asarray(t1_s, dtype)
        n, h = self.n_substeps, params.timing.integrator_dt_s
        starts = t0_s + jnp.arange(n, dtype=dtype) * h
        times = jnp.concatenate([starts, starts + 0.5 * h, t1_s[None]])
        ctxs = jax.vmap(lambda t: context(params, state, t))(times)

        # sub-step j's stages: its start t0 + j h, the middle (twice), its end where the next
        # starts (the last at t1_s): (n, 4, ...) per context entry, by slices (no gathers)
        def stages(a):
            end = jnp.concatenate([a[1:n], a[2 * n :]])
            return jnp.stack([a[:n], a[n : 2 * n], a[n : 2 * n], end], axis=1)

        stage_ctxs = jax.tree.map(stages, ctxs)
        m = delivered[:3]
        j_w, h_max = params.plant.wheel_inertia_kg_m2, params.plant.max_wheel_momentum_nms

        def substep(carry, stage_ctx):
            aug, wheel_sum = carry
            t_w = _PLANT.wheel_torque(delivered[3], aug[0], aug[2], aug[5], aug[7], stage_ctx.rate[0], j_w, h_max)

            # classical RK4 as one loop over its stages (one copy of the derivative in the
            # program): stage s at aug + c_s k_(s-1) with the context of t, t + h/2, t + h/2,
            # t + h; the slopes summed k1 + 2 k2 + 2 k3 + k4 in that order
            def stage(carry, sx):
                k_prev, total = carry
                cx, c, weight = sx
                k = derivative(aug + c * k_prev, m, t_w, params, cx)
                return (k, total + weight * k), None

            c = jnp.stack([0.0, 0.5 * h, 0.5 * h, h]).astype(dtype)
            weights = jnp.asarray([1.0, 2.0, 2.0, 1.0], dtype)
            zeros = jnp.zeros_like(aug)
            (_, total), _ = jax.lax.scan(stage, (zeros, zeros), (stage_ctx, c, weights))
            aug = aug + (h / 6.0) * total
            norm = jnp.sqrt(aug[0] * aug[0] + aug[1] * aug[1] + aug[2] * aug[2] + aug[3] * aug[3])
            aug = jnp.concatenate([aug[:4] / norm, aug[4:]])
            return (aug, wheel_sum + t_w), None

        aug0 = jnp.concatenate([state.attitude, state.rate_rad_s, state.wheel_speed_rad_s, jnp.zeros(1, dtype)])
        (aug, wheel_sum), _ = jax.lax.scan(substep, (aug0, jnp.zeros((), dtype)), stage_ctxs)
        applied = jnp.concatenate([m, (wheel_sum / n)[None]])
        return aug[:8], aug[8], applied, jax.tree.map(lambda a: a[2 * n], ctxs)

    def advance_disturbance(self, key: jax.Array, disturbance: jax.Array, params: EnvParams) -> jax.Array:
        """The held disturbance one control period on: with ``random_walk`` a held torque
        adds ``σ √Δt · N(0, I)`` N·m (``disturbance_walk_std`` σ); else (and for the
        sinusoid's phases and the other kinds) it is unchanged."""
        if not self.random_walk:
            return disturbance
        noise = jax.random.normal(key, (3,), disturbance.dtype)
        walked = disturbance + params.disturbance.walk_std * jnp.sqrt(params.timing.control_dt_s) * noise
        return jnp.where(params.disturbance.code == K.DIST_HELD, walked, disturbance)

    def step_env(self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams):
        """One decision: clip the action to [-1, 1] and scale it to ``[m, T_w]``, apply the
        actuator faults at the step's start time (under flight conditions between the
        actuator chain's command and output stages), move a random-walk disturbance on,
        advance ``n_substeps`` RK4 sub-steps, charge the step's cost (plus the termination
        charge on a finite step with ``max|ω_bo| > max_rate_rad_s``), sample the sensors at the
        step's end. Reward ``−cost``."""
        dtype = state.rate_rad_s.dtype
        key_fault, key_dist = jax.random.split(key) if self.random_walk else (key, key)
        limits = jnp.stack(
            [
                params.plant.max_dipole_am2,
                params.plant.max_dipole_am2,
                params.plant.max_dipole_am2,
                params.plant.max_wheel_torque_nm,
            ]
        ).astype(dtype)
        commanded = jnp.clip(jnp.asarray(action, dtype), -1.0, 1.0) * limits
        t0 = state.time.astype(dtype) * params.timing.control_dt_s
        time = state.time + 1
        t1 = time.astype(dtype) * params.timing.control_dt_s

        def faulted(c: jax.Array):
            if state.faults.kind.shape[-1]:
                return jfaults.apply(state.faults, state.fault_state, key_fault, c, t0, limits)
            return c, state.fault_state

        fl, flight = self.flight, state.flight
        if fl is None:
            delivered, fault_state = faulted(commanded)
        else:  # ActuatorChain.deliver; the wheel's friction against −Ω (T_w acts on the body)
            speeds = jnp.concatenate([jnp.zeros(3, dtype), -state.wheel_speed_rad_s])
            delivered, fault_state, actuators = jact.deliver(
                fl.actuators, params.flight.actuators, flight.actuators, commanded, faulted, flight.gain, speeds
            )
            flight = flight.replace(actuators=actuators)
        state = state.replace(disturbance=self.advance_disturbance(key_dist, state.disturbance, params))
        y, cost, applied, ctx_end = self.control_step(state, delivered, t0, t1, params)
        new_state = state.replace(
            time=time,
            attitude=y[:4],
            rate_rad_s=y[4:7],
            wheel_speed_rad_s=y[7:],
            fault_state=fault_state,
            flight=flight,
        )
        if not self.sensors:  # traced before ``finite``, as the lab's program always was
            obs = self._observe(new_state, ctx_end.q_d, ctx_end.w_d, ctx_end.field, t1)
        finite = jnp.isfinite(cost) & jnp.all(jnp.isfinite(y))
        if self.sensors:  # sampled at the step's end, kept when the state is finite (the numba env's _measure)
            truths = self._truths(new_state, ctx_end.rate, ctx_end.field)
            _, sampled = jsens.measure_suite(
                jax.random.fold_in(key, jsens.SENSOR_STREAM), params.sensors, state.sensors, truths, t1
            )
            new_state = new_state.replace(
                sensors=jax.tree.map(lambda a, b: jnp.where(finite, a, b), sampled, state.sensors)
            )
            readings = self.readings(new_state, ctx_end.rate, ctx_end.field)
            obs = self._observe_readings(
                new_state, readings, ctx_end.q_d, ctx_end.w_d, ctx_end.rate, t1, params.sensors
            )
        crossed = jnp.any(jnp.stack(_PLANT.limit_rows(y[4], y[5], y[6], params.cost.max_rate_rad_s)) > 0.0)
        terminated = jnp.logical_not(finite) | crossed
        x_end, _ = error_state(new_state.attitude, new_state.rate_rad_s, ctx_end.q_d, ctx_end.w_d)
        charge = jcost.termination_charge(params.cost.termination_mode, x_end, params.cost.Q, params.cost.horizon_s, t1)
        cost = cost + jnp.where(terminated & finite, charge, 0.0)
        obs = jnp.where(finite, obs, jnp.zeros_like(obs))
        info = {"cost": cost, "time_s": t1, "commanded": commanded, "applied": applied}
        return obs, new_state, -cost, terminated, info

    def reset_env(self, key: jax.Array, params: EnvParams):
        """A fresh episode drawn as the numba env draws it: the true inertia (nominal, fixed,
        or principal moments scaled by ``1 + U(−s, s)`` until they meet the triangle
        inequality and the axes turned by a random rotation of up to ``axis_angle_deg``), the
        orbit start (mean anomaly uniform in [0°, 360°), or fixed), the attitude (q_d(0), or
        with ``regulation`` q_d(0) ⊗ a rotation about a uniform axis by an angle uniform in
        [0, ``initial_angle_deg``]), ω_bo uniform in ±``initial_rate_max_rad_s``, Ω = 0, the
        sinusoid's phases (uniform in [0, 2π) when random), the faults (``params.faults``, or
        drawn from the configs with ``redraw_faults``) and their runtime state; under flight
        conditions the actuator chain at rest, the true inertia and the gains drawn from a
        folded key (:meth:`_draw_flight`) and the sensors' biases and first sample."""
        dtype = params.start.reference.dtype
        # two draws for everything but the faults (few random-number programs to compile)
        k_uniform, k_normal, k_moments, k_faults, k_fault_state = jax.random.split(key, 5)
        u = jax.random.uniform(k_uniform, (9,), dtype)
        g = jax.random.normal(k_normal, (6,), dtype)
        inertia, eff_inv = _draw_inertia(k_moments, u[8], g[3:], params)
        anomaly_deg = jnp.where(params.start.mean_anomaly_random, 360.0 * u[0], params.start.mean_anomaly_deg)
        q_d0 = params.start.reference[K.REF_HELD_START : K.REF_HELD_START + 4]
        turn = jq.from_axis_angle(g[:3], jnp.deg2rad(u[1] * params.start.initial_angle_deg))
        q0 = jnp.where(params.start.regulation, jq.multiply(q_d0, turn), q_d0)
        rate = (2.0 * u[2:5] - 1.0) * params.start.initial_rate_max_rad_s
        random_phase = params.disturbance.random_phase & (params.disturbance.code == K.DIST_SINUSOIDAL)
        disturbance = jnp.where(random_phase, (2 * math.pi) * u[5:8], params.disturbance.initial)
        faults = params.faults
        if self.redraw_faults:
            faults = jfaults.for_episode(k_faults, self.fault_configs, N_ACTUATORS, params.faults)
        state = EnvState(
            time=jnp.zeros((), jnp.int32),
            attitude=q0,
            rate_rad_s=rate,
            wheel_speed_rad_s=jnp.zeros(1, dtype),
            mean_anomaly0_rad=jnp.deg2rad(anomaly_deg),
            inertia_kg_m2=inertia,
            inertia_eff_inv=eff_inv,
            disturbance=disturbance,
            faults=faults,
            fault_state=jfaults.initial_state(k_fault_state, faults),
        )
        if self.flight is not None:
            state = self._draw_flight(jax.random.fold_in(key, jact.FLIGHT_STREAM), state, params)
        # the observation at t = 0: the reference is held at its start
        t0 = jnp.zeros((), dtype)
        held = params.start.reference[K.REF_HELD_START : K.REF_HELD_START + 7]
        if self.sensors:  # the biases drawn and the first sample at t = 0
            orbit_rate, _, _, field = orbit_field(params, state.mean_anomaly0_rad, t0)
            truths = self._truths(state, orbit_rate, field)
            k_bias, k_measure = jax.random.split(jax.random.fold_in(key, jsens.SENSOR_STREAM))
            start = jsens.start_suite(k_bias, params.sensors, truths, t0)
            state = state.replace(sensors=jsens.measure_suite(k_measure, params.sensors, start, truths, t0)[1])
            readings = self.readings(state, orbit_rate, field)
            return self._observe_readings(state, readings, held[:4], held[4:], orbit_rate, t0, params.sensors), state
        field = orbit_field(params, state.mean_anomaly0_rad, t0)[3] if self.observe_field else None
        return self._observe(state, held[:4], held[4:], field, t0), state

    def _draw_flight(self, key: jax.Array, state: EnvState, params: EnvParams) -> EnvState:
        """``state`` with its flight state: the actuator chain at rest and, with the parameters
        drawn, the true inertia (principal moments within ``1 ± inertia_moment``, axes turned by
        up to ``inertia_axis_deg``: :meth:`attitude_envs.uncertainty.InertiaUncertainty.draw`'s
        law, as the numba env's flight draw) and the actuators' gains ``1 + U(−tol, tol)``, from
        ``key`` (not the numba env's draws), or the params' ``given_*`` draws."""
        fl, fp = self.flight, params.flight
        dtype = params.start.reference.dtype
        flight = FlightState(actuators=jact.initial_state(fl.actuators, N_ACTUATORS, dtype))
        if not fl.parameters:
            return state.replace(flight=flight)
        k_moments, k_uniform, k_normal = jax.random.split(key, 3)
        u = jax.random.uniform(k_uniform, (1 + N_ACTUATORS,), dtype)
        inertia, eff_inv = state.inertia_kg_m2, state.inertia_eff_inv
        if fl.draw_inertia:
            axis = jax.random.normal(k_normal, (3,), dtype)
            inertia, eff_inv = _random_inertia(
                k_moments,
                u[0],
                axis,
                params.uncertainty.principal_moments,
                params.uncertainty.principal_axes,
                fp.inertia_moment,
                fp.inertia_axis_deg,
                params.plant.wheel_inertia_kg_m2,
            )
        if fl.actuators.gain:
            gain = 1.0 + fp.gain_tolerance * (2.0 * u[1:] - 1.0)
            flight = flight.replace(gain=jnp.where(fp.given, fp.given_gain, gain))
        return state.replace(
            inertia_kg_m2=jnp.where(fp.given, fp.given_inertia_kg_m2, inertia),
            inertia_eff_inv=jnp.where(fp.given, fp.given_inertia_eff_inv, eff_inv),
            flight=flight,
        )

    # ------------------------------------------------------------------ spaces
    def action_space(self, params: EnvParams | None = None) -> Box:
        """``Box(-1, 1, (4,))``: dipoles / ``max_dipole_am2``, wheel torque / ``max_wheel_torque_nm``."""
        return Box(-1.0, 1.0, (N_ACTUATORS,), jnp.float32)

    def observation_space(self, params: EnvParams | None = None) -> Box:
        """The numba env's bounds (``q_e`` in ±1, ``ω_e`` in ±2·max_rate, Ω/1000 in ±1e3, the
        scaled field in ±3, flags in [0, 1]), in the compute dtype."""
        return Box(self.obs_low, self.obs_high, (self.obs_size,), jnp.result_type(float))

    # ------------------------------------------------------------------ numba bridge
    def state_from(self, numba_env: Any, key: jax.Array | None = None) -> EnvState:
        """The JAX state of the numba env's current episode: the physical state, decisions
        taken, the episode's draws (orbit phase, true inertia, disturbance entry) and its
        realized actuator faults with their runtime state and, under flight conditions, its
        drawn gains with the actuator chain at rest (its delay line and lag state are not
        public: a ``ValueError`` after the first step with a delay or actuator dynamics; one for
        an env with sensors, whose samples are not public either). An intermittent fault not yet
        evaluated gets its first switch time drawn with ``key`` (default ``PRNGKey(0)``)
        from the same law. ``numba_env`` may be wrapped (``gym.make``'s env)."""
        numba_env = getattr(numba_env, "unwrapped", numba_env)
        chain = None if self.flight is None else self.flight.actuators
        check_state_from(bool(self.sensors), chain, int(numba_env.steps_taken))
        flight = None
        if self.flight is not None:
            flight = FlightState(actuators=jact.initial_state(chain, N_ACTUATORS, jnp.result_type(float)))
            if chain.gain:
                gain = np.asarray(numba_env.drawn_parameters()["actuator_gain"], dtype=float)
                flight = flight.replace(gain=jnp.asarray(gain))
        realized = numba_env.fault_layer.realized
        if len(realized) > self.n_faults:
            raise ValueError(
                f"the numba env realized {len(realized)} faults; this JAX env holds {self.n_faults} "
                "(build it with attitude_envs.jax.make and the faults the numba env was given)"
            )
        faults, fault_state = jfaults.from_numba_layer(realized, self.n_faults, key, dtype=float)
        y = np.asarray(numba_env.state_row, dtype=float)
        ep = np.asarray(numba_env.episode_constants, dtype=float)

        def f(v: Any) -> jax.Array:
            return jnp.asarray(np.asarray(v, dtype=float))

        return EnvState(
            time=jnp.asarray(numba_env.steps_taken, jnp.int32),
            attitude=f(y[:4]),
            rate_rad_s=f(y[4:7]),
            wheel_speed_rad_s=f(y[7:8]),
            mean_anomaly0_rad=f(ep[K.EN_ORBIT + K.ORB_M0]),
            inertia_kg_m2=f(ep[K.EN_INERTIA : K.EN_INERTIA + 9].reshape(3, 3)),
            inertia_eff_inv=f(ep[K.EN_EFF_INV : K.EN_EFF_INV + 9].reshape(3, 3)),
            disturbance=f(ep[K.EN_DIST : K.EN_DIST + 3]),
            faults=faults,
            fault_state=fault_state,
            flight=flight,
        )


# ----------------------------------------------------------------------------- draws
#: candidate moment draws per reset (the numba env redraws up to 1000 times)
MOMENT_CANDIDATES = 32


def _draw_inertia(
    key: jax.Array, u_angle: jax.Array, axis: jax.Array, params: EnvParams
) -> tuple[jax.Array, jax.Array]:
    """The episode's true inertia (kg·m²) and its ``I_eff⁻¹``
    (:meth:`attitude_envs.uncertainty.InertiaUncertainty.draw`): nominal, fixed, or (random)
    the principal moments scaled by ``1 + U(−s, s)``, the first of :data:`MOMENT_CANDIDATES`
    draws that meets the triangle inequality (the law of the numba env's redraw loop; the
    nominal moments if none does), and the principal axes turned by ``axis`` (N(0, I)) by
    ``u_angle · axis_angle_deg`` (``u_angle`` uniform in [0, 1])."""
    inertia, inertia_inv = _random_inertia(
        key,
        u_angle,
        axis,
        params.uncertainty.principal_moments,
        params.uncertainty.principal_axes,
        params.uncertainty.moment_scale,
        params.uncertainty.axis_angle_deg,
        params.plant.wheel_inertia_kg_m2,
    )
    code = params.uncertainty.code
    inertia = jnp.where(
        code == 2, inertia, jnp.where(code == 1, params.uncertainty.inertia_kg_m2, params.plant.inertia_kg_m2)
    )
    eff_inv = jnp.where(
        code == 2, inertia_inv, jnp.where(code == 1, params.uncertainty.eff_inv, params.plant.inertia_eff_inv)
    )
    return inertia, eff_inv


def _random_inertia(
    key: jax.Array,
    u_angle: jax.Array,
    axis: jax.Array,
    principal_moments: jax.Array,
    principal_axes: jax.Array,
    moment_scale: jax.Array,
    axis_angle_deg: jax.Array,
    wheel_inertia_kg_m2: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """A random true inertia (kg·m²) and its ``I_eff⁻¹`` (1/(kg·m²)) by
    :meth:`attitude_envs.uncertainty.InertiaUncertainty.draw`'s law: the ``principal_moments``
    scaled by ``1 + U(−s, s)`` (``s = moment_scale``), the first of :data:`MOMENT_CANDIDATES`
    draws from ``key`` that meets the triangle inequality (the nominal moments if none does),
    and the ``principal_axes`` turned about ``axis`` (N(0, I)) by ``u_angle · axis_angle_deg``
    (``u_angle`` uniform in [0, 1])."""
    dtype = principal_moments.dtype
    scale = 1.0 + (2.0 * jax.random.uniform(key, (MOMENT_CANDIDATES, 3), dtype) - 1.0) * moment_scale
    drawn = principal_moments * scale
    d0, d1, d2 = drawn[:, 0], drawn[:, 1], drawn[:, 2]
    ok = jnp.where(
        (d2 >= d0) & (d2 >= d1), d0 + d1 >= d2, jnp.where(d1 >= d0, d0 + d2 >= d1, d1 + d2 >= d0)
    )  # the two smaller moments sum to at least the largest
    moments = jnp.where(jnp.any(ok), drawn[jnp.argmax(ok)], principal_moments)
    rot = orbital_to_body(jq.from_axis_angle(axis, jnp.deg2rad(u_angle * axis_angle_deg))).T @ principal_axes
    inertia = rot @ jnp.diag(moments) @ rot.T
    inertia = 0.5 * (inertia + inertia.T)
    return inertia, _inverse3(inertia.at[1, 1].add(-wheel_inertia_kg_m2))


# ----------------------------------------------------------------------------- from the numba env
def _check_modeled(cfg: MagnetorquerConfig) -> None:
    """A one-line ``ValueError`` for what the JAX plant does not model in ``cfg``: ``sensors``
    or sensor faults in the lab (only on flight conditions' sensors),
    ``field_model='igrf'``, an ``inertia_uncertainty`` or flight inertia draw that could make
    ``I + ΔJ(t)`` indefinite (the numba env raises at such a reset)."""
    where = "Magnetorquer JAX plant"
    sensors, conditions = cfg.layers.sensor_layer, cfg.layers.conditions
    if sensors.config and conditions.sensors == 0:
        raise ValueError(
            f"{where}: keyword 'sensors' is modeled only as flight conditions' sensors (conditions with "
            "'sensors' > 0); in the lab the true state is observed"
        )
    if sensors.fault_configs and conditions.sensors == 0:
        raise ValueError(f"{where}: sensor faults are modeled only on flight conditions' sensors ('sensors' > 0)")
    if cfg.field.model == "igrf":
        raise ValueError(f"{where}: field_model='igrf' is not modeled (use 'dipole' or 'dipole-printed')")
    dist = cfg.layers.disturbance
    if dist is not None and dist.kind not in ("constant", "sinusoidal", "random_walk"):  # pragma: no cover
        raise ValueError(f"{where}: disturbance kind {dist.kind!r} is not modeled")
    dj, unc = cfg.time_varying_inertia, cfg.inertia_uncertainty
    smallest = float(np.min(np.linalg.eigvalsh(np.asarray(cfg.model.params.inertia_kg_m2, dtype=float))))
    if unc is not None and dj is not None:
        if unc.kind == "fixed":
            dj.check_against(unc.inertia_kg_m2)
        elif smallest * (1.0 - unc.moment_scale) <= float(np.max(dj.amplitude_kg_m2)):
            raise ValueError(
                f"{where}: inertia_uncertainty (random) with time_varying_inertia is not modeled where a draw "
                "could make I + ΔJ(t) indefinite (the numba env raises at such a reset)"
            )
    drawn = cfg.flight_inertia
    if (
        dj is not None
        and drawn is not None
        and smallest * (1.0 - drawn.moment_scale) <= float(np.max(dj.amplitude_kg_m2))
    ):
        raise ValueError(
            f"{where}: flight conditions' inertia draw (parameters={conditions.parameters}) with "
            "time_varying_inertia is not modeled where a draw could make I + ΔJ(t) indefinite (the numba env "
            "raises at such a reset)"
        )


def params_of(cfg: MagnetorquerConfig) -> EnvParams:
    """The ``EnvParams`` of a validated configuration
    (:func:`attitude_envs.envs.magnetorquer.configure`): its actuator faults drawn once with a
    numpy generator seeded 0 (with random fields only a default: each episode draws its own,
    ``redraw_faults``), its flight conditions' numbers and sensors."""
    p = cfg.model.params
    layers = cfg.layers
    shared = pack_shared(cfg)
    orbit = np.asarray(cfg.orbit.packed, dtype=float)
    unc = cfg.inertia_uncertainty
    nominal = np.asarray(p.inertia_kg_m2, dtype=float)
    moments, axes = np.linalg.eigh(nominal)
    unc_inertia = nominal if unc is None or unc.kind != "fixed" else np.asarray(unc.inertia_kg_m2, dtype=float)
    eff = unc_inertia.copy()
    eff[1, 1] -= p.wheel_inertia_kg_m2
    anomaly = cfg.orbit_config["mean_anomaly_deg"]
    dist = layers.disturbance
    if dist is None:
        dist_initial, walk_std, random_phase = np.zeros(3), 0.0, False
    elif dist.kind == "constant":
        dist_initial, walk_std, random_phase = dist.torque_nm, 0.0, False
    elif dist.kind == "random_walk":
        dist_initial, walk_std, random_phase = dist.initial_nm, dist.std, False
    else:
        dist_initial, walk_std, random_phase = dist.phase_rad, 0.0, dist.random_phase
    # one realization (the episode's own when nothing is drawn), in numpy: no eager JAX ops
    fault_layer = ActuatorFaults([dict(c) for c in layers.fault_layer.configs], N_ACTUATORS, p.limits)
    fault_layer.reset(np.random.default_rng(0))

    def f(v: Any) -> jax.Array:
        return jnp.asarray(np.asarray(v, dtype=float))

    def b(v: Any) -> jax.Array:
        return jnp.asarray(bool(v))

    return EnvParams(
        plant=PlantParams(
            inertia_kg_m2=f(nominal),
            inertia_eff_inv=f(p.inertia_eff_inv),
            wheel_inertia_kg_m2=f(shared[K.SH_JW]),
            max_dipole_am2=f(p.max_dipole_am2),
            max_wheel_torque_nm=f(p.max_wheel_torque_nm),
            max_wheel_momentum_nms=f(shared[K.SH_HMAX]),
        ),
        orbit=OrbitParams(
            circular=b(orbit[K.ORB_MODEL] == 1.0),
            semi_major_axis_m=f(orbit[K.ORB_A]),
            eccentricity=f(orbit[K.ORB_E]),
            mean_motion_rad_s=f(orbit[K.ORB_N]),
            semi_latus_rectum_m=f(orbit[K.ORB_P]),
            angular_momentum_m2_s=f(orbit[K.ORB_H]),
            mu_m3_s2=f(orbit[K.ORB_MU]),
            node=f(orbit[K.ORB_NODE : K.ORB_NODE + 3]),
            in_plane=f(orbit[K.ORB_IN_PLANE : K.ORB_IN_PLANE + 3]),
            normal=f(orbit[K.ORB_NORMAL : K.ORB_NORMAL + 3]),
            arg_perigee_rad=f(orbit[K.ORB_ARGP]),
            inclination_rad=f(shared[K.SH_INCL]),
        ),
        field=FieldParams(
            printed=b(shared[K.SH_FIELD] == K.FIELD_CODES["dipole-printed"]),
            dipole_strength_t_m3=f(shared[K.SH_STRENGTH]),
        ),
        timing=TimingParams(control_dt_s=f(cfg.control_dt_s), integrator_dt_s=f(shared[K.SH_H])),
        cost=CostParams(
            Q=f(shared[K.SH_Q : K.SH_Q + 36].reshape(6, 6)),
            R=f(shared[K.SH_R : K.SH_R + 9].reshape(3, 3)),
            max_rate_rad_s=f(cfg.max_rate_rad_s),
            termination_mode=jnp.asarray(jcost.mode_code(cfg.termination_cost), jnp.int32),
            horizon_s=f(cfg.episode_duration_s),
        ),
        start=StartParams(
            reference=f(shared[K.SH_REF :]),
            regulation=b(cfg.task == "regulation"),
            initial_angle_deg=f(cfg.initial_angle_deg),
            initial_rate_max_rad_s=f(cfg.initial_rate_max_rad_s),
            mean_anomaly_random=b(cfg.random_anomaly),
            mean_anomaly_deg=f(0.0 if cfg.random_anomaly else anomaly),
        ),
        disturbance=DisturbanceParams(
            code=jnp.asarray(int(shared[K.SH_DIST]), jnp.int32),
            scale=f(shared[K.SH_DIST_SCALE]),
            rate_rad_s=f(shared[K.SH_DIST_RATE]),
            harmonic=f(shared[K.SH_DIST_K]),
            amplitude_nm=f(shared[K.SH_DIST_AMP : K.SH_DIST_AMP + 3]),
            period_s=f(shared[K.SH_DIST_PERIOD]),
            initial=f(dist_initial),
            random_phase=b(random_phase),
            walk_std=f(walk_std),
            gravity_gradient=b(shared[K.SH_GG] != 0.0),
        ),
        inertia_change=InertiaChangeParams(
            on=b(shared[K.SH_DJ] != 0.0),
            amplitude_kg_m2=f(shared[K.SH_DJ_AMP : K.SH_DJ_AMP + 3]),
            frequency_rad_s=f(shared[K.SH_DJ_FREQ : K.SH_DJ_FREQ + 3]),
            phase_rad=f(shared[K.SH_DJ_PHASE : K.SH_DJ_PHASE + 3]),
        ),
        uncertainty=UncertaintyParams(
            code=jnp.asarray(_UNCERTAINTY_CODES[None if unc is None else unc.kind], jnp.int32),
            inertia_kg_m2=f(unc_inertia),
            eff_inv=f(np.linalg.inv(eff)),
            principal_moments=f(moments),
            principal_axes=f(axes),
            moment_scale=f(0.0 if unc is None else unc.moment_scale),
            axis_angle_deg=f(0.0 if unc is None else unc.axis_angle_deg),
        ),
        faults=jfaults.from_realized(fault_layer.realized),
        max_steps_in_episode=jnp.asarray(episode_decisions(cfg.episode_duration_s, cfg.control_dt_s), jnp.int32),
        flight=_flight_params(cfg),
        sensors=jsens.suite_params(
            layers.sensor_layer.config,
            _AXES,
            jnp.result_type(float),
            jsens.channel_faults(layers.sensor_layer, jnp.result_type(float), "Magnetorquer JAX plant"),
        ),
    )


def from_keywords(plant: str, kwargs: dict[str, Any]) -> tuple[MagnetorquerEnv, EnvParams]:
    """The JAX plant and its ``EnvParams`` for the numba env's keywords ``kwargs`` (flight
    conditions included), validated as the numba env validates them (no numba env is built).
    A one-line ``ValueError`` names what the JAX plant does not model (:func:`_check_modeled`)."""
    check_keywords(NumbaMagnetorquerEnv, kwargs)
    given = {**keyword_defaults(NumbaMagnetorquerEnv), **kwargs}
    cfg = configure(NumbaMagnetorquerEnv, given.get("preset"), given)
    _check_modeled(cfg)
    params = params_of(cfg)
    layers = cfg.layers
    configs = tuple(dict(c) for c in layers.fault_layer.configs)
    dist = layers.disturbance
    low, high = observation_bounds(cfg)
    env = MagnetorquerEnv(
        params,
        n_substeps=cfg.n_substeps,
        observe_field=cfg.observe_field,
        fault_hint=layers.fault_hint,
        random_walk=dist is not None and dist.kind == "random_walk",
        fault_configs=configs,
        redraw_faults=any(jfaults.draws_per_episode(c) for c in configs),
        obs_low=np.asarray(low, dtype=float),
        obs_high=np.asarray(high, dtype=float),
        flight=_flight_layout(cfg),
        sensors=tuple(name for name in _AXES if name in layers.sensor_layer.config),
    )
    return env, params


def _flight_layout(cfg: MagnetorquerConfig) -> FlightLayout | None:
    """The static layout of ``cfg``'s flight conditions (None in the lab): its actuator chain,
    whether parameters are drawn and whether the flight tolerances draw the true inertia."""
    layers = cfg.layers
    if layers.conditions.is_lab:
        return None
    return FlightLayout(
        actuators=jact.chain_layout(layers),
        parameters=layers.conditions.parameters > 0,
        draw_inertia=cfg.flight_inertia is not None,
    )


def _flight_params(cfg: MagnetorquerConfig) -> FlightParams | None:
    """The params of ``cfg``'s flight conditions (None in the lab): the actuator chain's, the
    flight inertia tolerances (zeros when none is drawn) and the gain tolerances."""
    layers = cfg.layers
    if layers.conditions.is_lab:
        return None
    p = cfg.model.params
    drawn = cfg.flight_inertia
    dtype = jnp.result_type(float)

    def f(v: Any) -> jax.Array:
        return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

    return FlightParams(
        actuators=jact.chain_params(layers, N_ACTUATORS, cfg.control_dt_s, dtype),
        inertia_moment=f(0.0 if drawn is None else drawn.moment_scale),
        inertia_axis_deg=f(0.0 if drawn is None else drawn.axis_angle_deg),
        gain_tolerance=f(layers.gain_tolerance),
        given=jnp.asarray(False),
        given_inertia_kg_m2=f(np.asarray(p.inertia_kg_m2, dtype=float)),
        given_inertia_eff_inv=f(p.inertia_eff_inv),
        given_gain=f(np.ones(N_ACTUATORS)),
    )


def with_drawn_parameters(params: EnvParams, drawn: dict) -> EnvParams:
    """``params`` whose resets take the true inertia and gains ``drawn`` (a numba flight
    episode's ``env.unwrapped.drawn_parameters()``: ``inertia_kg_m2``, ``actuator_gain`` where
    drawn) instead of drawing them: the JAX episode of that numba episode's plant (``I_eff⁻¹``
    computed with numpy as the numba env's ``_pack_env`` does, so bit for bit its). A
    ``ValueError`` for params without flight conditions or a draw missing."""
    fp = params.flight
    inertia = drawn_arrays(fp, drawn, {"inertia_kg_m2": (3, 3)})["inertia_kg_m2"]
    eff = inertia.copy()
    eff[1, 1] -= float(params.plant.wheel_inertia_kg_m2)
    gain = np.asarray(drawn.get("actuator_gain", np.ones(N_ACTUATORS)), dtype=float)
    dtype = params.start.reference.dtype

    def f(v: Any) -> jax.Array:
        return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

    return params.replace(
        flight=fp.replace(
            given=jnp.asarray(True),
            given_inertia_kg_m2=f(inertia),
            given_inertia_eff_inv=f(np.linalg.inv(eff)),
            given_gain=f(gain),
        )
    )
