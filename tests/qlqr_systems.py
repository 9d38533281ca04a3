"""Benchmark LQR instances from the learning-LQR literature (Kiumarsi et al., Krauth et al., Dean et al.) and random stabilizable systems."""

from __future__ import annotations

import numpy as np
import scipy.signal

from attitude_envs.envs.linear_system import LinearSystemEnv


def benchmark_systems() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(A, B, Q, R) of kiumarsi2x1, krauth3x2, dean3x3, kashima-free set."""
    nb3 = np.eye(3, k=1) + np.eye(3, k=-1)
    return {
        "kiumarsi2x1": (np.array([[-1.0, 2.0], [2.2, 1.7]]), np.array([[2.0], [1.6]]), np.eye(2), np.eye(1)),
        "krauth3x2": (
            0.95 * np.eye(3) + 0.01 * nb3,
            np.array([[1.0, 0.1], [0.0, 0.1], [0.0, 0.1]]),
            np.eye(3),
            np.eye(2),
        ),
        "dean3x3": (1.01 * np.eye(3) + 0.01 * nb3, np.eye(3), 1e-3 * np.eye(3), np.eye(3)),
    }


def random_system(seed: int, n: int, m: int, spectral_radius: float):
    """Random (A, B) with ρ(A) = ``spectral_radius`` (> 1: open-loop unstable), Q = I, R = I."""
    rng = np.random.default_rng(seed)
    A = rng.uniform(-1.0, 1.0, (n, n))
    A *= spectral_radius / np.max(np.abs(np.linalg.eigvals(A)))
    B = rng.uniform(-1.0, 1.0, (n, m))
    return A, B, np.eye(n), np.eye(m)


def stabilizing_gain(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """K₀ for PI: zero when A is stable, else pole placement at linspace(−0.5, 0.5, n)."""
    if np.max(np.abs(np.linalg.eigvals(A))) < 1.0:
        return np.zeros((B.shape[1], A.shape[0]))
    return scipy.signal.place_poles(A, B, np.linspace(-0.5, 0.5, A.shape[0])).gain_matrix


def linear_env(A, B, Q, R, **kwargs) -> LinearSystemEnv:
    """LinearSystem-v0 with a wide input range (no clipping in the deterministic tests)."""
    kwargs.setdefault("action_scale", 1e6)
    return LinearSystemEnv(preset=None, A=A, B=B, Q=Q, R=R, **kwargs)
