"""Worker processes that die with the process that started them.

:func:`die_with_parent` is a process-pool initializer (``initializer=die_with_parent,
initargs=(os.getpid(),)``): the worker ignores Ctrl-C (SIGINT; the parent handles it and ends
its workers) and exits when the parent process is gone, also after a SIGKILL of the parent,
which runs no clean-up. On Linux the kernel kills the worker when its parent dies
(``prctl(PR_SET_PDEATHSIG, SIGKILL)``); everywhere a watchdog thread checks every 0.25 s that
the given process still runs (a forkserver's children watch that process, not the forkserver).
Once the workers are gone, the forkserver and the resource tracker exit too.

:func:`run_in_child` runs one function in a fresh interpreter instead (a benchmark's run that
must start cold, on CPUs of its own): the spec and the result travel as JSON.
"""

from __future__ import annotations

import ctypes
import importlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

_PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCH_INTERVAL_S = 0.25
#: what starts the result line a :func:`run_in_child` child prints on its stdout
RESULT_PREFIX = "CHILD_RESULT "


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped, counts as dead)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[-1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:  # no /proc (macOS): signal 0 probes existence
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True


def _kill_self() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def _watch(parent_pid: int, ppid: int) -> None:
    while True:
        time.sleep(WATCH_INTERVAL_S)
        if os.getppid() != ppid or not alive(parent_pid):
            _kill_self()


def die_with_parent(parent_pid: int) -> None:
    """Pool-worker initializer: ignore SIGINT and exit when ``parent_pid`` is gone (see the module)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        except (OSError, AttributeError):
            pass  # the watchdog below still ends the worker
    ppid = os.getppid()
    if not alive(parent_pid):
        _kill_self()
    threading.Thread(target=_watch, args=(parent_pid, ppid), daemon=True, name="watch-parent").start()


def pin_to_one_core(index: int) -> int | None:
    """Restrict this process to one CPU: the ``index``-th (cyclically) of those it may run on.

    The local pool of a campaign that trains with SBX calls it in each worker (worker ``i`` →
    CPU ``i``), because JAX sizes its CPU thread pool from the process's CPU affinity and has
    no setting for it (see :mod:`experiments.training.algorithm`). Returns the CPU, or None where the
    platform has no affinity call (macOS) or refuses it."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    try:
        cpus = sorted(os.sched_getaffinity(0))
        cpu = cpus[int(index) % len(cpus)]
        os.sched_setaffinity(0, {cpu})
    except OSError:  # a sandbox that forbids it: run unpinned
        return None
    return cpu


def pool_context():
    """The multiprocessing context for a process pool: ``fork`` where available (fast start, no
    re-import of the caller's ``__main__``), unless this process already runs torch or JAX, whose
    thread pools a fork can leave locked in the child (a hang): then ``forkserver`` (else ``spawn``)."""
    import multiprocessing as mp

    methods = mp.get_all_start_methods()
    if "fork" in methods and not {"torch", "jax"} & set(sys.modules):
        return mp.get_context("fork")
    return mp.get_context("forkserver" if "forkserver" in methods else "spawn")


def run_in_child(
    target: str,
    spec: Mapping[str, Any],
    *,
    cpus: Iterable[int] | None = None,
    env: Mapping[str, str] | None = None,
    cwd: str | Path | None = None,
    timeout: float | None = None,
) -> dict[str, Any]:
    """``target(spec)`` in a fresh interpreter: ``target`` is ``"package.module:function"``,
    ``spec`` and the dict it returns are JSON. The child runs on this process's CPUs, or on
    ``cpus``: it sets that affinity itself before it imports ``target`` (so a thread pool sized
    from the affinity, JAX's, follows it; not ``preexec_fn``, unsafe in a process that runs JAX),
    with ``env`` (default: this process's environment) in ``cwd``. Returns the child's result
    with ``process_wall_s`` (s, interpreter start to exit); ``RuntimeError`` with the end of
    its stderr when it fails."""
    code = "import sys; from experiments.processes import child_main; raise SystemExit(child_main(sys.argv[1:]))"
    args = [target, json.dumps(dict(spec)), json.dumps(None if cpus is None else sorted(cpus))]
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=cwd,
        env=None if env is None else dict(env),
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    wall = time.perf_counter() - start
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_PREFIX)]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"child {target} failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    return {**json.loads(lines[-1][len(RESULT_PREFIX) :]), "process_wall_s": wall}


def child_main(argv: Sequence[str]) -> int:
    """The interpreter :func:`run_in_child` starts: ``argv`` is the target, the spec (JSON) and
    the CPUs (JSON list, or null); prints the target's result on one line of stdout."""
    target, spec, cpus = argv[0], json.loads(argv[1]), json.loads(argv[2])
    if cpus is not None:  # before the target's imports start a thread pool
        os.sched_setaffinity(0, set(cpus))
    module, _, name = target.partition(":")
    result = getattr(importlib.import_module(module), name)(spec)
    print(RESULT_PREFIX + json.dumps(result), flush=True)
    return 0
