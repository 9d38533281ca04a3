"""Named parameter sets of the papers' spacecraft, one mechanism for every env.

A :class:`Preset` is an immutable, named set of constructor values for one env, each
value a :class:`Sourced` carrying where it comes from: the paper (authors, year, and the
equation, table or section), or ``"assumed: <reason>"`` where the paper gives none.
``gym.make(env_id, preset="<name>", **overrides)`` starts from the preset and lets explicit
keyword arguments override single values (see :func:`resolve`).

>>> from attitude_envs import presets
>>> [p.name for p in presets.for_env("ReactionWheel-v0")]  # doctest: +SKIP
['pyramid-4wheel', 'heravi-2017']
>>> presets.get("ReactionWheel-v0", "heravi-2017").source("inertia_kg_m2")  # doctest: +SKIP
'Heravi & Novinzadeh 2017, eq. 71'

Older names are kept as aliases (each preset's ``aliases``, e.g. the slosh fills ``"i"`` …
``"iv"``), so saved configurations keep loading.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

__all__ = ["Preset", "Sourced", "all_presets", "for_env", "get", "register", "resolve", "suggest"]


def _frozen(value: Any) -> Any:
    """An immutable copy: arrays read-only, lists as tuples, dicts as read-only mappings,
    dataclass instances deep-copied with their array fields read-only."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        frozen = copy.deepcopy(value)
        for v in vars(frozen).values():
            if isinstance(v, np.ndarray):
                v.setflags(write=False)
        return frozen
    if isinstance(value, np.ndarray):
        arr = np.array(value, copy=True)
        arr.setflags(write=False)
        return arr
    if isinstance(value, dict):
        return MappingProxyType({k: _frozen(v) for k, v in value.items()})
    if isinstance(value, list):
        return tuple(_frozen(v) for v in value)
    return value


def _thawed(value: Any) -> Any:
    """A fresh, writable copy of a frozen value (what an env receives)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return copy.deepcopy(value)  # numpy's deepcopy gives writable arrays
    if isinstance(value, np.ndarray):
        return np.array(value, copy=True)
    if isinstance(value, Mapping):
        return {k: _thawed(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_thawed(v) for v in value]
    return value


@dataclass(frozen=True)
class Sourced:
    """One preset value and its source: ``"<authors> <year>, <eq./table/section>"`` or
    ``"assumed: <reason>"``."""

    value: Any
    source: str

    def __post_init__(self) -> None:
        if not isinstance(self.source, str) or not self.source.strip():
            raise ValueError("every preset value needs a source (paper, table or equation, or 'assumed: reason')")
        object.__setattr__(self, "value", _frozen(self.value))


@dataclass(frozen=True)
class Preset:
    """An immutable named parameter set of one env.

    ``env``: the env id without namespace (``"ReactionWheel-v0"``); ``citation``: the
    paper the values come from; ``values``: constructor keyword → :class:`Sourced`;
    ``aliases``: older names that select the same preset.
    """

    name: str
    env: str
    description: str
    citation: str
    values: Mapping[str, Sourced]
    aliases: tuple[str, ...] = ()
    default: bool = field(default=False)

    def __post_init__(self) -> None:
        for key, v in self.values.items():
            if not isinstance(v, Sourced):
                raise TypeError(f"preset {self.name!r}: value {key!r} must be a Sourced, got {type(v).__name__}")
        object.__setattr__(self, "values", MappingProxyType(dict(self.values)))
        object.__setattr__(self, "aliases", tuple(self.aliases))

    def params(self) -> dict[str, Any]:
        """The preset's constructor keywords as fresh, writable copies."""
        return {k: _thawed(v.value) for k, v in self.values.items()}

    def source(self, key: str) -> str:
        """Where value ``key`` comes from."""
        if key not in self.values:
            raise KeyError(f"preset {self.name!r} of {self.env} sets no {key!r}; it sets {sorted(self.values)}")
        return self.values[key].source


_REGISTRY: dict[str, dict[str, Preset]] = {}  # env -> name -> preset (built once, at import, from static data)
_ALIASES: dict[str, dict[str, str]] = {}  # env -> alias -> name


def _env_key(env: str) -> str:
    return env.split("/", 1)[-1]


def register(preset: Preset) -> Preset:
    """Add ``preset`` to the registry (names and aliases unique per env)."""
    env = _env_key(preset.env)
    names = _REGISTRY.setdefault(env, {})
    aliases = _ALIASES.setdefault(env, {})
    for n in (preset.name, *preset.aliases):
        if n in names or n in aliases:
            raise ValueError(f"preset name {n!r} is already used for {env}")
    if preset.default and any(p.default for p in names.values()):
        raise ValueError(f"{env} already has a default preset")
    names[preset.name] = preset
    aliases.update({a: preset.name for a in preset.aliases})
    return preset


def for_env(env: str) -> list[Preset]:
    """The presets of ``env`` (with or without the ``attitude_envs/`` namespace), default first."""
    found = list(_REGISTRY.get(_env_key(env), {}).values())
    return sorted(found, key=lambda p: not p.default)


def all_presets() -> list[Preset]:
    """Every registered preset, grouped by env."""
    return [p for env in sorted(_REGISTRY) for p in for_env(env)]


def suggest(name: str, accepted: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest accepted name, or ``""``."""
    close = difflib.get_close_matches(str(name), list(accepted), n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


def get(env: str, name: str | None = None) -> Preset:
    """The preset ``name`` of ``env`` (an alias works too); the env's default when None."""
    key = _env_key(env)
    names = _REGISTRY.get(key, {})
    if name is None:
        for p in names.values():
            if p.default:
                return p
        raise ValueError(f"{key} has no default preset")
    name = _ALIASES.get(key, {}).get(name, name)
    if name not in names:
        accepted = sorted(names) + sorted(_ALIASES.get(key, {}))
        raise ValueError(f"preset must be one of {accepted} for {key}, got {name!r}{suggest(name, accepted)}")
    return names[name]


def resolve(env: str, name: str | None, overrides: Mapping[str, Any], accepted: Iterable[str]) -> dict[str, Any]:
    """Constructor values of ``env``: the preset's (``name=None``: no preset), then every
    override that is not None. Unknown override keys raise a ``ValueError`` naming the env,
    the key, the closest accepted keyword and the accepted ones."""
    accepted = set(accepted)
    unknown = sorted(set(overrides) - accepted)
    if unknown:
        key = unknown[0]
        raise ValueError(
            f"{_env_key(env)} has no keyword argument {key!r}{suggest(key, accepted)} (accepted: {sorted(accepted)})"
        )
    values = {} if name is None else get(env, name).params()
    values.update({k: v for k, v in overrides.items() if v is not None})
    return values


# The papers' parameter sets (static data; importing registers them).
from attitude_envs.presets import (  # noqa: E402
    air_bearing,  # noqa: F401
    heravi_2017,  # noqa: F401
    navabi_slosh,  # noqa: F401
    pyramid_4wheel,  # noqa: F401
    sadigh_2022,  # noqa: F401
)
