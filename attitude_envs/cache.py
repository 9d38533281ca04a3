"""Where the suite keeps what it computes once and reuses across processes (J* solutions,
compiled solvers): ``$ATTITUDE_ENVS_CACHE/<name>`` when that variable is set, else
``~/.cache/attitude-envs/<name>`` (``$XDG_CACHE_HOME`` replaces ``~/.cache``)."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir(name: str) -> Path:
    """The cache folder ``name`` (not created here)."""
    root = os.environ.get("ATTITUDE_ENVS_CACHE")
    if root:
        return Path(root) / name
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "attitude-envs" / name
