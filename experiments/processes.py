"""Worker processes that die with the process that started them.

:func:`die_with_parent` is a process-pool initializer (``initializer=die_with_parent,
initargs=(os.getpid(),)``): the worker ignores Ctrl-C (SIGINT; the parent handles it and ends
its workers) and exits when the parent process is gone, also after a SIGKILL of the parent,
which runs no clean-up. On Linux the kernel kills the worker when its parent dies
(``prctl(PR_SET_PDEATHSIG, SIGKILL)``); everywhere a watchdog thread checks every 0.25 s that
the given process still runs (a forkserver's children watch that process, not the forkserver).
Once the workers are gone, the forkserver and the resource tracker exit too.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

_PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCH_INTERVAL_S = 0.25


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
    no setting for it (see :mod:`experiments.sb3.backends`). Returns the CPU, or None where the
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
