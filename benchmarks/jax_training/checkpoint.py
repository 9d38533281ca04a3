"""The finished sections of a run, kept as each one ends, as strict JSON."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from attitude_envs.files import atomic_write
from benchmarks.jax_training.task import say


class Checkpoint:
    """The finished sections of a run, kept in ``OUT/jax_training.partial.json`` as each one ends
    (a killed or failed run loses only the section it was in). A rerun of the same command on
    the same commit takes the finished sections from there; a finished run deletes the file."""

    def __init__(self, path: Path, key: dict[str, Any]) -> None:
        self.path, self.key = path, key
        self.sections: dict[str, Any] = {}
        self.section_wall_s: dict[str, float] = {}  # s per kept section
        self.reused: list[str] = []
        if path.is_file():
            saved = json.loads(path.read_text(encoding="utf-8"))
            if saved.get("key") == key:
                self.sections, self.section_wall_s = saved["sections"], saved["section_wall_s"]
                say(f"{path}: sections {sorted(self.sections)} finished before (same command and commit)")
            else:
                say(f"{path} is from another command or commit: starting over")

    def run(self, name: str, fn: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """The section ``name``: from the file when it finished before, else ``fn()`` (saved)."""
        if name in self.sections:
            say(f"{name}: finished before, not run again")
            self.reused.append(name)
            return self.sections[name]
        start = time.perf_counter()
        self.sections[name] = finite_or_none(fn())
        self.section_wall_s[name] = time.perf_counter() - start
        payload = {"key": self.key, "section_wall_s": self.section_wall_s, "sections": self.sections}
        atomic_write(self.path, json.dumps(payload, allow_nan=False) + "\n")
        return self.sections[name]


def finite_or_none(value: Any) -> Any:
    """``value`` as strict JSON: numpy scalars as Python numbers, NaN and ±inf as None."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
