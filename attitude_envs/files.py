"""Durable file writes: the one atomic write of the suite (a result, a table, a checkpoint
pointer or a compiled solver is either the old file or the whole new one, never half-written,
also when the process is killed mid-write)."""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any


def fsync_dir(path: str | os.PathLike) -> None:
    """Make a rename or a new file in directory ``path`` durable (a no-op on Windows, which
    cannot open a directory to flush it)."""
    if os.name == "nt":
        return
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write(
    path: str | os.PathLike,
    content: str | bytes | Callable[[Path], object],
    *,
    durable: bool = False,
) -> Path:
    """Write ``content`` to ``path`` through a temporary file in the same folder and
    ``os.replace``; the folder is created. ``content`` is text (UTF-8, newlines as given),
    bytes, or a writer called with the temporary file's path (a library's own ``save``; it
    must write that exact path, so a saver that appends its own suffix needs a file object).
    ``durable`` also fsyncs the file and the folder (a checkpoint survives a power loss, not
    only a kill). The new file's mode follows the umask. Returns ``path``."""
    path = Path(path)
    if path.name in ("", ".", ".."):
        raise ValueError(f"path must name a file, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    # A name of this process and thread (not mkstemp: its 0600 mode would outlive the rename);
    # ".tmp" last, so no glob for the real files' suffix picks it up mid-write.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        if callable(content):
            content(tmp)
            if not tmp.is_file():
                raise FileNotFoundError(
                    f"the writer of {str(path)!r} did not write the file it was given, {str(tmp)!r}"
                )
        else:
            with tmp.open("wb") as fh:
                fh.write(content.encode("utf-8") if isinstance(content, str) else bytes(content))
        if durable:
            fd = os.open(tmp, os.O_RDONLY)  # read-only: a writer may have left the file without write permission
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    if durable:
        fsync_dir(path.parent)
    return path


def read_json(path: str | os.PathLike, what: str = "file") -> Any:
    """The content of the JSON file ``path``; a one-line ``ValueError`` naming the file (and
    ``what`` it is, e.g. ``"the run's config"``) when it is not valid JSON (a file cut by a
    kill, or edited by hand), instead of a ``JSONDecodeError`` that names no file."""
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(
            f"{what} {str(path)!r} is not valid JSON ({exc}): it is cut or was edited; restore or delete it"
        ) from None
