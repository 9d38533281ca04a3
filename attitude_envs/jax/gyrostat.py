"""ReactionWheel and AirBearing (the gyrostat) as a JAX-native plant in gymnax 1.0's API.

The step is :mod:`attitude_envs.plants.gyrostat_kernels`'s, from the same definition
(:mod:`attitude_envs.plants.gyrostat_definition`, its row functions on a list of scalars): the
exact gyrostat ``I_eff ω̇ = −ω × (Iω + J_s A Ω) − A u + T_ext + p × K(q)``,
``Ω̇_i = u_i / J_s − a_i·ω̇``, ``q̇ = ½ q ⊗ [ω, 0]`` (:mod:`attitude_envs.plants.gyrostat`;
the offset torque ``p × K`` is Ahangarani Farahani et al.'s air-bearing gravity torque, eqs.
6–9), classical RK4 with ``n_substeps`` sub-steps of ``integrator_dt_s`` per decision, the
stage cost ``xᵀQx + u_cᵀRu_c`` integrated as an extra state, the quaternion renormalized
after every sub-step, the motor driver's speed limit before each sub-step. Sums are written
in the kernel's order, so under ``jax_enable_x64`` a trajectory matches the numba env's to
rounding: XLA fuses multiply-adds (FMA) where the numba kernel does not, about one ulp per
step (bit for bit with ``XLA_FLAGS=--xla_cpu_max_isa=SSE4_2``); a test checks whole episodes.

Per decision (``t = time · control_dt_s``): the action is clipped and scaled (or allocated,
``action_frame="body"``) to motor torques as :meth:`ReactionWheelEnv.commanded_torques`
does, the actuator faults act on them (:func:`attitude_envs.jax.faults.apply`, as the numba
env's fault layer), the RK4 sub-steps run, and a limit crossing (tumbling, the roll/pitch
stop, a non-finite state) terminates the episode with the termination charge
(:func:`attitude_envs.jax.cost.termination_charge`). ``info``: ``cost`` (J over the step,
charge included; reward ``−cost``), ``time_s``, ``error_angle_deg``, ``applied`` (mean
motor torque delivered over the step, N·m), ``commanded`` (N·m) and, with a tilt stop,
``tilt_limit_hit``. Observations are in the compute dtype (float64 under x64; the numba env
casts to float32). ``reset_env`` draws from the numba env's laws (not its draws), and an
``intermittent`` fault's dwell times come from the step's key.

Actuator faults that draw per episode (``index: "random"``, ``{"uniform": [a, b]}`` values,
onsets, durations) are drawn by ``reset_env`` from its key with
:func:`attitude_envs.jax.faults.realize` (the env's static ``fault_configs``, when
``redraw_faults``), as the numba env redraws them at each reset (the same law, not the same
draws); the episode's faults live in the state (``EnvState.faults``), so the autoreset of
``step`` starts each episode with its own.

Flight conditions (``conditions=``, :mod:`attitude_envs.conditions`): the delay and the actuator dynamics act between the faults' command and the plant
as :meth:`attitude_envs.actuator_dynamics.ActuatorChain.deliver` (:mod:`attitude_envs.jax.actuators`;
the chain's runtime state in ``EnvState.flight``), and ``reset_env`` draws the episode's true
plant (inertia moments and principal axes, misaligned wheel axes, the air bearing's offset
torque) and the motors' gains from its key by the numba env's laws (not its draws; the key is
folded, so the start, target and faults are the lab episode's of the same key), kept in
``EnvState.flight`` (the allocation and the cost stay nominal, as in the numba env). The
flight sensors (:mod:`attitude_envs.jax.sensors`: gyro, star tracker, tachometers with noise,
a bias drawn at reset, its walk, and the star tracker's sample-and-hold at its period) sample
at reset and at each step's end from keys folded off the reset's and the step's (the same law
as the numba sensor layer, not its draws); the observation is then the error state of the
readings (:meth:`GyrostatEnv.measured_row`), as the numba env's, and ``info``, the cost and
the limits stay the truth's.
:func:`with_drawn_parameters` gives a numba episode's draws to the reset instead (the x64
equality tests). The lab's compiled step is unchanged (``flight`` None in the env, its params
and state). Per-episode plants in the state cost speed: each env's RK4 reads its own matrices.

Modeled: every keyword of ReactionWheel-v0/-v1 and AirBearing-v0/-v1 but these, for which
:func:`from_keywords` (and :func:`attitude_envs.jax.make`) raises a one-line ``ValueError``
naming them: a ``sensors`` keyword in the lab (sensors only as flight conditions' sensors,
which an explicit ``sensors`` dict may replace), sensor faults in the lab
(:func:`attitude_envs.jax.sensors.channel_faults`); a ``disturbance`` other than ``"constant"``
(sinusoidal, random walk); ``inertia_uncertainty`` of kind ``"random"`` (``"fixed"`` is
modeled; vmap over :func:`with_inertia` instead); ``render_mode``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs import quaternion
from attitude_envs.envs.air_bearing import AirBearingEnv, euler_max
from attitude_envs.envs.base import check_keywords
from attitude_envs.envs.reaction_wheel import GyrostatConfig, ReactionWheelEnv, configure
from attitude_envs.faults import ActuatorFaults
from attitude_envs.jax import actuators as jact
from attitude_envs.jax import faults as jfaults
from attitude_envs.jax import quaternion as jq
from attitude_envs.jax import sensors as jsens
from attitude_envs.jax.cost import mode_code, termination_charge
from attitude_envs.jax.environment import (
    Environment,
    check_state_from,
    drawn_arrays,
    episode_decisions,
    preset_defaults,
)
from attitude_envs.jax.ops import JAX
from attitude_envs.jax.spaces import Box
from attitude_envs.plants.gyrostat_definition import define

#: 2·(180/π): ``degrees(2 a)`` as the numba env computes it (times 2 is exact)
_TWO_RAD_TO_DEG = 2.0 * (180.0 / np.pi)
_G = define(JAX)
#: start-attitude laws (``EnvParams.initial_mode``)
START_FIXED, START_AXIS_ANGLE, START_EULER = 0, 1, 2
#: sensor channels whose fault flags follow the actuators' in a ``fault_hint`` observation
_N_SENSOR_CHANNELS = 3


@dataclass(frozen=True)
class FlightLayout:
    """What the flight conditions (:mod:`attitude_envs.conditions`) switch on in the compiled
    program (static): the ``actuators`` chain's layout (:class:`attitude_envs.jax.actuators.ActuatorLayout`:
    delay, actuator dynamics, gains) and which true-plant parameters ``reset_env`` draws per
    episode: ``draw_plant`` (the wheel axes, and the rest below), ``draw_inertia`` (not with
    a fixed ``inertia_uncertainty``), ``draw_offset`` (the air bearing's offset torque)."""

    actuators: jact.ActuatorLayout
    draw_plant: bool = False
    draw_inertia: bool = False
    draw_offset: bool = False


@struct.dataclass
class FlightParams:
    """The flight conditions' numbers: the ``actuators`` chain
    (:class:`attitude_envs.jax.actuators.ActuatorParams`); the tolerances the true plant is
    drawn within per episode (``inertia_moment``: relative, on each principal moment;
    ``inertia_axis_deg``: the principal axes' rotation; ``misalignment_deg``: each wheel
    axis' tilt; ``offset_tolerance_nm``: the offset torque, per axis; ``gain_tolerance``:
    each motor's scale factor, relative), the nominal inertia's principal ``nominal_moments``
    and ``nominal_principal_axes`` (numpy's ``eigh``, as the numba draw). ``given``: the reset
    takes the ``given_*`` draws instead of drawing (an episode of the numba env:
    :func:`with_drawn_parameters`)."""

    actuators: jact.ActuatorParams
    inertia_moment: jax.Array
    inertia_axis_deg: jax.Array
    misalignment_deg: jax.Array
    offset_tolerance_nm: jax.Array
    gain_tolerance: jax.Array
    nominal_moments: jax.Array
    nominal_principal_axes: jax.Array
    given: jax.Array
    given_inertia_kg_m2: jax.Array
    given_inertia_eff_inv: jax.Array
    given_wheel_axes: jax.Array
    given_offset_torque_nm: jax.Array
    given_gain: jax.Array


@struct.dataclass
class EpisodePlant:
    """One episode's true plant drawn by the flight conditions: ``inertia_kg_m2``, its
    ``inertia_eff_inv`` (with the drawn axes), ``wheel_axes`` (3×N), ``offset_torque_nm``."""

    inertia_kg_m2: jax.Array
    inertia_eff_inv: jax.Array
    wheel_axes: jax.Array
    offset_torque_nm: jax.Array


@struct.dataclass
class FlightState:
    """An episode's flight state: its true ``plant`` (None: the params' plant), the motors'
    scale-factor ``gain`` (None: ones) and the actuator chain's runtime state
    ``actuators`` (delay line, rate limiter, lag)."""

    actuators: jact.ActuatorState
    plant: EpisodePlant | None = None
    gain: jax.Array | None = None


#: the gyrostat's sensor channels: name → slice of the state row ``[q, ω, Ω]``
_SLICES = {"gyro": (4, 7), "star_tracker": (0, 4), "tachometer": (7, None)}


def _row_truths(y: jax.Array) -> dict[str, jax.Array]:
    """What each sensor channel measures of the state row ``y = [q, ω, Ω]``."""
    return {name: y[a:b] for name, (a, b) in _SLICES.items()}


@struct.dataclass
class EnvState:
    """One episode's state: ``time`` (decisions taken), the physical state ``attitude``
    (4, scalar-last unit quaternion, body to inertial), ``rate_rad_s`` (3, body rate, rad/s),
    ``wheel_speed_rad_s`` (N, relative to the body, rad/s), the episode's
    ``target_attitude`` (4), its realized actuator ``faults`` (``params.faults``, or drawn
    at the reset with ``redraw_faults``) and their runtime ``fault_state``."""

    time: jax.Array
    attitude: jax.Array
    rate_rad_s: jax.Array
    wheel_speed_rad_s: jax.Array
    target_attitude: jax.Array
    faults: jfaults.FaultParams
    fault_state: jfaults.FaultState
    flight: FlightState | None = None
    sensors: jsens.SuiteState | None = None


#: a params field whose default is that group of the default preset's params
_default = preset_defaults(lambda: configure(ReactionWheelEnv, None, {}), lambda cfg: _params_of(cfg, ReactionWheelEnv))


@struct.dataclass
class PlantParams:
    """The plant (SI): ``inertia_kg_m2`` (3×3, whole spacecraft, wheels' spin inertia
    included) and its ``inertia_eff_inv`` ``(I − J_s A Aᵀ)⁻¹`` (keep them consistent:
    :func:`with_inertia`), ``wheel_axes`` (3×N unit columns), ``wheel_inertia_kg_m2`` (J_s),
    ``max_wheel_torque_nm``, ``max_wheel_speed_rad_s`` (inf: none), ``offset_torque_nm`` (3,
    the true plant's ``m g r_s``), ``action_map`` (N×3: the body-frame allocation ``−A⁺``
    times the torque limit)."""

    inertia_kg_m2: jax.Array
    inertia_eff_inv: jax.Array
    wheel_axes: jax.Array
    wheel_inertia_kg_m2: jax.Array
    max_wheel_torque_nm: jax.Array
    max_wheel_speed_rad_s: jax.Array
    offset_torque_nm: jax.Array
    action_map: jax.Array


@struct.dataclass
class TimingParams:
    """``control_dt_s``, ``integrator_dt_s`` (their ratio is the env's static ``n_substeps``),
    ``episode_duration_s`` (s)."""

    control_dt_s: jax.Array
    integrator_dt_s: jax.Array
    episode_duration_s: jax.Array


@struct.dataclass
class CostParams:
    """``Q``, ``R``, ``termination_mode`` (:func:`attitude_envs.jax.cost.mode_code`) and the
    limits: ``max_rate_rad_s`` (tumbling), ``tilt_sin``, ``tilt_cos`` (sine and cosine of the
    roll/pitch stop; 2 and −2: none)."""

    Q: jax.Array
    R: jax.Array
    termination_mode: jax.Array
    max_rate_rad_s: jax.Array
    tilt_sin: jax.Array
    tilt_cos: jax.Array


@struct.dataclass
class StartParams:
    """An episode's start and target: ``initial_mode`` (:data:`START_FIXED`
    ``initial_attitude``, :data:`START_AXIS_ANGLE` within ``initial_angle_deg`` of identity,
    :data:`START_EULER` 3-2-1 angles uniform in ± ``initial_euler_max_deg``), rate
    ``initial_rate_rad_s`` when ``rate_fixed`` else uniform in ± ``initial_rate_max_rad_s``,
    target ``target_attitude`` when ``target_fixed`` else within ``target_angle_deg``."""

    initial_mode: jax.Array
    initial_attitude: jax.Array
    initial_angle_deg: jax.Array
    initial_euler_max_deg: jax.Array
    rate_fixed: jax.Array
    initial_rate_rad_s: jax.Array
    initial_rate_max_rad_s: jax.Array
    target_fixed: jax.Array
    target_attitude: jax.Array
    target_angle_deg: jax.Array


@struct.dataclass
class DisturbanceParams:
    """``torque_nm`` (3, N·m, body axes): the constant external torque (zeros: none)."""

    torque_nm: jax.Array


@struct.dataclass
class EnvParams:
    """Every number of a gyrostat task (SI units; arrays, so ``jax.vmap`` randomizes them),
    in groups that default to the default preset's (ReactionWheel-v0's): ``plant``,
    ``timing``, ``cost`` (with the limits and the termination charge), ``start``,
    ``disturbance``, ``faults`` (the realized actuator faults of every episode, on the motor
    torques, N·m; padded with kind 0 to a common length when params of several fault sets
    are stacked; an env with ``redraw_faults`` draws each episode's from its fault configs
    instead, padded to this length, as the numba env does), ``flight`` (the flight
    conditions' per-episode draws and actuator chain, None in the lab), ``sensors`` (None:
    the truth is observed) and ``max_steps_in_episode`` (decisions)."""

    plant: PlantParams = _default("plant")
    timing: TimingParams = _default("timing")
    cost: CostParams = _default("cost")
    start: StartParams = _default("start")
    disturbance: DisturbanceParams = _default("disturbance")
    faults: jfaults.FaultParams = struct.field(default_factory=jfaults.no_faults)
    max_steps_in_episode: jax.Array = _default("max_steps_in_episode")
    flight: FlightParams | None = None
    sensors: jsens.SuiteParams | None = None


def with_inertia(params: EnvParams, inertia_kg_m2: jax.Array) -> EnvParams:
    """``params`` on a body of inertia ``inertia_kg_m2`` (3×3, kg·m², wheels' spin inertia
    included), with ``inertia_eff_inv`` recomputed (traceable: ``jax.vmap`` it over inertias)."""
    inertia = jnp.asarray(inertia_kg_m2, dtype=params.plant.inertia_kg_m2.dtype)
    a = params.plant.wheel_axes
    eff = inertia - params.plant.wheel_inertia_kg_m2 * a @ a.T
    return params.replace(plant=params.plant.replace(inertia_kg_m2=inertia, inertia_eff_inv=jnp.linalg.inv(eff)))


# ---------------------------------------------------------------------------- the kernel's math
# Each entry computed with the products and the summation order of gyrostat_kernels' lanes.
# Written on scalars (tuples of 0-d arrays), not 3-vectors: under ``jax.vmap`` every quantity
# is then one contiguous array over the batch and every operation elementwise, which XLA
# fuses into vectorized loops. At 128 envs and more the sub-step runs 1.6-2.6x faster than
# with 3-vector slices, gathers and concatenations (on one CPU core, 2026-11-28); at 1-8
# envs, where dispatch dominates, 0.4-1x.


def _constants(p: EnvParams, n: int, n_state: int, m_cost: int) -> tuple[list, int, int, int, int]:
    """The definition's flat constants ``C`` (the kernel's :func:`pack_constants` layout, as a
    list of scalars: wheel axes, Q, R, the scalars) and the offsets ``(ax, cq, cr, sc)``."""
    A, Q, R = p.plant.wheel_axes, p.cost.Q, p.cost.R
    cq = 3 * n
    cr = cq + n_state * n_state
    sc = cr + m_cost * m_cost
    po = p.plant.offset_torque_nm
    C = (
        [A[k, i] for k in range(3) for i in range(n)]
        + [Q[i, j] for i in range(n_state) for j in range(n_state)]
        + [R[i, j] for i in range(m_cost) for j in range(m_cost)]
        + [
            p.plant.wheel_inertia_kg_m2,
            p.plant.max_wheel_torque_nm,
            p.plant.max_wheel_speed_rad_s,
            p.timing.integrator_dt_s,
        ]
        + [
            po[0],
            po[1],
            po[2],
            p.cost.max_rate_rad_s,
            p.timing.control_dt_s,
            p.timing.episode_duration_s,
            p.cost.tilt_sin,
            p.cost.tilt_cos,
        ]
    )
    return C, 0, cq, cr, sc


def _error_state(y, target, C, sc: int, n: int, include_h: bool, n_state: int):
    """``x = [q_e,vec, ω, (J_s Ω)]`` (a tuple) with ``q_e = q_T* ⊗ q/|q|`` (``q_e,w ≥ 0``) and
    ``q_e,w`` (the definition's ``error_state_lane``), of the state ``y = (q, ω, Ω)`` and
    ``target`` (4 scalars each); ``C``, ``sc``: :func:`_constants`."""
    W = [*y[: 7 + n], *target] + [None] * n_state
    qe_w = _G.error_state_lane(W, C, 0, 1, n, include_h, 0, 7 + n, 11 + n, sc, True)
    return tuple(W[11 + n : 11 + n + n_state]), qe_w


def _from_euler_321_deg(euler_deg: jax.Array) -> jax.Array:
    """The quaternion of 3-2-1 Euler angles [roll, pitch, yaw], deg
    (:func:`attitude_envs.quaternion.from_euler_321_deg`)."""
    phi, theta, psi = jnp.radians(euler_deg) * 0.5
    return quaternion.from_euler_321_half_angles(phi, theta, psi, xp=jnp)


def _to_matrix(q: jax.Array) -> jax.Array:
    """The rotation matrix (body to inertial) of a unit quaternion (:func:`attitude_envs.quaternion.to_matrix`)."""
    x, y, z, w = q
    return jnp.stack(
        [
            jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)]),
            jnp.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)]),
            jnp.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]),
        ]
    )


