"""Compiled step of the discrete LTI plant, shared by LinearSystem-v0 and its batched env
(the same loops in the same order, so both paths give bitwise-identical trajectories)."""

from __future__ import annotations

from numba import njit

from attitude_envs.plants.ops import NUMBA, define_quad_form

quad_form = define_quad_form(NUMBA)


@njit(cache=True, error_model="numpy")
def linear_step(x, u, A, B, Q, R, out):
    """``out = A x + B u``; returns the stage cost ``xᵀQx + uᵀRu``."""
    n, m = B.shape
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += A[i, j] * x[j]
        for j in range(m):
            acc += B[i, j] * u[j]
        out[i] = acc
    return quad_form(Q, x, n) + quad_form(R, u, m)


@njit(cache=True, error_model="numpy")
def linear_step_batch(X, U, A, B, Q, R, out, costs):
    """:func:`linear_step` for every row of ``X`` and ``U``."""
    for e in range(X.shape[0]):
        costs[e] = linear_step(X[e], U[e], A, B, Q, R, out[e])
