"""The stage cost's quadratic forms, summed in the compiled kernels' order (so a symbolic
step's cost agrees with the env's to rounding)."""

from __future__ import annotations

import numpy as np


def quad_form(M: np.ndarray, v: list, total=0.0):
    """``total + vᵀ M v``, accumulated row by row onto ``total`` as
    :func:`attitude_envs.plants.kernel_math.quad_form` does (zero entries skipped)."""
    for i in range(len(v)):
        acc = 0.0
        for j in range(len(v)):
            if M[i, j] != 0.0:
                acc = acc + float(M[i, j]) * v[j]
        total = total + v[i] * acc
    return total
