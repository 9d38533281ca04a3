"""Fixed-step integrators for the plants."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Derivative = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(f: Derivative, t: float, y: np.ndarray, h: float) -> np.ndarray:
    """One classical fourth-order Runge–Kutta step of ``ẏ = f(t, y)`` over ``h`` seconds."""
    k1 = f(t, y)
    k2 = f(t + 0.5 * h, y + 0.5 * h * k1)
    k3 = f(t + 0.5 * h, y + 0.5 * h * k2)
    k4 = f(t + h, y + h * k3)
    return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def substeps(control_dt_s: float, integrator_dt_s: float) -> int:
    """Number of integrator sub-steps per control period; the ratio must be an integer."""
    n = round(control_dt_s / integrator_dt_s)
    if n < 1 or abs(n * integrator_dt_s - control_dt_s) > 1e-9 * control_dt_s:
        raise ValueError(
            f"control_dt_s ({control_dt_s}) must be a positive integer multiple of integrator_dt_s ({integrator_dt_s})"
        )
    return n
