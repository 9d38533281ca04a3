"""attitude_envs.files: the one atomic write (text, bytes or a writer; durable on request)."""

import os
import stat
import sys
from pathlib import Path

import pytest

from attitude_envs import files
from attitude_envs.files import atomic_write


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_text_is_written_as_utf8_with_its_newlines_and_the_folder_is_created(tmp_path):
    target = tmp_path / "new" / "deeper" / "report.md"
    text = "J / J* ≥ 1\r\nline two\n"
    assert atomic_write(target, text) == target
    assert target.read_bytes() == text.encode("utf-8")
    assert _names(target.parent) == ["report.md"]


def test_bytes_replace_an_existing_file(tmp_path):
    target = tmp_path / "table.bin"
    target.write_bytes(b"old contents, longer than the new")
    atomic_write(str(target), b"\x00\x01new")
    assert target.read_bytes() == b"\x00\x01new"
    assert _names(tmp_path) == ["table.bin"]


def test_a_writer_gets_a_temporary_path_beside_the_target(tmp_path):
    target = tmp_path / "solver.casadi"
    seen = []

    def save(tmp: Path) -> None:
        seen.append(tmp)
        tmp.write_text("built", encoding="utf-8")

    atomic_write(target, save)
    assert target.read_text(encoding="utf-8") == "built"
    assert len(seen) == 1 and isinstance(seen[0], Path)
    assert seen[0].parent == tmp_path and seen[0] != target
    assert _names(tmp_path) == ["solver.casadi"]


def test_a_writer_that_raises_leaves_the_old_file_and_no_temporary_file(tmp_path):
    target = tmp_path / "episodes.csv"
    target.write_text("old\n", encoding="utf-8")

    def half_then_fail(tmp: Path) -> None:
        tmp.write_text("half a ro", encoding="utf-8")
        raise RuntimeError("killed mid-write")

    with pytest.raises(RuntimeError, match="killed mid-write"):
        atomic_write(target, half_then_fail)
    assert target.read_text(encoding="utf-8") == "old\n"
    assert _names(tmp_path) == ["episodes.csv"]


def test_a_writer_that_writes_elsewhere_is_an_error_not_a_silent_loss(tmp_path):
    target = tmp_path / "weights.npy"
    target.write_bytes(b"old")
    with pytest.raises(FileNotFoundError, match="did not write the file it was given"):
        atomic_write(target, lambda tmp: None)
    assert target.read_bytes() == b"old"
    assert _names(tmp_path) == ["weights.npy"]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permission bits")
@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_the_new_file_mode_follows_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        text = atomic_write(tmp_path / "text.json", "{}\n")
        written = atomic_write(tmp_path / "saved.bin", lambda tmp: tmp.write_bytes(b"x"))
    finally:
        os.umask(old)
    for path in (text, written):
        assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask  # not mkstemp's 0600


@pytest.mark.parametrize("path", ["", ".", "..", "/", "results/.."])
def test_a_path_without_a_file_name_is_a_value_error(path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match="path must name a file"):
        atomic_write(path, "text")
    assert _names(tmp_path) == []


@pytest.mark.parametrize(
    ("content", "expected"),
    [("text\n", b"text\n"), (b"bytes", b"bytes"), (lambda tmp: tmp.write_bytes(b"saved"), b"saved")],
)
def test_durable_fsyncs_the_file_and_then_its_folder(tmp_path, monkeypatch, content, expected):
    synced = []  # per fsync: whether it was of a directory
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        synced.append(stat.S_ISDIR(os.fstat(fd).st_mode))
        real_fsync(fd)

    monkeypatch.setattr(files.os, "fsync", fsync)
    target = atomic_write(tmp_path / "latest.json", content, durable=True)
    assert target.read_bytes() == expected
    assert synced == ([False] if sys.platform == "win32" else [False, True])
    assert _names(tmp_path) == ["latest.json"]


def test_not_durable_does_not_fsync(tmp_path, monkeypatch):
    monkeypatch.setattr(files.os, "fsync", lambda fd: pytest.fail("fsync without durable=True"))
    atomic_write(tmp_path / "a.txt", "a")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "a"
