import os

import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)

# Campaigns in tests take J* from the shipped table or the solver's cache only (solving each
# test campaign's episodes would add minutes); tests that solve say so in their config.
# Set at import so module- and session-scoped fixtures and subprocesses see it too.
os.environ.setdefault("ATTITUDE_ENVS_OPTIMUM_SOLVE", "0")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def asymmetric_inertia() -> np.ndarray:
    """A full (non-diagonal) inertia tensor meeting the triangle inequality, kg·m²."""
    return np.array([[4.0, 0.1, -0.05], [0.1, 3.5, 0.08], [-0.05, 0.08, 3.0]])
