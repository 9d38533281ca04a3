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

import importlib
from collections.abc import Callable
from typing import Any

from attitude_envs.symbolic.problem import DiscreteProblem

__all__ = ["BUILDERS", "DiscreteProblem", "problem_for"]


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
}
#: the builders that model flight conditions (the drawn plant, the delay, the actuator chain)
FLIGHT_BUILDERS = frozenset({"ReactionWheel-v0", "AirBearing-v0"})


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
