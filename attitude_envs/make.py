"""Env construction with one-line errors: unknown ids and keyword arguments become ``ValueError``."""

from __future__ import annotations

import inspect
import re
from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import load_env_creator

from attitude_envs import presets

_UNEXPECTED = re.compile(r"unexpected keyword argument '([^']+)'")


def make_checked(env_id: str, **kwargs: Any) -> gym.Env:
    """``gym.make`` whose unknown-keyword ``TypeError`` becomes a one-line ``ValueError``
    naming the env id, the keyword and the closest accepted one (``control_dt`` → "did you
    mean 'control_dt_s'?")."""
    try:
        return gym.make(env_id, **kwargs)
    except TypeError as exc:
        found = _UNEXPECTED.search(str(exc))
        if found is None:
            raise ValueError(f"bad keyword arguments for env {env_id!r}: {str(exc).split(' was raised')[0]}") from exc
        key, accepted = found.group(1), env_keywords(env_id)
        raise ValueError(
            f"bad keyword arguments for env {env_id!r}: it has no keyword argument {key!r}"
            f"{presets.suggest(key, accepted)} (accepted: {sorted(accepted)})"
        ) from exc


def env_keywords(env_id: str) -> set[str]:
    """The keyword arguments the constructor of ``env_id`` accepts (those of every class in
    its MRO that passes ``**kwargs`` on)."""
    entry = gym.spec(env_id).entry_point
    creator = load_env_creator(entry) if isinstance(entry, str) else entry
    callables = (
        [c.__init__ for c in inspect.getmro(creator) if "__init__" in c.__dict__]
        if inspect.isclass(creator)
        else [creator]
    )
    names: set[str] = set()
    for fn in callables:
        params = inspect.signature(fn).parameters.values()
        names |= {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self"}
        if not any(p.kind == p.VAR_KEYWORD for p in params):
            break
    return names


def check_env_id(env_id: str) -> str:
    """``env_id`` if registered (the suite's ids are registered when the package ``attitude_envs``, the
    parent of this module, is imported); ``ValueError`` otherwise."""
    if env_id not in gym.registry:
        ours = sorted(k for k in gym.registry if k.startswith("attitude_envs/"))
        raise ValueError(f"unknown env id {env_id!r}; accepted: {ours} (or any registered gymnasium id)")
    return env_id
