"""Exact-resume checkpoints of a training run: everything its continuation depends on.

:func:`experiments.training.training.train` runs ``learn()`` in segments that end at rollout
boundaries (where SB3 holds no half-collected data) and checkpoints between two segments, so a
resumed run continues bitwise like an uninterrupted one. ``checkpoints/step_<n>/`` holds

* ``state.pkl``: the whole algorithm object (policy and optimizer tensors, off-policy replay
  buffer, last observations and episode starts, episode-info buffers, the action space's
  generator, action noise, update counters, schedules and their :class:`RunClock`), the
  training envs in full (every sub-env with its generator and physical state, Monitor counters,
  VecNormalize statistics and running returns), the global torch / numpy / ``random``
  generators, and the run's bookkeeping (``evaluations.csv`` up to this step, best so far);
* ``model.zip`` and ``vecnormalize.pkl``: the portable SB3 snapshot of the same model.

The directory is written under a temporary name, fsynced and renamed; only then does
``latest.json`` (fsynced, atomic rename) point at it. The pickles are tied to the installed
SB3/torch versions: they resume a run, they are not an exchange format (``model.zip`` is).
"""

from __future__ import annotations

import os
import pickle
import random
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import torch
from numba.core.dispatcher import Dispatcher
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecNormalize

from experiments.training.callbacks import new_checkpoint_dir, publish_checkpoint, write_model_files
from experiments.training.run_dir import STATE_FILE


class RunClock:
    """The run's step budget as the schedules see it.

    ``train`` calls ``learn()`` once per segment, and SB3 computes a schedule's
    ``progress_remaining`` as ``1 - n / (end of the segment)``. :meth:`progress_remaining` maps it
    back to ``1 - n / total``, bit for bit what one ``learn(total)`` call would pass."""

    def __init__(self, total: int) -> None:
        self.total = int(total)
        self.segment_end = int(total)

    def progress_remaining(self, segment_progress: float) -> float:
        steps = round((1.0 - float(segment_progress)) * self.segment_end)  # n, exactly (an integer)
        return 1.0 - steps / self.total


class BudgetSchedule:
    """A hyperparameter schedule (``lin_3e-4`` …) evaluated on the run's true progress (:class:`RunClock`)."""

    def __init__(self, schedule, clock: RunClock) -> None:
        self.schedule = schedule
        self.clock = clock

    def __call__(self, progress_remaining: float) -> float:
        return self.schedule(self.clock.progress_remaining(progress_remaining))


def capture_rng() -> dict[str, Any]:
    """The global generators SB3 draws from (torch: policy noise, gSDE; numpy: minibatch
    permutations, replay sampling; ``random``)."""
    numpy_state = np.random.get_state()  # noqa: NPY002  (SB3 draws from numpy's legacy global generator)
    state = {"python": random.getstate(), "numpy": numpy_state, "torch": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def restore_rng(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])  # noqa: NPY002  (SB3 draws from numpy's legacy global generator)
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


_DISK_CACHED_KERNEL = "numba-disk-cached"


def _source_stamp(func) -> tuple[float, int] | None:
    """``(mtime, size)`` of the file that defines ``func`` (numba's test of a stale disk cache), or None."""
    try:
        st = os.stat(func.__code__.co_filename)
    except (AttributeError, OSError):
        return None
    return st.st_mtime, st.st_size


class _RunPickler(cloudpickle.Pickler):
    """Pickles the algorithm object whole (env included, in the same pass so that objects the
    model and the env share stay shared), except its logger, which the next ``learn()`` rebuilds.

    A numba kernel compiled with ``cache=True`` (an env's batched step) keeps its disk cache:
    numba rebuilds an unpickled kernel without it, so a run resumed in a new process compiled the
    env's step again (5–25 s) instead of loading it. The kernel is pickled as numba pickles it,
    beside the stamp of its source file; :class:`_RunUnpickler` turns its cache back on when that
    file is unchanged (numba's own test: the function, its globals and so its code are the same)."""

    def persistent_id(self, obj):
        if isinstance(obj, Logger):
            return "logger"
        if isinstance(obj, Dispatcher) and obj.stats.cache_path is not None:
            data = cloudpickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
            return (_DISK_CACHED_KERNEL, _source_stamp(obj.py_func), data)
        return None


class _RunUnpickler(pickle.Unpickler):
    def persistent_load(self, pid):
        if pid == "logger":
            return None
        if isinstance(pid, tuple) and len(pid) == 3 and pid[0] == _DISK_CACHED_KERNEL:
            _, stamp, data = pid
            kernel = pickle.loads(data)  # this process's own kernel when it already has it
            if kernel.stats.cache_path is None and stamp is not None and _source_stamp(kernel.py_func) == stamp:
                try:
                    kernel.enable_caching()
                except RuntimeError:  # numba finds no cache location for the file: compile, as before
                    pass
            return kernel
        raise pickle.UnpicklingError(f"unknown persistent id {pid!r}")


def _env_state(venv) -> dict[str, Any]:
    """The training env in full. VecNormalize (the top wrapper, or under a VecFrameStack)
    pickles itself without its wrapped env and its running discounted returns (reward
    normalization), so both are saved beside it."""
    wrapper = venv
    while wrapper is not None and not isinstance(wrapper, VecNormalize):
        wrapper = getattr(wrapper, "venv", None)
    if wrapper is not None:
        return {"normalize": wrapper, "envs": wrapper.venv, "returns": np.array(wrapper.returns)}
    return {"normalize": None, "envs": venv, "returns": None}


def _restore_env(state: dict[str, Any]) -> None:
    if state["normalize"] is not None:
        state["normalize"].set_venv(state["envs"])
        state["normalize"].returns = state["returns"]


def _fsync_file(path: Path) -> None:
    with path.open("rb") as fh:
        os.fsync(fh.fileno())


def write_checkpoint(root: Path, model, clock: RunClock, run: dict[str, Any], keep: int = 2) -> Path:
    """Checkpoint ``model`` (with its env, the global generators and ``run`` bookkeeping) to
    ``root/step_<n>/``, then point ``root/latest.json`` at it; keeps the ``keep`` newest."""
    steps = int(model.num_timesteps)
    directory, tmp = new_checkpoint_dir(root, steps)
    write_model_files(model, tmp)  # portable model.zip (+ vecnormalize.pkl)
    state = {"env": _env_state(model.get_env()), "model": model, "clock": clock, "rng": capture_rng(), "run": run}
    with (tmp / STATE_FILE).open("wb") as fh:
        _RunPickler(fh, protocol=pickle.HIGHEST_PROTOCOL).dump(state)
    for path in tmp.iterdir():
        _fsync_file(path)
    return publish_checkpoint(root, tmp, directory, steps, keep)


def read_checkpoint(directory: Path) -> tuple[Any, RunClock, dict[str, Any], dict[str, Any]]:
    """``(model, clock, run, rng)`` of a checkpoint; the model has its training env back.
    Restore ``rng`` (:func:`restore_rng`) last, right before training continues."""
    path = Path(directory) / STATE_FILE
    try:
        with path.open("rb") as fh:
            state = _RunUnpickler(fh).load()
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, TypeError) as exc:
        raise ValueError(
            f"checkpoint {str(path)!r} cannot be read ({type(exc).__name__}: {exc}); it is tied to the "
            "stable-baselines3/torch versions that wrote it"
        ) from exc
    _restore_env(state["env"])  # the model's env, reconnected to its sub-envs
    return state["model"], state["clock"], state["run"], state["rng"]
