"""ConstrainedSlew-v0's discrete problem: the gyrostat's (ReactionWheel-v0's plant, step and
cost, :mod:`attitude_envs.symbolic.gyrostat`) plus the env's path constraints.

The env is a :class:`~attitude_envs.envs.reaction_wheel.ReactionWheelEnv`, so its step, cost,
tumble and wheel-speed-stop rows and (under flight conditions) its actuator chain are the
gyrostat builder's, unchanged. Appended to that ``g`` (before the fixed friction signs'
margin rows, which stay last), each imposed at every node ``x_1 … x_N``, ``g ≤ 0`` satisfied
(the sign of :mod:`attitude_envs.constraints`):

* one row per active keep-out cone: ``cos θ − cos α`` with ``cos θ = d · (R(q) b)``
  (:meth:`attitude_envs.constraints.KeepOutCone.cos_angle`: ``d`` the cone's inertial
  direction, ``b`` the body boresight, ``R(q)`` body to inertial,
  :func:`attitude_envs.quaternion.to_matrix`);
* the body-rate limit per axis and sign: ``(±ω_k − L_ω) / L_ω`` (6 rows);
* the wheel-speed limit per wheel and sign: ``(±Ω_i − L_Ω) / L_Ω`` (2N rows).

The env's ``max`` over axes and wheels (:class:`~attitude_envs.constraints.BodyRateLimit`,
:class:`~attitude_envs.constraints.WheelSpeedLimit`) is the per-entry rows (smooth, linear);
the rate and wheel rows are normalized by their limits (each entry O(1)). Every appended row
carries a back-off (``row + b ≤ 0``, :func:`backoff`: :data:`BACKOFF` in the lab,
:data:`FLIGHT_BACKOFF` through a flight actuator chain): IPOPT meets a constraint only to its
tolerance and the env counts any ``g > 0`` at a decision time, so the optimum keeps a hair
inside each limit. :func:`path_constraint` gives the exact values the env reports
(``info["constraints"]``, its order and units) as a CasADi function.

The env checks its constraints at the decision times only (the states ``x_k``), as here.
"""

from __future__ import annotations

import dataclasses

import casadi
import numpy as np

from attitude_envs.symbolic import gyrostat
from attitude_envs.symbolic.problem import DiscreteProblem

__all__ = [
    "BACKOFF",
    "FLIGHT_BACKOFF",
    "backoff",
    "FRICTION_SIGN_MARGIN_RAD_S",
    "build_constrained_slew",
    "cone_row",
    "limit_rows",
    "path_constraint",
    "with_friction_signs",
]

#: the back-off of every appended row (cone rows: a cosine; rate and wheel rows: a fraction
#: of their limit), so that the env's replay of the optimum stays at ``g ≤ 0``
BACKOFF = 1e-6
#: the back-off under flight conditions with an actuator chain: the env quantizes the commands
#: the oracle keeps continuous (and its first solve relaxes the wheels' Coulomb signs), which
#: moves the replay's states off the NLP's by about 1e-5 in a cone's cosine (measured); 1e-3
#: is about 0.2° at a 15° cone and 0.1 % of the rate and wheel limits
FLIGHT_BACKOFF = 1e-3
#: the gyrostat's (the friction signs are fixed as in ReactionWheel-v0)
FRICTION_SIGN_MARGIN_RAD_S = gyrostat.FRICTION_SIGN_MARGIN_RAD_S


