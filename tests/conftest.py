import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)

# Campaigns in tests take J* from the shipped table or the solver's cache only (solving each
# test campaign's episodes would add minutes); tests that solve say so in their config.
# Set at import so module- and session-scoped fixtures and subprocesses see it too.
os.environ.setdefault("ATTITUDE_ENVS_OPTIMUM_SOLVE", "0")

# JAX's persistent compilation cache, one per test session (set before anything imports jax, so
# in-process jax and every subprocess see it): a run that builds the same SBX model as an earlier
# one, in this process or in a `train` subprocess (a resumed run, a campaign's run), loads the
# compiled XLA programs instead of compiling them again (~60 programs, half of an SBX run's CPU
# time). The programs are the same, so are the numbers. Every compile is cached (JAX's default
# keeps only those over 1 s).
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="attitude-envs-tests-jax-cache-")
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    _owner, _cache = os.getpid(), os.environ["JAX_COMPILATION_CACHE_DIR"]
    atexit.register(lambda: os.getpid() == _owner and shutil.rmtree(_cache, ignore_errors=True))  # not forked children


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def asymmetric_inertia() -> np.ndarray:
    """A full (non-diagonal) inertia tensor meeting the triangle inequality, kg·m²."""
    return np.array([[4.0, 0.1, -0.05], [0.1, 3.5, 0.08], [-0.05, 0.08, 3.0]])
