"""A benchmark's results file: its rows under ``meta`` (machine, date, git revision, argv), so
a committed result says where and from what it was measured."""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

from experiments.report import git_revision


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


def append_journal(path: str | Path, entry: dict[str, Any], default: Any = float) -> None:
    """Append ``entry`` as one JSON line to the journal ``path``, on a line of its own: after a
    kill cut the last line short, that fragment stays alone on its line (readers skip it) instead
    of swallowing the entry written next. Flushed to disk before returning."""
    path = Path(path)
    with path.open("a+b") as fh:
        fh.seek(0, os.SEEK_END)
        if fh.tell() > 0:
            fh.seek(-1, os.SEEK_END)
            if fh.read(1) != b"\n":
                fh.write(b"\n")
        fh.write((json.dumps(entry, default=default) + "\n").encode("utf-8"))
        fh.flush()
        os.fsync(fh.fileno())


def journal_entries(path: str | Path) -> list[dict[str, Any]]:
    """The entries of the journal ``path`` in order (empty when there is none), without the line
    a kill cut short."""
    path = Path(path)
    if not path.is_file():
        return []
    entries = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            entries.append(json.loads(line))
        except ValueError:
            continue  # a line cut short by a killed run
    return entries
