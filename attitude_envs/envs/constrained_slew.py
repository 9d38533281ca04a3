"""ConstrainedSlew-v0: large-angle rest-to-rest slews of ReactionWheel-v0's spacecraft around
keep-out cones, within wheel-speed and body-rate limits, with a constraint-cost channel.

The plant, the compiled step and the cost J are ReactionWheel-v0's
(:mod:`attitude_envs.envs.reaction_wheel`); this class adds the per-episode slew and cones,
the constraints (:mod:`attitude_envs.constraints`), their entries in ``info`` and the cones
in the observation. :class:`attitude_envs.wrappers.safety.SafetyGymnasiumWrapper` turns its
``step`` into Safety-Gymnasium's 6-tuple.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from attitude_envs import presets, quaternion, validation
from attitude_envs.constraints import BodyRateLimit, Constraint, KeepOutCone, WheelSpeedLimit
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.evaluation.success import FINAL_ERROR_DEG
from attitude_envs.presets import Preset, Sourced
from attitude_envs.presets import pyramid_4wheel as _pyramid

#: the most keep-out cones an episode has (the observation's padded slots)
MAX_CONES = 3
#: each cone slot of the observation: direction in body axes (3), cos(half-angle), mask
CONE_FEATURES = 5
#: the cones in the order an episode activates them: (name, boresight keyword, inertial body)
CONE_KINDS = (
    ("keep_out_sun_star_tracker", "star_tracker_boresight", "sun"),
    ("keep_out_moon_star_tracker", "star_tracker_boresight", "moon"),
    ("keep_out_sun_instrument", "instrument_boresight", "sun"),
)
_HALF_ANGLE_KEY = {"keep_out_sun_star_tracker": "sun_exclusion_deg", "keep_out_moon_star_tracker": "moon_exclusion_deg"}
_HALF_ANGLE_KEY["keep_out_sun_instrument"] = "instrument_exclusion_deg"
_OWN_OPTION_KEYS = ("keep_out_cones",)
#: how many draws of the Sun and Moon directions an episode may reject before giving up
_MAX_CONE_DRAWS = 10_000

_HE5AS = "Terma HE-5AS star tracker on CryoSat (ESA/GCMD instrument description: its baffle meets "
_RPM = 2.0 * math.pi / 60.0
_P = _pyramid.PYRAMID_4WHEEL.values

PYRAMID_4WHEEL_SLEW = presets.register(
    Preset(
        name="pyramid-4wheel-slew",
        env="ConstrainedSlew-v0",
        description="ReactionWheel-v0's 4 kg·m² pyramid-4wheel spacecraft: slews up to 180° around keep-out cones",
        citation=_pyramid.PYRAMID_4WHEEL.citation,
        default=True,
        values={
            **{
                k: _P[k]
                for k in (
                    "inertia_kg_m2",
                    "wheel_axes",
                    "wheel_inertia_kg_m2",
                    "max_wheel_torque_nm",
                    "max_wheel_speed_rad_s",
                    "Q",
                    "R",
                    "cost_input",
                )
            },
            "control_dt_s": Sourced(0.5, "assumed: 2 Hz decisions for a learner (AirBearing-v1's period)"),
            "integrator_dt_s": Sourced(0.1, "assumed: pyramid-4wheel's RK4 step of 0.1 s (5 per decision)"),
            "episode_duration_s": Sourced(
                120.0,
                "assumed: about three times the 41 s a rate-limited eigenaxis slew of 180° takes to within 2° "
                "(measured, baselines/cbf.py at 90 % of the 5 °/s limit), room for the detour around the cones",
            ),
            "initial_angle_deg": Sourced(180.0, "assumed: the start anywhere (random axis, angle up to 180°)"),
            "target_angle_deg": Sourced(0.0, "assumed: unused (ConstrainedSlew-v0 draws the target from the start)"),
            "initial_rate_max_rad_s": Sourced(0.0, "assumed: rest-to-rest slews"),
            "observe_wheel_speeds": Sourced(
                True, "assumed: the wheel-speed limit is a constraint, so the policy sees Ω / Ω_max"
            ),
            "action_frame": Sourced("body", "assumed: a body-torque demand, ReactionWheel-v0's advice for learning"),
            "slew_angle_deg": Sourced(180.0, "assumed: slews of up to 180° (the constrained-slew task)"),
            "cone_count": Sourced((1, 3), "assumed: one to three keep-out cones per episode"),
            "sun_exclusion_deg": Sourced(30.0, _HE5AS + "the required Sun exclusion angle of 30°)"),
            "moon_exclusion_deg": Sourced(25.0, _HE5AS + "the Moon exclusion angle of 25°)"),
            "instrument_exclusion_deg": Sourced(20.0, "assumed: an optical instrument's Sun keep-out half-angle"),
            "star_tracker_boresight": Sourced(np.array([0.0, 0.0, 1.0]), "assumed: the star tracker looks along +z"),
            "instrument_boresight": Sourced(np.array([1.0, 0.0, 0.0]), "assumed: the instrument looks along +x"),
            "cone_margin_deg": Sourced(5.0, "assumed: the start and the target at least 5° outside every cone"),
            "wheel_speed_limit_rad_s": Sourced(
                0.9 * 5400.0 * _RPM, "assumed: 90 % of the rated 5400 rpm (the motor driver's stop is at 100 %)"
            ),
            "body_rate_limit_rad_s": Sourced(
                math.radians(5.0),
                "assumed: 5 °/s per body axis, of the order of a star tracker's tracking-rate limit; below the "
                "≈ 6 °/s that the wheels' momentum at the wheel-speed limit allows about the weakest axis",
            ),
        },
    )
)

_OWN_KEYS = (
    "slew_angle_deg",
    "cone_count",
    "sun_exclusion_deg",
    "moon_exclusion_deg",
    "instrument_exclusion_deg",
    "star_tracker_boresight",
    "instrument_boresight",
    "cone_margin_deg",
    "wheel_speed_limit_rad_s",
    "body_rate_limit_rad_s",
)


def _unit_vector(name: str, value) -> np.ndarray:
    v = validation.finite_array(name, value, (3,))
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a unit vector (|v| = 1 ± 1e-6), got |v| = {norm:.9g}")
    return v / norm


def _cone_count(value) -> tuple[int, int]:
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        low = high = int(value)
    else:
        try:
            low, high = (validation.integer("cone_count", v, 0) for v in value)
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"cone_count must be an integer in [0, {MAX_CONES}] or a pair (low, high) of them, got {value!r}"
            ) from exc
    if not 0 <= low <= high <= MAX_CONES:
        raise ValueError(f"cone_count must lie in [0, {MAX_CONES}] with low <= high, got {value!r}")
    return low, high


class ConstrainedSlewEnv(ReactionWheelEnv):
    """Rest-to-rest slews of up to 180° of ReactionWheel-v0's spacecraft that keep a star
    tracker's and an instrument's boresights out of keep-out cones, within a wheel-speed and
    a body-rate limit.

    **Description.** ReactionWheel-v0's exact gyrostat, compiled RK4 step and cost
    ``J = ∫ (xᵀQx + u_cᵀRu_c) dt`` (:class:`~attitude_envs.envs.reaction_wheel.ReactionWheelEnv`)
    with the ``pyramid-4wheel`` spacecraft. Each episode draws a start attitude, a target
    within ``slew_angle_deg`` of it, and one to three keep-out cones
    (:class:`~attitude_envs.constraints.KeepOutCone`), in this order:

    1. ``keep_out_sun_star_tracker``: the star tracker boresight (body axes) out of the Sun's
       ``sun_exclusion_deg`` (30°, the Terma HE-5AS on CryoSat);
    2. ``keep_out_moon_star_tracker``: the same boresight out of the Moon's
       ``moon_exclusion_deg`` (25°, the same star tracker);
    3. ``keep_out_sun_instrument``: the instrument boresight out of the Sun's
       ``instrument_exclusion_deg`` (20°, assumed).

    The Sun and Moon directions are drawn uniformly on the sphere, again until the start and
    the target are at least ``cone_margin_deg`` outside every active cone (rejection
    sampling from the env's ``np_random``). The constraints, each ``g ≤ 0`` when satisfied
    (:mod:`attitude_envs.constraints` states the sign once), are the active cones,
    ``wheel_speed`` (``max|Ω_i| − wheel_speed_limit_rad_s``) and ``body_rate``
    (``max|ω_k| − body_rate_limit_rad_s``). They are checked at the decision times (the end
    of each step), not inside a step: within the default 5 °/s per axis (8.7 °/s in all) a
    step of 0.5 s turns a boresight by at most 4.4°, so no cone of 20° or more is crossed
    unseen while the rate limit holds. A violation ends
    nothing; it is counted and costed (below).

    **Action space.** ReactionWheel-v0's; the preset's ``action_frame="body"``:
    ``Box(-1, 1, (3,), float32)``, a body-torque demand ``T = a · max_wheel_torque_nm``
    allocated to the four wheels (minimum norm, each wheel clipped).

    **Observation space.** ``Box(float32)``: ReactionWheel-v0's observation (the error state
    ``[q_e,vec (3), ω (3, rad/s)]``, then ``Ω / Ω_max`` (4, the preset observes the wheel
    speeds), then the fault flags with ``fault_hint``), followed by ``3 × 5`` cone entries,
    one slot per cone in the order above: the cone's inertial direction in body axes
    ``R(q)ᵀ s`` (3, unit), ``cos α`` of its half-angle, and a mask (1.0: the cone is active
    this episode; an inactive slot is all zeros). Bounds: ReactionWheel-v0's, then [-1, 1]
    for the directions and cosines and [0, 1] for the masks. With the default flags the
    observation has 6 + 4 + 15 = 25 entries. The boresights are constants of the env
    (``star_tracker_boresight``, ``instrument_boresight``), not observed.

    **Reward.** ``−cost``, ReactionWheel-v0's J step cost (``info["cost"]``), unchanged: the
    constraints are not in the reward.

    **Info.** ReactionWheel-v0's info (:mod:`attitude_envs.info`) plus, on every
    step and reset:

    * ``constraints``: name → ``g`` (float) of each active constraint at the end of the step;
    * ``constraint_margins_deg``: cone name → ``θ − α`` (deg, positive outside);
    * ``constraint_cost``: 1.0 if any constraint is violated (``g > 0``) at the end of the
      step, else 0.0, Safety-Gymnasium's per-step indicator convention (0.0 at reset);
    * ``violations``: the episode's violating steps so far (the sum of ``constraint_cost``);
    * ``violations_by_constraint``: name → the episode's steps that violated it.

    **Starting state.** At rest, wheels at rest; the start attitude a rotation about a
    random axis by an angle uniform in [0, ``initial_angle_deg``] (180°); the target the
    start turned about a random axis by an angle uniform in [0, ``slew_angle_deg``].
    ``reset(options=...)`` takes ReactionWheel-v0's options (``attitude``,
    ``target_attitude``, ...; the cones are drawn around what they pin) and
    ``keep_out_cones``, a list of up to three ``{"inertial_direction": [3 floats, unit],
    "half_angle_deg": float}`` for the slots in order (which pins the cones: none is drawn,
    and their half-angles replace the keywords').

    **Episode end.** ReactionWheel-v0's: terminated on a non-finite state or tumbling
    (``max|ω| > max_rate_rad_s``), truncated at ``episode_duration_s`` (120 s: about three times
    the 41 s that :class:`baselines.cbf.EigenaxisSlewPolicy` takes to bring a 180° slew within
    2° at 90 % of the 5 °/s limit; without the rate limit the wheels' speed stop bounds the
    same slew to 17–23 s). A constraint violation ends nothing.

    **Arguments.** Every ReactionWheel-v0 keyword, with this preset's defaults, plus:

    ============================  ===========  ===================  =====  ==============================================
    name                          type         default              unit   description
    ============================  ===========  ===================  =====  ==============================================
    ``preset``                    str          "pyramid-4wheel-     —      parameter set (see Presets)
                                               slew"
    ``slew_angle_deg``            float        180                  deg    target within this angle of the start, [0, 180]
    ``cone_count``                int / pair   (1, 3)               —      cones per episode: a number in [0, 3] or a
                                                                           range (low, high) drawn uniformly
    ``sun_exclusion_deg``         float        30                   deg    star tracker Sun exclusion half-angle, (0, 90)
    ``moon_exclusion_deg``        float        25                   deg    star tracker Moon exclusion half-angle, (0, 90)
    ``instrument_exclusion_deg``  float        20                   deg    instrument Sun keep-out half-angle, (0, 90)
    ``star_tracker_boresight``    3 floats     [0, 0, 1]            —      unit boresight in body axes
    ``instrument_boresight``      3 floats     [1, 0, 0]            —      unit boresight in body axes
    ``cone_margin_deg``           float        5                    deg    start and target at least this far outside
                                                                           every cone, [0, 30]
    ``wheel_speed_limit_rad_s``   float        0.9 × 5400 rpm       rad/s  wheel-speed constraint, (0, inf)
    ``body_rate_limit_rad_s``     float        5 °/s                rad/s  body-rate constraint, (0, inf)
    ``control_dt_s``              float        0.5                  s      decision period
    ``episode_duration_s``        float        120                  s      time limit
    (every other)                                                          ReactionWheel-v0's keywords and defaults
    ============================  ===========  ===================  =====  ==============================================

    **Presets.** ``"pyramid-4wheel-slew"`` (default): ReactionWheel-v0's ``pyramid-4wheel``
    plant, cost and torque limit, the cited star tracker cones and the assumed limits.

    **Faults and sensors.** ReactionWheel-v0's faults, sensors and flight conditions
    (``conditions=``, its table :mod:`attitude_envs.presets.flight_gyrostat`).

    **Success** (:mod:`attitude_envs.evaluation.success`): ``FINAL_ERROR_DEG`` as
    ReactionWheel-v0; the violation count is reported beside it (``info["violations"]``).

    **Baselines, learned agents and the optimum** on the default episodes, seeds 0–19 (the
    ``slew`` campaign, ``attitude-envs benchmark --config slew``; ΣJ/ΣJ*, and the share of
    episodes that violate a constraint): J* with the path constraints solves all 20 with no
    violation in its replay (ΣJ* 45 123, against 44 982 for the same slews without the
    constraints, whose optimum breaks one on 6 of the 20:
    ``benchmarks/constrained_slew_optimum.py``); ``mpc-constrained``
    (:mod:`baselines.mpc_constrained`, a 15 s horizon) 1.004 (0 %); ``eigenaxis`` 1.205 (10 %),
    ``eigenaxis+cbf`` (:mod:`baselines.cbf`) 1.212 (0 %); PPO with a violation penalty
    (:class:`~attitude_envs.wrappers.ConstraintPenalty`) 1.172 (22 %, 3 training seeds × 20) and
    the same models behind the CBF filter 1.177 (0 %); PPO-Lagrangian 1.308 (15 %), behind the
    filter 1.315 (0 %). The learned agents end their slews 12–16° off the target on average.

    **Version history.** v0 (2026-11): the slews, cones, limits, constraint info and
    observation above.
    """

    env_name = "ConstrainedSlew-v0"
    default_preset = "pyramid-4wheel-slew"
    success_metric = FINAL_ERROR_DEG

    def __init__(
        self,
        preset: str | None = None,
        slew_angle_deg: float | None = None,
        cone_count=None,
        sun_exclusion_deg: float | None = None,
        moon_exclusion_deg: float | None = None,
        instrument_exclusion_deg: float | None = None,
        star_tracker_boresight=None,
        instrument_boresight=None,
        cone_margin_deg: float | None = None,
        wheel_speed_limit_rad_s: float | None = None,
        body_rate_limit_rad_s: float | None = None,
        **kwargs: Any,
    ) -> None:
        given = {k: v for k, v in locals().items() if k in _OWN_KEYS}
        super().__init__(preset, **kwargs)
        preset_values = presets.get(self.env_name, self.preset).params() if self.preset is not None else {}
        cfg = {k: given[k] if given[k] is not None else preset_values.get(k) for k in _OWN_KEYS}
        missing = [k for k in _OWN_KEYS if cfg[k] is None]
        if missing:
            raise ValueError(f"{self.env_name} preset {self.preset!r} sets no {missing[0]!r}; pass {missing[0]}=...")
        self.slew_angle_deg = validation.in_range("slew_angle_deg", cfg["slew_angle_deg"], 0.0, 180.0)
        self.cone_count = _cone_count(cfg["cone_count"])
        self.half_angles_deg = {
            name: validation.in_range(key, cfg[key], 0.0, 90.0, open_low=True, open_high=True)
            for name, key in _HALF_ANGLE_KEY.items()
        }
        self.boresights = {
            key: _unit_vector(key, cfg[key]) for key in ("star_tracker_boresight", "instrument_boresight")
        }
        self.cone_margin_deg = validation.in_range("cone_margin_deg", cfg["cone_margin_deg"], 0.0, 30.0)
        self.wheel_speed_limit = WheelSpeedLimit(
            validation.positive("wheel_speed_limit_rad_s", cfg["wheel_speed_limit_rad_s"])
        )
        self.body_rate_limit = BodyRateLimit(validation.positive("body_rate_limit_rad_s", cfg["body_rate_limit_rad_s"]))
        #: this episode's active keep-out cones, in slot order
        self.cones: list[KeepOutCone] = []
        self._violations = 0
        self._violations_by: dict[str, int] = {}
        self._last_constraint_cost = 0.0
        self._count_next_info = False

        cone_low = np.tile([-1.0, -1.0, -1.0, -1.0, 0.0], MAX_CONES)
        cone_high = np.ones(CONE_FEATURES * MAX_CONES)
        low = np.concatenate([self.observation_space.low, cone_low]).astype(np.float32)
        high = np.concatenate([self.observation_space.high, cone_high]).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    # ------------------------------------------------------------------ public interface
    @classmethod
    def _flight_table_key(cls, preset: str | None) -> tuple[str, str | None]:
        """ReactionWheel-v0's flight table (the same plant and sensors)."""
        return "ReactionWheel-v0", None

    @property
    def constraints(self) -> list[Constraint]:
        """This episode's constraints: the active cones, then ``wheel_speed`` and ``body_rate``."""
        return [*self.cones, self.wheel_speed_limit, self.body_rate_limit]

    def constraint_values(self) -> dict[str, float]:
        """Name → ``g`` of each constraint at the current true state (``g > 0``: violated)."""
        return self._constraint_state()[0]

    def _constraint_state(self) -> tuple[dict[str, float], dict[str, float]]:
        """``(name → g, cone name → margin θ − α in deg)`` at the current true state, the
        rotation ``R(q)`` computed once for every cone (this runs every step)."""
        y = self.state_row
        rotation = quaternion.to_matrix(y[:4])
        values, margins = {}, {}
        for cone in self.cones:
            cos = cone.cos_angle(y, rotation)
            values[cone.name] = cos - cone.cos_half_angle
            margins[cone.name] = KeepOutCone.angle_deg_of(cos) - cone.half_angle_deg
        for limit in (self.wheel_speed_limit, self.body_rate_limit):
            values[limit.name] = float(limit.value(y))
        return values, margins

    def cone_features(self) -> np.ndarray:
        """The observation's cone block (``3 × 5``, see the class docstring) at the true state."""
        out = np.zeros(CONE_FEATURES * MAX_CONES, dtype=np.float32)
        rotation = quaternion.to_matrix(self.state_row[:4])
        for i, cone in enumerate(self.cones):
            k = i * CONE_FEATURES
            out[k : k + 3] = rotation.T @ cone.inertial_direction
            out[k + 3] = cone.cos_half_angle
            out[k + 4] = 1.0
        return out

    # ------------------------------------------------------------------ episode
    def reset_episode(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """:meth:`ReactionWheelEnv.reset_episode` with the target drawn from the start (within
        ``slew_angle_deg``) and this episode's keep-out cones drawn around both (or pinned by
        ``options["keep_out_cones"]``)."""
        options = validation.mapping("reset options", options)
        gym.Env.reset(self, seed=seed)  # seed here: the slew and the cones are drawn before the parent's draws
        rng = self.np_random
        pinned = options.pop("keep_out_cones", None)
        if "attitude" in options:
            q0 = validation.unit_quaternion("options['attitude']", options["attitude"])
        elif self._initial_fixed is not None:
            q0 = self._initial_fixed.copy()
        else:
            q0 = quaternion.random_within_angle(rng, self._initial_angle)
        if "target_attitude" in options:
            target = validation.unit_quaternion("options['target_attitude']", options["target_attitude"])
        elif self._target_fixed is not None:
            target = self._target_fixed.copy()
        else:
            target = quaternion.multiply(q0, quaternion.random_within_angle(rng, self.slew_angle_deg))
        options["attitude"], options["target_attitude"] = q0, target
        self.cones = self._pinned_cones(pinned) if pinned is not None else self._draw_cones(rng, q0, target)
        super().reset_episode(None, options)
        self._violations = 0
        self._violations_by = {c.name: 0 for c in self.constraints}
        self._last_constraint_cost = 0.0
        self._count_next_info = False

    def _cone(self, slot: int, direction: np.ndarray, half_angle_deg: float) -> KeepOutCone:
        name, boresight_key, _ = CONE_KINDS[slot]
        return KeepOutCone(self.boresights[boresight_key], direction, half_angle_deg, name=name)

    def _draw_cones(self, rng: np.random.Generator, q0: np.ndarray, target: np.ndarray) -> list[KeepOutCone]:
        """The episode's cones: a count in ``cone_count``, then the Sun and Moon directions
        uniform on the sphere until the start and the target clear every active cone by
        ``cone_margin_deg``."""
        low, high = self.cone_count
        n = int(rng.integers(low, high + 1))
        if n == 0:
            return []
        for _ in range(_MAX_CONE_DRAWS):
            bodies = {}
            for body in ("sun", "moon"):
                v = rng.normal(size=3)
                bodies[body] = v / np.linalg.norm(v)
            cones = [self._cone(i, bodies[CONE_KINDS[i][2]], self.half_angles_deg[CONE_KINDS[i][0]]) for i in range(n)]
            if all(c.margin_deg(q) >= self.cone_margin_deg for c in cones for q in (q0, target)):
                return cones
        raise RuntimeError(  # pragma: no cover - needs cones that cover nearly the whole sphere
            f"no keep-out cones clear the start and the target by cone_margin_deg = {self.cone_margin_deg:g} "
            f"after {_MAX_CONE_DRAWS} draws; lower cone_margin_deg or the half-angles"
        )

    def _pinned_cones(self, pinned) -> list[KeepOutCone]:
        if not isinstance(pinned, (list, tuple)) or len(pinned) > MAX_CONES:
            raise ValueError(
                f"options['keep_out_cones'] must be a list of at most {MAX_CONES} dicts "
                f"{{'inertial_direction': [3 floats], 'half_angle_deg': float}}, got {pinned!r}"
            )
        cones = []
        for i, spec in enumerate(pinned):
            where = f"options['keep_out_cones'][{i}]"
            spec = validation.mapping(where, spec)
            validation.known_keys(where, spec, {"inertial_direction", "half_angle_deg"})
            direction = _unit_vector(f"{where}['inertial_direction']", spec.get("inertial_direction"))
            default_angle = self.half_angles_deg[CONE_KINDS[i][0]]
            angle = validation.in_range(
                f"{where}['half_angle_deg']",
                spec.get("half_angle_deg", default_angle),
                0.0,
                90.0,
                open_low=True,
                open_high=True,
            )
            cones.append(self._cone(i, direction, angle))
        return cones

    def step(self, action):
        self._count_next_info = True
        # ReactionWheel-v0's step without its episode guard (this class's own guard wraps this
        # method and clips with this observation space)
        obs, reward, terminated, truncated, info = ReactionWheelEnv.step.__wrapped__(self, action)
        if obs.shape[0] < self.observation_space.shape[0]:  # the compiled step's observation
            obs = np.concatenate([obs, self.cone_features()])
        return obs, reward, terminated, truncated, info

    def _observation(self) -> np.ndarray:
        return np.concatenate([super()._observation(), self.cone_features()])

    def _info(self, applied: np.ndarray, commanded: np.ndarray, cost: float) -> dict:
        info = super()._info(applied, commanded, cost)
        values, margins = self._constraint_state()
        if self._count_next_info:  # a step's info: count its violations once
            self._count_next_info = False
            violated = [name for name, g in values.items() if g > 0.0]
            for name in violated:
                self._violations_by[name] += 1
            self._last_constraint_cost = 1.0 if violated else 0.0
            self._violations += int(bool(violated))
        info["constraints"] = values
        info["constraint_margins_deg"] = margins
        info["constraint_cost"] = self._last_constraint_cost
        info["violations"] = self._violations
        info["violations_by_constraint"] = dict(self._violations_by)
        return info
