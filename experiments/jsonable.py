"""JSON-ready copies of nested values (run configs, episode keys, cache keys)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np


def json_ready(value: Any, leaf: Callable[[Any], Any] | None = None) -> Any:
    """``value`` with mappings as dicts (keys as str), tuples and lists as lists, numpy arrays
    and scalars as lists and numbers; every leaf (numpy scalars as Python's) as
    ``leaf(leaf_value)`` (default: itself)."""
    if isinstance(value, Mapping):
        return {str(k): json_ready(v, leaf) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v, leaf) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist(), leaf)
    if isinstance(value, np.generic):
        return json_ready(value.item(), leaf)
    return value if leaf is None else leaf(value)


def repr_code(value: Any) -> Any:
    """A ``leaf`` for :func:`json_ready` (a run's config): callables and classes (schedules,
    activation classes) as their repr, other leaves as they are."""
    return repr(value) if callable(value) or isinstance(value, type) else value
