"""Env construction with one-line errors: unknown ids and keyword arguments become ``ValueError``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym


def make_checked(env_id: str, **kwargs: Any) -> gym.Env:
    """``gym.make`` whose unknown-keyword ``TypeError`` becomes a ``ValueError`` naming the env."""
    try:
        return gym.make(env_id, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad keyword arguments for env {env_id!r}: {str(exc).split(' was raised')[0]}") from exc


def check_env_id(env_id: str) -> str:
    """``env_id`` if registered (the suite's ids are registered on import); ``ValueError`` otherwise."""
    import attitude_envs  # noqa: F401  (registers the ids)

    if env_id not in gym.registry:
        ours = sorted(k for k in gym.registry if k.startswith("attitude_envs/"))
        raise ValueError(f"unknown env id {env_id!r}; accepted: {ours} (or any registered gymnasium id)")
    return env_id
