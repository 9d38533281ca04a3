"""Symbolic (CasADi) models of the envs' own discrete optimal-control problems.

:func:`problem_for` resets an env and returns its :class:`DiscreteProblem` for that episode:
the exact discrete dynamics and step cost the env computes, with the episode's realized
faults, start state and disturbance known (an oracle, used by the optimal-control yardstick
J*). The gyrostat's step is built from a parameter set
(:func:`attitude_envs.symbolic.gyrostat.step_function` of a
:class:`~attitude_envs.symbolic.gyrostat.GyrostatParameters`): J* builds it from the episode's
true plant, the model-predictive baseline (:mod:`baselines.mpc`) from the nominal model, so
both use one model. Requires CasADi (``pip install 'attitude-envs[optimal]'``); the core
package never imports this module.

One builder module per plant; each builder takes the unwrapped env right after its reset and
returns the :class:`DiscreteProblem`. :data:`BUILDERS` maps an env name to its builder,
loaded on first use (so builder modules import :class:`DiscreteProblem` from
:mod:`attitude_envs.symbolic.problem` without an import cycle). A new plant is one line:
``"Name-v0": _builder("module", "function"),``.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable
from typing import Any

import casadi
import numpy as np

from attitude_envs.symbolic.problem import DiscreteProblem

__all__ = [
    "BUILDERS",
    "FLIGHT_BUILDERS",
    "DiscreteProblem",
    "friction_sign_margin",
    "friction_speeds",
    "has_coulomb_friction",
    "problem_for",
    "with_friction_signs",
]


def _builder(module: str, function: str) -> Callable[[Any], DiscreteProblem]:
    """A builder ``module.function`` of this package, imported on its first call."""

    def build(env: Any) -> DiscreteProblem:
        return getattr(importlib.import_module(f"{__name__}.{module}"), function)(env)

    build.__qualname__ = f"{module}.{function}"
    return build


#: env name -> builder(unwrapped env, just reset) -> DiscreteProblem
BUILDERS: dict[str, Callable[[Any], DiscreteProblem]] = {
    "LinearSystem-v0": _builder("linear", "build_linear_system"),
    "ReactionWheel-v0": _builder("gyrostat", "build_reaction_wheel"),
    "AirBearing-v0": _builder("gyrostat", "build_air_bearing"),
    "FuelSlosh-v0": _builder("slosh", "build_fuel_slosh"),
    "Magnetorquer-v0": _builder("magnetorquer", "build_magnetorquer"),
    "ConstrainedSlew-v0": _builder("constrained_slew", "build_constrained_slew"),
}
#: the builders that model flight conditions (the drawn plant, the delay, the actuator chain)
FLIGHT_BUILDERS = frozenset(
    {"ReactionWheel-v0", "AirBearing-v0", "LinearSystem-v0", "FuelSlosh-v0", "Magnetorquer-v0", "ConstrainedSlew-v0"}
)
#: the builders with wheel Coulomb friction under flight conditions: env name -> module whose
#: ``with_friction_signs(env, signs)`` fixes the signs per step (:func:`with_friction_signs`)
FRICTION_SIGN_MODULES = {
    "ReactionWheel-v0": "gyrostat",
    "AirBearing-v0": "gyrostat",
    "Magnetorquer-v0": "magnetorquer",
    "ConstrainedSlew-v0": "constrained_slew",  # the gyrostat's signs, its own rows kept
}
#: the modules whose states are the gyrostat's ``[q, ω, Ω, …]``
_GYROSTAT_STATE_MODULES = ("gyrostat", "constrained_slew")


def _name(env: Any) -> str:
    base = env.unwrapped
    return getattr(base, "env_name", type(base).__name__)


def has_coulomb_friction(env: Any) -> bool:
    """Whether the episode of ``env`` (just reset) acts through an actuator chain with Coulomb
    friction that its symbolic model can fix the signs of (False in the lab)."""
    from attitude_envs.symbolic.actuators import ChainSpec

    if _name(env) not in FRICTION_SIGN_MODULES:
        return False
    spec = ChainSpec.from_env(env.unwrapped, 0)
    return spec.has_friction and bool(np.any(spec.coulomb != 0))


def friction_speeds(env: Any, states: np.ndarray) -> np.ndarray:
    """``(n, N)``: the speeds whose Coulomb sign the problem of ``env`` fixes per step
    (:func:`with_friction_signs`), at each row of the symbolic ``states``: the gyrostats'
    wheel speeds ``Ω``; Magnetorquer's ``[0, 0, 0, −Ω]`` (its chain's convention)."""
    name, states = _name(env), np.atleast_2d(np.asarray(states, dtype=float))
    if FRICTION_SIGN_MODULES.get(name) in _GYROSTAT_STATE_MODULES:
        n_w = env.unwrapped.model.params.wheel_axes.shape[1]
        return states[:, 7 : 7 + n_w]
    if name == "Magnetorquer-v0":
        return importlib.import_module(f"{__name__}.magnetorquer").friction_speeds(env.unwrapped, states)
    raise ValueError(f"{name} has no Coulomb friction signs to fix (those of {sorted(FRICTION_SIGN_MODULES)} do)")


def friction_sign_margin(env: Any) -> float:
    """The margin (rad/s) :func:`with_friction_signs` holds the speeds of ``env`` from zero by
    (its module's ``FRICTION_SIGN_MARGIN_RAD_S``)."""
    return float(importlib.import_module(f"{__name__}.{FRICTION_SIGN_MODULES[_name(env)]}").FRICTION_SIGN_MARGIN_RAD_S)


def with_friction_signs(env: Any, signs: np.ndarray, margin_where: np.ndarray | bool = True) -> DiscreteProblem | None:
    """The problem of the episode ``env`` (just reset) starts, with the Coulomb friction's
    ``sign(speed)`` fixed per step to ``signs`` ((n_steps, N), e.g. the sign of
    :func:`friction_speeds` of a first solve's trajectory) in place of the ``tanh``
    relaxation: exact wherever the optimum keeps those signs. ``margin_where``: where the
    speeds are held at least the module's ``FRICTION_SIGN_MARGIN_RAD_S`` from zero on the
    side of their sign (path constraints on the state each step starts from; the last ``N``
    rows of ``g``): True (default) at every step, False nowhere, or an (n_steps, N) bool
    array (e.g. where the trajectory the signs came from already clears the margin). None
    when the episode has no Coulomb friction."""
    name = _name(env)
    module = importlib.import_module(f"{__name__}.{FRICTION_SIGN_MODULES[name]}")
    problem = module.with_friction_signs(env.unwrapped, signs)
    if problem is None or margin_where is True:
        return problem
    n_steps, n = problem.n_steps, np.asarray(signs).reshape(problem.n_steps, -1).shape[1]
    where = np.broadcast_to(np.asarray(margin_where, dtype=float), (n_steps, n))
    note = f"; the fixed friction signs held with a margin |Omega| >= {module.FRICTION_SIGN_MARGIN_RAD_S:g} rad/s"
    n_p = problem.params.shape[1]
    xs, a, ps = casadi.SX.sym("x", problem.n_x), casadi.SX.sym("a", problem.n_u), casadi.SX.sym("p", n_p + n)
    rows = problem.g(xs, ps[:n_p])
    n_rows = rows.shape[0]
    if not where.any():  # the signs alone: the margin rows dropped
        p0 = casadi.SX.sym("p", n_p)
        g = casadi.Function("g", [xs, p0], [problem.g(xs, p0)[: n_rows - n]], ["x", "p"], ["g"])
        return dataclasses.replace(problem, g=g, notes=problem.notes.replace(note, ""))
    # per step and speed: a flag after the signs in p switches its margin row on (1) or off (0)
    flags = ps[n_p:]
    g = casadi.Function(
        "g", [xs, ps], [casadi.vertcat(rows[: n_rows - n], flags * rows[n_rows - n :])], ["x", "p"], ["g"]
    )
    x_next, cost = problem.step(xs, a, ps[:n_p])
    step = casadi.Function("step", [xs, a, ps], [x_next, cost], ["x", "a", "p"], ["x_next", "cost"])
    return dataclasses.replace(
        problem,
        step=step,
        g=g,
        params=np.column_stack([problem.params, where]),
        notes=problem.notes.replace(note, note + " where the previous trajectory clears it"),
    )


def problem_for(env: Any, seed: int | None = None, options: dict | None = None) -> DiscreteProblem:
    """Reset ``env`` with ``seed`` and ``options`` and return its episode's
    :class:`DiscreteProblem` (the env is left at the start of that episode).

    Raises ValueError for an env without a builder, and (from the builder) for fault kinds,
    disturbances or settings the symbolic model does not represent."""
    base = env.unwrapped
    name = getattr(base, "env_name", type(base).__name__)
    if name not in BUILDERS:
        raise ValueError(f"env must be one of {sorted(BUILDERS)} for a symbolic model, got {name!r}")
    conditions = getattr(base, "conditions", None)
    plant_conditions = None if conditions is None else conditions.as_dict() | {"sensors": 0.0}
    if plant_conditions is not None and any(plant_conditions.values()) and name not in FLIGHT_BUILDERS:
        # sensors do not change the plant (the oracle knows the true state); the rest does
        raise ValueError(
            f"the symbolic model of {name} does not model flight conditions yet ({conditions.as_dict()}); "
            f"those of {sorted(FLIGHT_BUILDERS)} do"
        )
    env.reset(seed=seed, options=options)
    return BUILDERS[name](base)