def _cos_angle(x, body_axis: np.ndarray, direction):
    """``d · (R(q) b)`` of the symbolic state ``x`` (q scalar last), the formula of
    :func:`attitude_envs.quaternion.to_matrix`; ``direction`` ``d`` numeric (3) or a symbolic
    3-vector (a parameter of the NLP)."""
    qx, qy, qz, qw = x[0], x[1], x[2], x[3]
    rot = [
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
        [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
        [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
    ]
    b = [float(v) for v in body_axis]
    if isinstance(direction, (casadi.SX, casadi.MX)):
        d = [direction[i] for i in range(3)]
    else:  # plain floats: a numpy scalar times an SX would make a numpy object array
        d = [float(v) for v in direction]
    return sum(d[i] * (rot[i][0] * b[0] + rot[i][1] * b[1] + rot[i][2] * b[2]) for i in range(3))


def cone_row(x, body_axis: np.ndarray, direction, cos_half_angle, backoff: float = 0.0):
    """One keep-out cone's row ``cos θ − cos α + backoff`` (``≤ 0``: outside the cone with the
    back-off) of the symbolic state ``x`` (``[q, …]``, q scalar last): ``cos θ = d · (R(q) b)``
    with ``b`` the (numeric) body boresight and ``d`` the inertial direction, numeric or a
    symbolic 3-vector; ``cos_half_angle`` numeric or symbolic. An NLP whose cones change per
    episode (:mod:`baselines.mpc_constrained`) passes ``d`` and ``cos α`` as parameters; an
    unused slot with ``d = 0`` and ``cos α = 1`` is the constant ``backoff − 1``."""
    return _cos_angle(x, body_axis, direction) - cos_half_angle + backoff


def limit_rows(x, rate_limit_rad_s: float, speed_limit_rad_s: float, n_wheels: int, backoff: float = 0.0) -> list:
    """The body-rate rows ``(±ω_k − L_ω) / L_ω + backoff`` (6: per axis and sign), then the
    wheel-speed rows ``(±Ω_i − L_Ω) / L_Ω + backoff`` (2N: per wheel and sign) of the symbolic
    state ``x = [q (4), ω (3), Ω (N), …]``, each ``≤ 0`` within its limit and the back-off."""
    rate, speed = float(rate_limit_rad_s), float(speed_limit_rad_s)
    rows = []
    for k in range(3):
        rows += [(x[4 + k] - rate) / rate + backoff, (-x[4 + k] - rate) / rate + backoff]
    for i in range(n_wheels):
        rows += [(x[7 + i] - speed) / speed + backoff, (-x[7 + i] - speed) / speed + backoff]
    return rows


def _n_wheels(env) -> int:
    return int(np.asarray(env.model.params.wheel_axes).shape[1])


def path_constraint(env, n_x: int | None = None) -> casadi.Function:
    """``x -> g`` of the episode ``env`` (unwrapped ConstrainedSlew-v0, just reset): the exact
    values of ``env.constraints`` at the symbolic state ``x`` (``[q, ω, Ω, …]``, ``n_x``
    entries: default ``7 + N``), in that order and in their units: each cone's
    ``cos θ − cos α``, then ``max_i |Ω_i| − L_Ω`` and ``max_k |ω_k| − L_ω`` (``info["constraints"]``'s
    values; the names are :func:`constraint_names`)."""
    n_w = _n_wheels(env)
    xs = casadi.SX.sym("x", 7 + n_w if n_x is None else n_x)
    out = [_cos_angle(xs, c.body_axis, c.inertial_direction) - c.cos_half_angle for c in env.cones]
    out.append(casadi.mmax(casadi.fabs(xs[7 : 7 + n_w])) - env.wheel_speed_limit.limit_rad_s)
    out.append(casadi.mmax(casadi.fabs(xs[4:7])) - env.body_rate_limit.limit_rad_s)
    return casadi.Function("constraints", [xs], [casadi.vertcat(*out)], ["x"], ["g"])


def constraint_names(env) -> list[str]:
    """The names of :func:`path_constraint`'s entries (``env.constraints``' order)."""
    return [c.name for c in env.constraints]


def backoff(env) -> float:
    """The back-off of the episode ``env`` (unwrapped, just reset): :data:`BACKOFF` in the lab
    and without an actuator chain, :data:`FLIGHT_BACKOFF` with one."""
    from attitude_envs.symbolic.actuators import ChainSpec

    return BACKOFF if ChainSpec.from_env(env, _n_wheels(env)).is_identity else FLIGHT_BACKOFF


def _rows(env, xs) -> list:
    """The appended rows (see the module), back-off included."""
    b = backoff(env)
    rows = [cone_row(xs, c.body_axis, c.inertial_direction, c.cos_half_angle, b) for c in env.cones]
    limits = (env.body_rate_limit.limit_rad_s, env.wheel_speed_limit.limit_rad_s)
    return rows + limit_rows(xs, *limits, _n_wheels(env), b)


def _with_constraints(env, base: DiscreteProblem | None, fixed_signs: bool) -> DiscreteProblem | None:
    if base is None:
        return None
    n_w = _n_wheels(env)
    xs = casadi.SX.sym("x", base.n_x)
    extra = _rows(env, xs)
    if base.g.n_in() == 2:  # the fixed friction signs: g(x, p), their margin rows last
        p = casadi.SX.sym("p", base.g.size1_in(1))
        rows = base.g(xs, p)
        n_rows = rows.shape[0]
        keep = n_w if fixed_signs else 0
        g_out = casadi.vertcat(rows[: n_rows - keep], *extra, rows[n_rows - keep :])
        g = casadi.Function("g", [xs, p], [g_out], ["x", "p"], ["g"])
    else:
        g = casadi.Function("g", [xs], [casadi.vertcat(base.g(xs), *extra)], ["x"], ["g"])
    names = ", ".join(c.name for c in env.cones) or "none"
    notes = (
        f"{base.notes}; keep-out cones ({names}) cos(theta) - cos(alpha) <= 0, body-rate limit per axis "
        f"and wheel-speed limit per wheel as state constraints at the decision times (back-off {backoff(env):g})"
    )
    return dataclasses.replace(base, env_id=env.env_name, g=g, notes=notes)


def build_constrained_slew(env) -> DiscreteProblem:
    """The problem of the episode ``env`` (an unwrapped ConstrainedSlew-v0, just reset) starts:
    :func:`attitude_envs.symbolic.gyrostat.build_reaction_wheel`'s with the cones, the
    body-rate and the wheel-speed limits appended to ``g``."""
    return _with_constraints(env, gyrostat.build_reaction_wheel(env), fixed_signs=False)


def with_friction_signs(env, signs) -> DiscreteProblem | None:
    """:func:`attitude_envs.symbolic.gyrostat.with_friction_signs` with this env's rows
    appended (before the friction margin rows, which stay the last ``N``); None when the
    episode has no Coulomb friction."""
    return _with_constraints(env, gyrostat.with_friction_signs(env, signs), fixed_signs=True)
