import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def asymmetric_inertia() -> np.ndarray:
    """A full (non-diagonal) inertia tensor meeting the triangle inequality, kg·m²."""
    return np.array([[4.0, 0.1, -0.05], [0.1, 3.5, 0.08], [-0.05, 0.08, 3.0]])
