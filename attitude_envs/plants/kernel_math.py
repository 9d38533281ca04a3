"""Small compiled helpers shared by the plants' kernels."""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy")
def quad_form(M, v, n):
    """``vᵀ M v`` over the first ``n`` entries of ``v`` (row-by-row summation order)."""
    total = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += M[i, j] * v[j]
        total += v[i] * acc
    return total
