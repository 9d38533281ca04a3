"""A benchmark's results file: its rows under ``meta`` (machine, date, git revision, argv), so
a committed result says where and from what it was measured."""

from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

from experiments.report.provenance import git_revision


def write_results(out: str | Path, argv: list[str] | None, **payload: Any) -> Path:
    """Write ``{"meta": …, **payload}`` as JSON to ``out`` (parent folders made); ``argv``: the
    script's arguments (None: ``sys.argv[1:]``). Returns the path."""
    meta = {
        "machine": platform.platform(),
        "date": time.strftime("%Y-%m-%d"),
        "git_revision": git_revision(),
        "argv": list(argv) if argv is not None else sys.argv[1:],
    }
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"meta": meta, **payload}, indent=1) + "\n", encoding="utf-8")
    return path
