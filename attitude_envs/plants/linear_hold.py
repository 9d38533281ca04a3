"""A discrete LTI plant and its quadratic stage cost over ``k`` steps of a held input: the
decision-period model of LinearSystem-v0 (``control_dt_s = k · dt_s``) and its compiled
steps, shared by the single and the batched env (the same loops in the same order, so both
give bitwise-identical trajectories).

With the input ``u`` held over ``k`` steps of ``x⁺ = A x + B u`` the state after ``j`` steps is
``x_j = Aʲ x + (Σ_{i<j} Aⁱ) B u``, an exact discretization (no approximation beyond rounding)
of the model to the period ``k · dt_s``:

* ``x_k = A_k x + B_k u`` with ``A_k = Aᵏ`` and ``B_k = (Σ_{i<k} Aⁱ) B``;
* ``Σ_{j<k} ℓ(x_j, u) = xᵀQ_k x + 2 xᵀN_k u + uᵀR_k u`` for the stage cost
  ``ℓ(x, u) = xᵀQx + 2xᵀNu + uᵀRu``.

Both follow from the augmented state ``z = (x, u)`` with ``z⁺ = F z``,
``F = [[A, B], [0, I]]``: ``Fᵏ = [[Aᵏ, B_k], [0, I]]`` and
``[[Q_k, N_k], [N_kᵀ, R_k]] = Σ_{j<k} (Fʲ)ᵀ W Fʲ`` with ``W = [[Q, N], [Nᵀ, R]]`` — the
discrete counterpart of Van Loan's (1978) integral for the continuous-time cost
(:func:`attitude_envs.linearization.zoh_cost`). The sum is taken by repeated doubling
(``S_{a+b} = S_a + (Fᵃ)ᵀ S_b Fᵃ``, ``O(log k)`` matrix products).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from attitude_envs.linearization import LinearModel
from attitude_envs.plants.linear_kernels import linear_step


def held_sums(F: np.ndarray, W: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``(Fᵏ, Σ_{j<k} (Fʲ)ᵀ W Fʲ)`` for a square ``F`` and ``W`` of its size, ``k ≥ 1``, by
    binary decomposition of ``k`` (``O(log k)`` products; ``k = 1`` gives ``(F, W)`` exactly)."""
    if k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    size = F.shape[0]
    power, total = np.eye(size), np.zeros((size, size))  # the first c steps: Fᶜ and its sum (c = 0)
    base_power, base_total = F.copy(), W.copy()  # a block of b = 2ⁱ steps
    first = True
    while k:
        if k & 1:
            if first:  # c = 0: the block itself (k = 1 returns F, W unchanged)
                power, total = base_power.copy(), base_total.copy()
                first = False
            else:  # steps c..c+b−1: (Fᶜ)ᵀ (Σ_{i<b} (Fⁱ)ᵀ W Fⁱ) Fᶜ
                total = total + power.T @ base_total @ power
                power = base_power @ power
        k >>= 1
        if k:
            base_total = base_total + base_power.T @ base_total @ base_power
            base_power = base_power @ base_power
    return power, total


def hold_model(model: LinearModel, k: int) -> LinearModel:
    """The discrete ``model`` (period ``dt_s``) with its input held over ``k`` steps: a
    :class:`LinearModel` of period ``k · dt_s`` s with ``A_k = Aᵏ``, ``B_k = (Σ_{i<k} Aⁱ) B``
    and the exact cost weights ``Q_k``, ``R_k``, ``N_k`` of the sum of the ``k`` steps' stage
    costs (module docstring). ``k = 1`` returns ``model`` itself."""
    if model.dt_s is None:
        raise ValueError("hold_model needs a discrete model (dt_s set), got a continuous one")
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    k = int(k)
    if k == 1:
        return model
    n, m = model.n, model.m
    F = np.zeros((n + m, n + m))
    F[:n, :n] = model.A
    F[:n, n:] = model.B
    F[n:, n:] = np.eye(m)
    W = np.zeros((n + m, n + m))
    W[:n, :n] = model.Q
    W[n:, n:] = model.R
    if model.N is not None:
        W[:n, n:] = model.N
        W[n:, :n] = np.asarray(model.N).T
    power, total = held_sums(F, W, k)
    total = 0.5 * (total + total.T)  # exactly symmetric (the sum is, up to rounding)
    return LinearModel(
        power[:n, :n].copy(),
        power[:n, n:].copy(),
        total[:n, :n].copy(),
        total[n:, n:].copy(),
        total[:n, n:].copy(),
        k * model.dt_s,
    )


@njit(cache=True, error_model="numpy")
def held_step(x, u, A, B, Q, N, R, out):
    """``out = A x + B u``; returns ``xᵀQx + 2xᵀNu + uᵀRu`` (the decision-period model's
    matrices of :func:`hold_model`): the single step's arithmetic plus the cross term."""
    n, m = B.shape
    cross = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += N[i, j] * u[j]
        cross += x[i] * acc
    return linear_step(x, u, A, B, Q, R, out) + 2.0 * cross


@njit(cache=True, error_model="numpy")
def held_step_batch(X, U, A, B, Q, N, R, out, costs):
    """:func:`held_step` for every row of ``X`` and ``U``."""
    for e in range(X.shape[0]):
        costs[e] = held_step(X[e], U[e], A, B, Q, N, R, out[e])


@njit(cache=True, error_model="numpy")
def noisy_held_steps(x, u, A, B, Q, R, noise, out):
    """``k = len(noise)`` steps ``x⁺ = A x + B u + noise[j]`` of the model at ``dt_s`` with
    ``u`` held; ``out`` the last state. Returns the summed stage costs ``Σ_j (x_jᵀQx_j +
    uᵀRu)``. Each step is the arithmetic of the single step
    (:func:`attitude_envs.plants.linear_kernels.linear_step`, then ``+ noise[j]``), so the
    result is bitwise that of ``k`` single steps with the same draws."""
    cur = x.copy()
    total = 0.0
    for s in range(noise.shape[0]):
        total += linear_step(cur, u, A, B, Q, R, out)
        for i in range(cur.shape[0]):
            out[i] = out[i] + noise[s, i]
            cur[i] = out[i]
    return total