def _normals(u: jax.Array) -> jax.Array:
    """Standard normals of uniforms ``u`` in (−1, 1), as ``jax.random.normal`` makes them."""
    lo = np.nextafter(np.array(-1.0, u.dtype), np.array(0.0, u.dtype))  # erf_inv(-1) = -inf
    return np.sqrt(2.0) * jax.lax.erf_inv(jnp.maximum(u, lo))


def _inv3(m: jax.Array) -> jax.Array:
    """The inverse of a 3×3 matrix by its adjugate (elementwise under ``jax.vmap``: a batched
    LU solve costs more than the whole draw)."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    co = jnp.stack(
        [
            jnp.stack([e * i - f * h, c * h - b * i, b * f - c * e]),
            jnp.stack([f * g - d * i, a * i - c * g, c * d - a * f]),
            jnp.stack([d * h - e * g, b * g - a * h, a * e - b * d]),
        ]
    )
    return co / (a * co[0, 0] + b * co[1, 0] + c * co[2, 0])


def _draw_inertia(key: jax.Array, u: jax.Array, moments, principal_axes, moment_scale, axis_angle_deg) -> jax.Array:
    """A true inertia by :meth:`attitude_envs.uncertainty.InertiaUncertainty.draw`'s law: each
    principal moment times ``1 + U(−s, s)``, redrawn until the triangle inequality holds (from
    ``key``; rarely: the first try takes ``u[:3]``), the principal axes rotated about a
    standard normal axis (``u[3:6]``) by an angle uniform in [0, max] (``u[6]``). ``u``: 7
    uniforms in (−1, 1)."""
    dtype = moments.dtype

    def draw(v):
        drawn = moments * (1.0 + v * moment_scale)
        s = jnp.sort(drawn)
        return drawn, s[0] + s[1] >= s[2]

    def redraw(carry):
        k, _, _ = carry
        k, sub = jax.random.split(k)
        return (k, *draw(jax.random.uniform(sub, (3,), dtype, -1.0, 1.0)))

    _, drawn, _ = jax.lax.while_loop(lambda c: jnp.logical_not(c[2]), redraw, (key, *draw(u[:3])))
    angle = jnp.radians(0.5 * (u[6] + 1.0) * axis_angle_deg)
    rot = _to_matrix(jq.from_axis_angle(_normals(u[3:6]), angle)) @ principal_axes
    inertia = (rot * drawn) @ rot.T  # rot diag(drawn) rotᵀ
    return 0.5 * (inertia + inertia.T)


def _misaligned_axes(u: jax.Array, axes: jax.Array, max_angle_deg) -> jax.Array:
    """Unit wheel axes (3×N), each tilted by an angle uniform in [0, max] (``u[3N:]``) about a
    uniformly random perpendicular (standard normals of ``u[:3N]``;
    :func:`attitude_envs.envs.reaction_wheel.misaligned_axes`'s law), normalized as
    :class:`~attitude_envs.plants.gyrostat.GyrostatParams` does. ``u``: 4N uniforms in (−1, 1)."""
    n = axes.shape[1]
    r = _normals(u[: 3 * n]).reshape(3, n)
    perp = r - jnp.sum(r * axes, axis=0) * axes
    perp = perp / jnp.sqrt(jnp.sum(perp * perp, axis=0))
    angle = jnp.radians(max_angle_deg) * (0.5 * (u[3 * n :] + 1.0))
    out = jnp.cos(angle) * axes + jnp.sin(angle) * perp
    return out / jnp.sqrt(jnp.sum(out * out, axis=0))


class GyrostatEnv(Environment):
    """ReactionWheel-v0/-v1 and AirBearing-v0/-v1 in JAX (see the module docstring).

    Static (fixed at construction, part of the compiled program): ``n_wheels``,
    ``n_substeps``, ``include_wheel_momentum`` (``x`` carries ``J_s Ω``), ``body_cost_input``
    (``u_c = −A u``, else ``u``), ``observe_wheel_speeds``, ``body_action_frame``,
    ``fault_hint``, ``has_tilt_stop``, ``flight`` (:class:`FlightLayout`, None in the lab),
    ``sensors`` (the modeled sensor channels), the fault configs (``fault_configs``, validated
    fault dicts; ``redraw_faults``: ``reset_env`` draws each episode's faults from them).
    Envs with equal static attributes are equal (they share compiled code; the fault
    configs count only with ``redraw_faults``, so envs of different fixed faults share it).
    Build one with :func:`attitude_envs.jax.make`."""

    def __init__(
        self,
        *,
        n_wheels: int,
        n_substeps: int,
        include_wheel_momentum: bool,
        body_cost_input: bool,
        observe_wheel_speeds: bool,
        body_action_frame: bool,
        fault_hint: bool,
        has_tilt_stop: bool,
        env_name: str = "ReactionWheel",
        params: EnvParams | None = None,
        fault_configs: tuple[dict, ...] = (),
        redraw_faults: bool = False,
        flight: FlightLayout | None = None,
        sensors: tuple[str, ...] = (),
    ) -> None:
        self.n_wheels = int(n_wheels)
        self.n_substeps = int(n_substeps)
        self.include_wheel_momentum = bool(include_wheel_momentum)
        self.body_cost_input = bool(body_cost_input)
        self.observe_wheel_speeds = bool(observe_wheel_speeds)
        self.body_action_frame = bool(body_action_frame)
        self.fault_hint = bool(fault_hint)
        self.has_tilt_stop = bool(has_tilt_stop)
        self.env_name = str(env_name)
        self.fault_configs = tuple(dict(c) for c in fault_configs)
        self.redraw_faults = bool(redraw_faults)
        #: the flight conditions' static layout (None: the lab, the step and reset unchanged)
        self.flight = flight
        #: the sensor channels modeled (empty: the truth is observed)
        self.sensors = tuple(sensors)
        self._params = params

    # static identity: equal layouts share jit caches
    def _static(self) -> tuple:
        return (
            self.n_wheels,
            self.n_substeps,
            self.include_wheel_momentum,
            self.body_cost_input,
            self.observe_wheel_speeds,
            self.body_action_frame,
            self.fault_hint,
            self.has_tilt_stop,
            self.env_name,
            self.redraw_faults,
            _frozen(self.fault_configs) if self.redraw_faults else (),
            self.flight,
            self.sensors,
        )

    def __hash__(self) -> int:
        return hash(self._static())

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other._static() == self._static()

    # equal envs share compiled code, so their default params must not be traced into it:
    # resolved here, before the jitted step and reset
    def step(self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams | None = None):
        """One decision with autoreset (gymnax 1.0's ``step``, see :class:`Environment`)."""
        return super().step(key, state, action, self.default_params if params is None else params)

    def reset(self, key: jax.Array, params: EnvParams | None = None):
        """A fresh episode drawn with ``key`` (gymnax 1.0's ``reset``)."""
        return super().reset(key, self.default_params if params is None else params)

    @property
    def name(self) -> str:
        return self.env_name

    @property
    def default_params(self) -> EnvParams:
        if self._params is None:
            raise ValueError("this GyrostatEnv has no default params: build it with attitude_envs.jax.make")
        return self._params

    @property
    def n_state(self) -> int:
        """Entries of the error state ``x`` (6, plus N with wheel momentum)."""
        return 6 + (self.n_wheels if self.include_wheel_momentum else 0)

    @property
    def n_obs(self) -> int:
        """Entries of the observation: ``x``, ``Ω/Ω_max`` (N, with ``observe_wheel_speeds``),
        the ``fault_hint`` flags (N + 3)."""
        n = self.n_state + (self.n_wheels if self.observe_wheel_speeds else 0)
        return n + (self.n_wheels + _N_SENSOR_CHANNELS if self.fault_hint else 0)

    # ------------------------------------------------------------------ spaces
    def action_space(self, params: EnvParams | None = None) -> Box:
        """``Box(-1, 1)``: per wheel (motor torque / limit) or, in the body frame, 3 (body
        torque demand / limit)."""
        return Box(-1.0, 1.0, (3 if self.body_action_frame else self.n_wheels,), dtype=jnp.result_type(float))

    def observation_space(self, params: EnvParams | None = None) -> Box:
        """The numba env's bounds: ``|q_e,vec| ≤ 1``, rates within 2 × ``max_rate_rad_s``,
        wheel momentum within 1.5 J_s Ω_max, ``|Ω/Ω_max| ≤ 1.5``, flags in [0, 1]."""
        p = self.default_params if params is None else params
        rate = 2.0 * float(p.cost.max_rate_rad_s)
        high = [np.ones(3), np.full(3, rate)]
        if self.include_wheel_momentum:
            h = 1.5 * float(p.plant.wheel_inertia_kg_m2) * float(p.plant.max_wheel_speed_rad_s)
            high.append(np.full(self.n_wheels, h if np.isfinite(h) else 1e6))
        if self.observe_wheel_speeds:
            high.append(np.full(self.n_wheels, 1.5))
        high = np.concatenate(high)
        low = -high
        if self.fault_hint:
            n_flags = self.n_wheels + _N_SENSOR_CHANNELS
            low, high = np.concatenate([low, np.zeros(n_flags)]), np.concatenate([high, np.ones(n_flags)])
        return Box(low, high, (self.n_obs,), dtype=jnp.result_type(float))

    # ------------------------------------------------------------------ the plant
    def commanded_torques(self, action: jax.Array, params: EnvParams) -> jax.Array:
        """Motor torques (N·m) of an action (:meth:`ReactionWheelEnv.commanded_torques`):
        clipped to [-1, 1] and scaled, or allocated in the body frame and clipped per wheel."""
        dtype = params.plant.inertia_kg_m2.dtype
        a = jnp.minimum(jnp.maximum(jnp.asarray(action, dtype=dtype), -1.0), 1.0)
        limit = params.plant.max_wheel_torque_nm
        if not self.body_action_frame:
            return a * limit
        m = params.plant.action_map
        torque = a[0:1] * m[:, 0] + a[1:2] * m[:, 1] + a[2:3] * m[:, 2]
        return jnp.minimum(jnp.maximum(torque, -limit), limit)

    def _rk4(self, y: jax.Array, cmd: jax.Array, target: jax.Array, p: EnvParams):
        """``n_substeps`` RK4 sub-steps of ``y = [q, ω, Ω]`` with the motor command ``cmd``
        (N·m) held, the stage cost against ``target``; returns the new ``y``, the integrated
        stage cost and the mean motor torque delivered (N·m) (the kernel's sub-step loop)."""
        n, h = self.n_wheels, p.timing.integrator_dt_s
        n_sub, n_state = self.n_substeps, self.n_state
        m_cost = 3 if self.body_cost_input else n
        C, ax, cq, cr, sc = _constants(p, n, n_state, m_cost)
        cmd_s = [cmd[i] for i in range(n)]
        tgt = [target[i] for i in range(4)]
        ext = [p.disturbance.torque_nm[i] for i in range(3)]
        mat = [p.plant.inertia_kg_m2[i, j] for i in range(3) for j in range(3)]
        mat += [p.plant.inertia_eff_inv[i, j] for i in range(3) for j in range(3)]
        # rows of the definition's scratch list (one lane: B = 1, e = 0)
        Y, U, UJ = 0, 7 + n, 7 + 2 * n
        EXT = UJ + n
        MAT = EXT + 3
        TGT = MAT + len(mat)
        X = TGT + 4
        OUT = X + n_state
        half, sixth = 0.5 * h, h / 6.0

        def substep(_, carry):
            aug, applied = carry  # (q, ω, Ω, cost) and the mean delivered torque, as scalars
            # motor driver: torque limit, then no torque beyond ±max_speed over the next h
            drive = cmd_s + list(aug[7 : 7 + n])
            u = [_G.speed_limit_lane(drive, C, 0, 1, i, 0, n, sc) for i in range(n)]
            applied = tuple(applied[i] + u[i] / n_sub for i in range(n))
            terms = u + [None] * (n + max(3, n))
            ru = _G.input_terms_lane(terms, C, 0, 1, n, self.body_cost_input, 0, n, 2 * n, ax, cr, sc)
            uj = terms[n : 2 * n]

            def f(state):  # (ẏ, stage cost) as one tuple
                W = [*state[: 7 + n], *u, *uj, *ext, *mat, *tgt] + [None] * (n_state + 7 + n)
                _G.derivative_lane(W, C, 0, 1, n, True, Y, U, UJ, EXT, MAT, OUT, ax, sc)
                x_cost = _G.state_cost_lane(W, C, 0, 1, n, self.include_wheel_momentum, False, Y, TGT, X, cq, sc, True)
                return (*W[OUT : OUT + 7 + n], x_cost + ru)

            # classical RK4: stages at t, t + h/2, t + h/2, t + h, as a loop. Unrolled, the
            # stages ran 1.2x faster at 8 envs but XLA's CPU fusion recomputed shared terms
            # where no loop bounds a fusion: ReactionWheel-v1 (one sub-step) stepped 20 times
            # a second instead of 4·10⁵
            def stage(s, carry):
                k, acc = carry
                step = jnp.where(s == 3, h, half)
                tmp = tuple(jnp.where(s == 0, a, a + step * kk) for a, kk in zip(aug, k, strict=True))
                k = f(tmp)
                # acc = k1 + 2 k2 + 2 k3 + k4, summed in that order
                weight = jnp.where(s == 3, 1.0, 2.0)
                acc = tuple(jnp.where(s == 0, kk, a + weight * kk) for a, kk in zip(acc, k, strict=True))
                return k, acc

            zeros = tuple(jnp.zeros_like(a) for a in aug)
            _, acc = jax.lax.fori_loop(0, 4, stage, (zeros, zeros))
            aug = tuple(a + sixth * k for a, k in zip(aug, acc, strict=True))
            q = aug[0:4]
            norm = jnp.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            aug = tuple(c / norm for c in q) + aug[4:]
            return aug, applied

        zero = jnp.zeros((), dtype=y.dtype)
        aug0 = tuple(y[i] for i in range(7 + n)) + (zero,)
        aug, applied = jax.lax.fori_loop(0, n_sub, substep, (aug0, (zero,) * n))
        return jnp.stack(aug[:-1]), aug[-1], jnp.stack(applied)

    def _observe(
        self,
        y: jax.Array,
        target: jax.Array,
        faults: jfaults.FaultParams,
        t_s,
        params: EnvParams,
        sensors: jsens.SuiteState | None = None,
    ):
        """The observation of state ``y`` at ``t_s`` (s) under the episode's ``faults`` (and,
        for the ``fault_hint`` flags, the faults of the ``sensors``), the error state ``x`` and
        ``q_e,w``."""
        y_s, target_s = tuple(y[i] for i in range(7 + self.n_wheels)), tuple(target[i] for i in range(4))
        # the error state reads only J_s of the constants: a C of that one scalar (offset 0)
        x, qe_w = _error_state(
            y_s,
            target_s,
            [params.plant.wheel_inertia_kg_m2],
            0,
            self.n_wheels,
            self.include_wheel_momentum,
            self.n_state,
        )
        x = jnp.stack(x)
        parts = [x]
        if self.observe_wheel_speeds:
            parts.append(y[7:] / params.plant.max_wheel_speed_rad_s)
        if self.fault_hint:
            flags = jfaults.active_flags(faults, t_s, self.n_wheels).astype(y.dtype)
            parts += [flags, jsens.suite_flags(params.sensors, sensors, tuple(_SLICES), t_s, y.dtype)]
        return jnp.concatenate(parts), x, qe_w

    def step_env(self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams):
        """One decision (``control_dt_s``) without autoreset:
        ``(obs, state, reward, terminated, info)``."""
        p = params
        dtype = p.plant.inertia_kg_m2.dtype
        t0 = state.time.astype(dtype) * p.timing.control_dt_s
        fl, flight = self.flight, state.flight
        if fl is not None and fl.draw_plant:  # this episode's true plant (the allocation stays nominal)
            pl = flight.plant
            plant = p.plant.replace(
                inertia_kg_m2=pl.inertia_kg_m2,
                inertia_eff_inv=pl.inertia_eff_inv,
                wheel_axes=pl.wheel_axes,
                offset_torque_nm=pl.offset_torque_nm,
            )
            p = p.replace(plant=plant)
        commanded = self.commanded_torques(action, p)
        limits = jnp.broadcast_to(p.plant.max_wheel_torque_nm, commanded.shape)
        if fl is None:
            delivered, fault_state = jfaults.apply(state.faults, state.fault_state, key, commanded, t0, limits)
        else:  # ActuatorChain.deliver: delay, resolution, rate limit, faults, lag, gain, friction
            delivered, fault_state, act = jact.deliver(
                fl.actuators,
                p.flight.actuators,
                flight.actuators,
                commanded,
                lambda c: jfaults.apply(state.faults, state.fault_state, key, c, t0, limits),
                flight.gain,
                state.wheel_speed_rad_s,
            )
            flight = flight.replace(actuators=act)
        y = jnp.concatenate([state.attitude, state.rate_rad_s, state.wheel_speed_rad_s])
        y_new, cost, applied = self._rk4(y, delivered, state.target_attitude, p)
        time = state.time + 1
        t1 = time.astype(dtype) * p.timing.control_dt_s
        obs, x, qe_w = self._observe(y_new, state.target_attitude, state.faults, t1, p)
        finite = jnp.all(jnp.isfinite(y_new)) & jnp.isfinite(cost)
        sensor_state = state.sensors
        if self.sensors:  # sampled at the step's end when the state is finite (the numba env's _measure)
            y_m, measured_state = self._measure(
                jax.random.fold_in(key, jsens.SENSOR_STREAM), p, state.sensors, y_new, t1
            )
            obs = self._observe(y_m, state.target_attitude, state.faults, t1, p, measured_state)[0]
            sensor_state = jax.tree.map(lambda a, b: jnp.where(finite, a, b), measured_state, state.sensors)
        rate = jnp.max(jnp.abs(y_new[4:7]))
        tilt = _G.tilt_lane(y_new[0], y_new[1], y_new[2], y_new[3], p.cost.tilt_sin, p.cost.tilt_cos)
        terminated = jnp.logical_not(finite) | (rate > p.cost.max_rate_rad_s) | tilt
        charge = termination_charge(p.cost.termination_mode, x, p.cost.Q, p.timing.episode_duration_s, t1)
        cost = cost + jnp.where(terminated & finite, charge, 0.0)
        obs = jnp.where(finite, obs, jnp.zeros_like(obs))
        new_state = EnvState(
            time=time,
            attitude=y_new[0:4],
            rate_rad_s=y_new[4:7],
            wheel_speed_rad_s=y_new[7:],
            target_attitude=state.target_attitude,
            faults=state.faults,
            fault_state=fault_state,
            flight=flight,
            sensors=sensor_state,
        )
        info = {
            "cost": cost,
            "time_s": t1,
            "error_angle_deg": jnp.arccos(jnp.minimum(1.0, qe_w)) * _TWO_RAD_TO_DEG,
            "applied": applied,
            "commanded": commanded,
        }
        if self.has_tilt_stop:
            info["tilt_limit_hit"] = tilt
        return obs, new_state, -cost, terminated, info

    def reset_env(self, key: jax.Array, params: EnvParams):
        """A fresh episode: start attitude, body rate (rad/s) and target drawn from the numba
        env's laws (not its draws), wheels at rest, the episode's faults (``params.faults``,
        or drawn from the fault configs with ``redraw_faults``) and their runtime state at
        its start. ``(obs, state)``."""
        p = params
        dtype = p.plant.inertia_kg_m2.dtype
        # one uniform draw for everything (each draw compiles a threefry program); the two
        # standard normal axes from 6 of them, as jax.random.normal makes its normals. A
        # third key only when the faults are drawn (the other draws stay as they were)
        if self.redraw_faults:
            k_draw, k_fault, k_realize = jax.random.split(key, 3)
        else:
            k_draw, k_fault = jax.random.split(key)
        u = jax.random.uniform(k_draw, (14,), dtype=dtype, minval=-1.0, maxval=1.0)
        lo = np.nextafter(np.array(-1.0, dtype), np.array(0.0, dtype))  # erf_inv(-1) = -inf
        axes = (np.sqrt(2.0) * jax.lax.erf_inv(jnp.maximum(u[8:], lo))).reshape(2, 3)
        u = 0.5 * (u[:8] + 1.0)  # U(0, 1)
        # rotations about uniformly random axes by angles uniform in [0, max]
        axis_angle = jq.from_axis_angle(axes[0], jnp.radians(u[0] * p.start.initial_angle_deg))
        drawn_target = jq.from_axis_angle(axes[1], jnp.radians(u[1] * p.start.target_angle_deg))
        euler = p.start.initial_euler_max_deg * (2.0 * u[2:5] - 1.0)  # AirBearing: 3-2-1 angles uniform in ±max
        q0 = jnp.select(
            [p.start.initial_mode == START_EULER, p.start.initial_mode == START_AXIS_ANGLE],
            [_from_euler_321_deg(euler), axis_angle],
            p.start.initial_attitude,
        )
        target = jnp.where(p.start.target_fixed, p.start.target_attitude, drawn_target)
        rate = jnp.where(
            p.start.rate_fixed, p.start.initial_rate_rad_s, p.start.initial_rate_max_rad_s * (2.0 * u[5:8] - 1.0)
        )
        faults = p.faults
        if self.redraw_faults:
            faults = self._draw_faults(k_realize, p.faults)
        flight = None if self.flight is None else self._draw_flight(jax.random.fold_in(key, jact.FLIGHT_STREAM), p)
        state = EnvState(
            time=jnp.zeros((), dtype=jnp.int32),
            attitude=q0,
            rate_rad_s=rate,
            wheel_speed_rad_s=jnp.zeros(self.n_wheels, dtype=dtype),
            target_attitude=target,
            faults=faults,
            fault_state=jfaults.initial_state(k_fault, faults),
            flight=flight,
        )
        if self.sensors:  # the biases drawn and the first sample at t = 0
            k_sensor = jax.random.fold_in(key, jsens.SENSOR_STREAM)
            k_bias, k_measure = jax.random.split(k_sensor)
            y = jnp.concatenate([q0, rate, state.wheel_speed_rad_s])
            t0 = jnp.zeros((), dtype=dtype)
            start = jsens.start_suite(k_bias, p.sensors, _row_truths(y), t0)
            state = state.replace(sensors=self._measure(k_measure, p, start, y, t0)[1])
        return self.get_obs(state, p), state

    def _measure(self, key: jax.Array, p: EnvParams, s: jsens.SuiteState, y: jax.Array, t_s):
        """The measured state row ``[q_m, ω_m, Ω_m]`` of the true row ``y`` at ``t_s`` and the
        sensors' next state (a channel not modeled measures the truth)."""
        m, s = jsens.measure_suite(key, p.sensors, s, _row_truths(y), t_s)
        return jnp.concatenate([m["star_tracker"], m["gyro"], m["tachometer"]]), s

    def measured_row(self, state: EnvState) -> jax.Array:
        """The sensors' last readings as a state row ``[q_m, ω_m, Ω_m]`` (the truth without sensors)."""
        y = jnp.concatenate([state.attitude, state.rate_rad_s, state.wheel_speed_rad_s])
        if not self.sensors:
            return y
        parts = []
        for name, (a, b) in _SLICES.items():
            cs = getattr(state.sensors, name)
            parts.append(y[a:b] if cs is None else cs.last)
        gyro, star, tach = parts
        return jnp.concatenate([star, gyro, tach])

    def _draw_flight(self, key: jax.Array, p: EnvParams) -> FlightState:
        """An episode's flight state: the actuator chain at rest and, with the parameters
        drawn, the true plant and the motors' gains within the flight tolerances, by the numba
        env's laws (:meth:`ReactionWheelEnv._draw_flight_plant`; not its draws), or the
        params' ``given_*`` draws."""
        fl, fp = self.flight, p.flight
        dtype = p.plant.inertia_kg_m2.dtype
        n = self.n_wheels
        actuators = jact.initial_state(fl.actuators, n, dtype)
        if not fl.draw_plant:
            return FlightState(actuators=actuators)
        # one uniform draw for every number (each draw compiles a threefry program): 7 for the
        # inertia, 4N for the axes, 3 for the offset, N for the gains; a second key only for
        # the inertia's rare redraws
        k_draw, k_redraw = jax.random.split(key)
        u = jax.random.uniform(k_draw, (10 + 5 * n,), dtype, -1.0, 1.0)
        inertia = p.plant.inertia_kg_m2
        if fl.draw_inertia:
            inertia = _draw_inertia(
                k_redraw, u[:7], fp.nominal_moments, fp.nominal_principal_axes, fp.inertia_moment, fp.inertia_axis_deg
            )
        axes = _misaligned_axes(u[7 : 7 + 4 * n], p.plant.wheel_axes, fp.misalignment_deg)
        offset = p.plant.offset_torque_nm
        if fl.draw_offset:
            offset = offset + fp.offset_tolerance_nm * u[7 + 4 * n : 10 + 4 * n]
        eff_inv = _inv3(inertia - p.plant.wheel_inertia_kg_m2 * axes @ axes.T)
        given = fp.given
        plant = EpisodePlant(
            inertia_kg_m2=jnp.where(given, fp.given_inertia_kg_m2, inertia),
            inertia_eff_inv=jnp.where(given, fp.given_inertia_eff_inv, eff_inv),
            wheel_axes=jnp.where(given, fp.given_wheel_axes, axes),
            offset_torque_nm=jnp.where(given, fp.given_offset_torque_nm, offset),
        )
        gain = None
        if fl.actuators.gain:
            gain = 1.0 + fp.gain_tolerance * u[10 + 4 * n :]
            gain = jnp.where(given, fp.given_gain, gain)
        return FlightState(actuators=actuators, plant=plant, gain=gain)

    def _draw_faults(self, key: jax.Array, like: jfaults.FaultParams) -> jfaults.FaultParams:
        """One episode's faults (:func:`attitude_envs.jax.faults.for_episode`)."""
        return jfaults.for_episode(key, self.fault_configs, self.n_wheels, like)

    def get_obs(self, state: EnvState, params: EnvParams) -> jax.Array:
        """The observation of ``state`` (the error state, wheel speeds, fault flags)."""
        y = self.measured_row(state)
        t_s = state.time.astype(y.dtype) * params.timing.control_dt_s
        return self._observe(y, state.target_attitude, state.faults, t_s, params, state.sensors)[0]

    # ------------------------------------------------------------------ from the numba env
    def state_from(
        self, numba_env: Any, time: int = 0, key: jax.Array | None = None, n_faults: int | None = None
    ) -> EnvState:
        """The JAX state of ``numba_env``'s current episode: its state row, target, realized
        faults and their runtime state (from ``fault_layer.realized``). The numba env exposes no step
        counter: ``time`` is the decisions it took (0 after ``reset``).
        ``key`` draws the first switch of intermittent faults that have not acted yet
        (the numba layer draws it at their first step). ``n_faults``: the fault entries of the
        params it will step under (default: the env's default params', or more if realized)."""
        env = getattr(numba_env, "unwrapped", numba_env)
        if not isinstance(env, ReactionWheelEnv):
            raise ValueError(f"the JAX gyrostat takes a ReactionWheel or AirBearing env, got {type(env).__name__}")
        _check_layers(env.sensor_layer, env.conditions, env.disturbance)
        dtype = jnp.result_type(float)
        row = np.array(env.state_row, dtype=float)
        realized = env.fault_layer.realized
        if n_faults is None:
            n_faults = 0 if self._params is None else self._params.faults.n_faults
        fp, fault_state = jfaults.from_numba_layer(realized, n_faults, key, dtype=dtype)
        check_state_from(bool(self.sensors), None if self.flight is None else self.flight.actuators, int(time))
        flight = None
        if self.flight is not None:
            flight = self._flight_state_from(env, time, dtype)
        return EnvState(
            time=jnp.asarray(time, dtype=jnp.int32),
            attitude=jnp.asarray(row[:4], dtype=dtype),
            rate_rad_s=jnp.asarray(row[4:7], dtype=dtype),
            wheel_speed_rad_s=jnp.asarray(row[7:], dtype=dtype),
            target_attitude=jnp.asarray(np.array(env.target_attitude), dtype=dtype),
            faults=_as_dtype(fp, dtype),
            fault_state=fault_state,
            flight=flight,
        )

    def _flight_state_from(self, env: Any, time: int, dtype) -> FlightState:
        """The flight state of the numba env's current episode: its drawn true plant
        (``drawn_parameters()`` and ``kernel_matrices``) and gains; the actuator chain at rest,
        as after a reset (the numba chain's delay line and lag state are not public: a
        ``ValueError`` for ``time > 0`` with a delay or actuator dynamics)."""
        fl = self.flight
        actuators = jact.initial_state(fl.actuators, self.n_wheels, dtype)
        if not fl.draw_plant:
            return FlightState(actuators=actuators)
        drawn = env.drawn_parameters()
        mats = np.array(env.kernel_matrices, dtype=float)

        def f(v):
            return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

        plant = EpisodePlant(
            inertia_kg_m2=f(mats[:9].reshape(3, 3)),
            inertia_eff_inv=f(mats[9:].reshape(3, 3)),
            wheel_axes=f(drawn["wheel_axes"]),
            offset_torque_nm=f(drawn["offset_torque_nm"]),
        )
        gain = f(drawn["actuator_gain"]) if fl.actuators.gain else None
        return FlightState(actuators=actuators, plant=plant, gain=gain)


def with_drawn_parameters(params: EnvParams, drawn: dict) -> EnvParams:
    """``params`` whose resets take the true plant and gains ``drawn`` (a numba flight
    episode's ``env.unwrapped.drawn_parameters()``: ``inertia_kg_m2``, ``wheel_axes``,
    ``offset_torque_nm``, ``actuator_gain`` where drawn) instead of drawing them: the JAX
    episode of that numba episode's plant (``inertia_eff_inv`` computed with numpy as
    :class:`~attitude_envs.plants.gyrostat.GyrostatParams` does, so bit for bit the numba
    env's). ``ValueError`` for lab params or a missing entry."""
    fp = params.flight
    dtype = params.plant.inertia_kg_m2.dtype
    shapes = {"inertia_kg_m2": (3, 3), "wheel_axes": tuple(params.plant.wheel_axes.shape), "offset_torque_nm": (3,)}
    a = drawn_arrays(fp, drawn, shapes)
    inertia, axes = a["inertia_kg_m2"], a["wheel_axes"]
    j_s = float(params.plant.wheel_inertia_kg_m2)
    eff_inv = np.linalg.inv(inertia - j_s * axes @ axes.T)
    gain = np.asarray(drawn.get("actuator_gain", np.ones(axes.shape[1])), dtype=float)

    def f(v):
        return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

    return params.replace(
        flight=fp.replace(
            given=jnp.asarray(True),
            given_inertia_kg_m2=f(inertia),
            given_inertia_eff_inv=f(eff_inv),
            given_wheel_axes=f(axes),
            given_offset_torque_nm=f(a["offset_torque_nm"]),
            given_gain=f(gain),
        )
    )


def episode_params(numba_env: Any, params: EnvParams, n_faults: int | None = None) -> EnvParams:
    """``params`` with ``numba_env``'s current episode's realized faults (padded to
    ``n_faults`` entries, default ``params``' count, or more if realized) and true inertia
    (kg·m², drawn per episode with ``inertia_uncertainty``): the params under which the JAX
    step follows that episode, e.g. after ``reset(options={"faults": ...})``, with random
    fault draws or a random inertia."""
    env = getattr(numba_env, "unwrapped", numba_env)
    realized = env.fault_layer.realized
    n = params.faults.n_faults if n_faults is None else n_faults
    dtype = params.plant.inertia_kg_m2.dtype
    mats = np.array(env.kernel_matrices, dtype=float)
    plant = params.plant.replace(
        inertia_kg_m2=jnp.asarray(mats[:9].reshape(3, 3), dtype=dtype),
        inertia_eff_inv=jnp.asarray(mats[9:].reshape(3, 3), dtype=dtype),
    )
    return params.replace(faults=_as_dtype(jfaults.from_realized(realized, max(n, len(realized))), dtype), plant=plant)


def _as_dtype(fp: jfaults.FaultParams, dtype) -> jfaults.FaultParams:
    """``fp`` with its float arrays in ``dtype``."""
    return jax.tree.map(lambda a: a.astype(dtype) if jnp.issubdtype(a.dtype, jnp.floating) else a, fp)


def _frozen(value: Any) -> Any:
    """``value`` (fault dicts: dicts, lists, arrays, numbers) as a hashable equal-by-value tuple."""
    if isinstance(value, dict):
        return tuple(sorted((str(k), _frozen(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple, np.ndarray)):
        return tuple(_frozen(v) for v in value)
    return value.item() if isinstance(value, np.generic) else value


def _check_layers(sensor_layer: Any, conditions: Any, disturbance: Any) -> None:
    """A one-line ``ValueError`` naming the first of an env's layers' configuration that the
    JAX gyrostat does not model: sensors or sensor faults in the lab, a disturbance other than
    constant."""
    if sensor_layer.fault_configs and conditions.sensors == 0:
        raise ValueError(
            "sensor faults are modeled by the JAX gyrostat only on flight conditions' sensors (conditions with "
            "'sensors' > 0)"
        )
    if sensor_layer.enabled and conditions.sensors == 0:
        raise ValueError(
            "sensors are modeled by the JAX gyrostat only as flight conditions' sensors (conditions with 'sensors' "
            "> 0); in the lab it observes the truth"
        )
    if disturbance is not None and disturbance.kind != "constant":
        raise ValueError(
            f"disturbance of kind {disturbance.kind!r} is not modeled by the JAX gyrostat (only 'constant')"
        )


def _params_of(cfg: GyrostatConfig, cls: type[ReactionWheelEnv], euler_max_deg: Any = None) -> EnvParams:
    """The ``EnvParams`` of a validated configuration (:func:`attitude_envs.envs.reaction_wheel.configure`)
    of env class ``cls`` (``euler_max_deg``: an AirBearing's validated ``initial_euler_max_deg``)."""
    plant, model, layers = cfg.model.params, cfg.model, cfg.layers
    unc = cfg.inertia_uncertainty
    inertia = plant.inertia_kg_m2 if unc is None else unc.inertia_kg_m2
    inertia_eff_inv = plant.inertia_eff_inv if unc is None else plant.with_inertia(unc.inertia_kg_m2).inertia_eff_inv
    # the default faults: the numba layer's draw with a fixed generator (no JAX program to
    # compile; realize's layout). With random fields only a default: each episode draws its
    # own (``redraw_faults``)
    faults = ActuatorFaults(list(layers.fault_layer.configs), plant.n_wheels, plant.max_wheel_torque_nm)
    faults.reset(np.random.default_rng(0))
    dtype = jnp.result_type(float)

    def f(v):
        return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

    tilt = cfg.tilt_limit_deg
    if tilt is None:
        tilt_sin, tilt_cos = 2.0, -2.0  # never: |sin θ| ≤ 1, cos φ ≥ −1 (pack_constants)
    else:
        rad = math.radians(tilt)
        tilt_sin, tilt_cos = float(np.sin(rad)), float(np.cos(rad))
    if cfg.initial_attitude is not None:
        mode = START_FIXED
    elif issubclass(cls, AirBearingEnv):
        mode = START_EULER
    else:
        mode = START_AXIS_ANGLE
    sensor_config = layers.sensor_layer.config if layers.sensor_layer.enabled else {}
    axes = {name: (3 if name != "tachometer" else plant.n_wheels) for name in _SLICES}
    sensor_faults = jsens.channel_faults(layers.sensor_layer, dtype, "JAX gyrostat")
    sensor_params = jsens.suite_params(sensor_config, axes, dtype, sensor_faults)
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    rate, target = cfg.initial_rate_rad_s, cfg.target_attitude
    return EnvParams(
        plant=PlantParams(
            inertia_kg_m2=f(inertia),
            inertia_eff_inv=f(inertia_eff_inv),
            wheel_axes=f(plant.wheel_axes),
            wheel_inertia_kg_m2=f(plant.wheel_inertia_kg_m2),
            max_wheel_torque_nm=f(plant.max_wheel_torque_nm),
            max_wheel_speed_rad_s=f(plant.max_wheel_speed_rad_s),
            offset_torque_nm=f(cfg.true_params.offset_torque_nm),
            action_map=f(model.allocation * plant.max_wheel_torque_nm),
        ),
        timing=TimingParams(
            control_dt_s=f(cfg.control_dt_s),
            integrator_dt_s=f(cfg.integrator_dt_s),
            episode_duration_s=f(cfg.episode_duration_s),
        ),
        cost=CostParams(
            Q=f(model.cost.Q),
            R=f(model.cost.R),
            termination_mode=jnp.asarray(mode_code(cfg.termination_cost), dtype=jnp.int32),
            max_rate_rad_s=f(cfg.max_rate_rad_s),
            tilt_sin=f(tilt_sin),
            tilt_cos=f(tilt_cos),
        ),
        start=StartParams(
            initial_mode=jnp.asarray(mode, dtype=jnp.int32),
            initial_attitude=f(identity if cfg.initial_attitude is None else cfg.initial_attitude),
            initial_angle_deg=f(cfg.initial_angle_deg),
            initial_euler_max_deg=f(np.zeros(3) if euler_max_deg is None else euler_max_deg),
            rate_fixed=jnp.asarray(rate is not None),
            initial_rate_rad_s=f(np.zeros(3) if rate is None else rate),
            initial_rate_max_rad_s=f(cfg.initial_rate_max_rad_s),
            target_fixed=jnp.asarray(target is not None),
            target_attitude=f(identity if target is None else target),
            target_angle_deg=f(cfg.target_angle_deg),
        ),
        disturbance=DisturbanceParams(
            torque_nm=f(np.zeros(3) if layers.disturbance is None else layers.disturbance.torque_nm)
        ),
        faults=_as_dtype(jfaults.from_realized(faults.realized), dtype),
        max_steps_in_episode=jnp.asarray(episode_decisions(cfg.episode_duration_s, cfg.control_dt_s), dtype=jnp.int32),
        flight=_flight_params(cfg, dtype),
        sensors=sensor_params,
    )


def from_keywords(plant: str, kwargs: dict[str, Any]) -> tuple[GyrostatEnv, EnvParams]:
    """The JAX gyrostat ``plant`` ("ReactionWheel" or "AirBearing") and its ``EnvParams`` for the
    numba env's keywords ``kwargs``, validated as the numba env validates them (no numba env
    is built); a one-line ``ValueError`` names any configuration not modeled."""
    cls = AirBearingEnv if plant == "AirBearing" else ReactionWheelEnv
    check_keywords(cls, kwargs)
    given = dict(kwargs)
    euler = given.pop("initial_euler_max_deg", None)  # AirBearing's own keyword
    cfg = configure(cls, given.get("preset"), given)
    if cls is AirBearingEnv:
        euler = euler_max(cls.env_name, cfg.preset, cfg.tilt_limit_deg, euler)
    layers = cfg.layers
    _check_layers(layers.sensor_layer, layers.conditions, layers.disturbance)
    unc = cfg.inertia_uncertainty
    if unc is not None and unc.kind != "fixed":
        raise ValueError(
            f"inertia_uncertainty of kind {unc.kind!r} is not modeled by the JAX gyrostat "
            "(vmap over params with attitude_envs.jax.gyrostat.with_inertia instead)"
        )
    if cfg.render_mode is not None:
        raise ValueError(f"render_mode={cfg.render_mode!r} is not modeled by the JAX gyrostat (it does not render)")
    params = _params_of(cfg, cls, euler)
    configs = tuple(dict(c) for c in layers.fault_layer.configs)
    sensor_config = layers.sensor_layer.config if layers.sensor_layer.enabled else {}
    jenv = GyrostatEnv(
        n_wheels=cfg.model.params.n_wheels,
        n_substeps=cfg.n_substeps,
        include_wheel_momentum=cfg.model.include_wheel_momentum,
        body_cost_input=cfg.model.cost_input == "body",
        observe_wheel_speeds=cfg.observe_wheel_speeds,
        body_action_frame=cfg.action_frame == "body",
        fault_hint=layers.fault_hint,
        has_tilt_stop=cfg.tilt_limit_deg is not None,
        env_name=plant,
        params=params,
        fault_configs=configs,
        redraw_faults=any(jfaults.draws_per_episode(c) for c in configs),
        flight=_flight_layout(cfg),
        sensors=tuple(name for name in _SLICES if name in sensor_config),
    )
    return jenv, params


def _flight_layout(cfg: GyrostatConfig) -> FlightLayout | None:
    """The static layout of ``cfg``'s flight conditions (None in the lab), as
    :func:`attitude_envs.envs.base.build_layers` builds the actuator chain."""
    layers = cfg.layers
    if layers.conditions.is_lab:
        return None
    tol = cfg.flight_tolerances
    draw_plant = tol is not None
    return FlightLayout(
        actuators=jact.chain_layout(layers),
        draw_plant=draw_plant,
        draw_inertia=draw_plant and cfg.inertia_uncertainty is None,
        draw_offset=draw_plant and "offset_torque_nm" in tol,
    )


def _flight_params(cfg: GyrostatConfig, dtype) -> FlightParams | None:
    """The params of ``cfg``'s flight conditions (None in the lab): its plant tolerances
    (``flight_tolerances``) and the actuator chain's."""
    layers = cfg.layers
    if layers.conditions.is_lab:
        return None
    plant = cfg.model.params
    n = plant.n_wheels
    tol = cfg.flight_tolerances or {}  # none drawn: every tolerance 0
    moments, principal = np.linalg.eigh(plant.inertia_kg_m2)

    def f(v):
        return jnp.asarray(np.asarray(v, dtype=float), dtype=dtype)

    return FlightParams(
        actuators=jact.chain_params(layers, n, cfg.control_dt_s, dtype),
        inertia_moment=f(tol.get("inertia_moment", 0.0)),
        inertia_axis_deg=f(tol.get("inertia_axis_deg", 0.0)),
        misalignment_deg=f(tol.get("wheel_misalignment_deg", 0.0)),
        offset_tolerance_nm=f(tol.get("offset_torque_nm", 0.0)),
        gain_tolerance=f(layers.gain_tolerance),
        nominal_moments=f(moments),
        nominal_principal_axes=f(principal),
        given=jnp.asarray(False),
        given_inertia_kg_m2=f(plant.inertia_kg_m2),
        given_inertia_eff_inv=f(plant.inertia_eff_inv),
        given_wheel_axes=f(plant.wheel_axes),
        given_offset_torque_nm=f(cfg.true_params.offset_torque_nm),
        given_gain=f(np.ones(n)),
    )


__all__ = [
    "CostParams",
    "DisturbanceParams",
    "EnvParams",
    "EnvState",
    "EpisodePlant",
    "FlightLayout",
    "FlightParams",
    "FlightState",
    "GyrostatEnv",
    "PlantParams",
    "StartParams",
    "TimingParams",
    "episode_params",
    "from_keywords",
    "with_drawn_parameters",
    "with_inertia",
]
