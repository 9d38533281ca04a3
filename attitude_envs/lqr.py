"""Infinite-horizon linear-quadratic regulators: the one place the algebraic Riccati
equations are solved.

Both functions follow python-control's ``lqr`` / ``dlqr``: they return ``(K, S, E)``, the
gain of the state feedback ``u = −K x``, the solution ``S`` of the Riccati equation (the
optimal cost-to-go is ``xᵀSx``) and the closed-loop eigenvalues ``E = eig(A − BK)``. The
cost has the cross term ``N``: ``xᵀQx + 2xᵀNu + uᵀRu``. The Riccati equations are solved by
scipy (:func:`scipy.linalg.solve_continuous_are`, :func:`scipy.linalg.solve_discrete_are`).

The inputs are checked once, each failure a ``ValueError`` naming the argument: ``A``
square, ``B`` with as many rows as ``A``, ``Q`` (n×n) and ``R`` (m×m) symmetric (a relative
asymmetry up to 1e-10 is symmetrized away), ``R`` positive definite, ``N`` n×m, all finite.
A problem with no stabilizing solution (``(A, B)`` not stabilizable, or a mode of ``A`` on
the stability boundary that the cost does not see) is a ``ValueError`` that says so.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from attitude_envs import validation

_SYMMETRY_RTOL = 1e-10


def lqr(A, B, Q, R, N=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time LQR of ``ẋ = Ax + Bu`` minimizing ``∫ (xᵀQx + 2xᵀNu + uᵀRu) dt``.

    Returns ``(K, S, E)``: ``K = R⁻¹(BᵀS + Nᵀ)`` (m×n, ``u = −Kx``), ``S`` (n×n) the
    stabilizing solution of ``AᵀS + SA − (SB + N)R⁻¹(BᵀS + Nᵀ) + Q = 0``, and ``E`` (n,
    complex) the eigenvalues of ``A − BK``, all in the open left half-plane. ``N=None`` is
    no cross term.
    """
    A, B, Q, R, N = _problem(A, B, Q, R, N)
    try:
        S = scipy.linalg.solve_continuous_are(A, B, Q, R, s=N)
    except np.linalg.LinAlgError as err:
        raise _no_stabilizing_solution("continuous", "the imaginary axis", err) from err
    K = np.linalg.solve(R, B.T @ S + N.T)
    E = np.linalg.eigvals(A - B @ K).astype(complex)
    if not (np.all(np.isfinite(S)) and np.all(E.real < 0.0)):
        raise _no_stabilizing_solution("continuous", "the imaginary axis", f"closed-loop eigenvalues {E}")
    return K, S, E


def dlqr(A, B, Q, R, N=None, discount: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete-time LQR of ``x⁺ = Ax + Bu`` minimizing ``Σₖ γᵏ (xₖᵀQxₖ + 2xₖᵀNuₖ + uₖᵀRuₖ)``
    with ``γ = discount`` in (0, 1].

    Returns ``(K, S, E)``: ``K = (R + γBᵀSB)⁻¹(γBᵀSA + Nᵀ)`` (m×n, ``u = −Kx``), ``S`` (n×n)
    the stabilizing solution of the Riccati equation of the scaled system ``(√γA, √γB)`` —
    the discounted problem is that undiscounted one — and ``E`` (n, complex) the eigenvalues
    of ``A − BK``, the plant's closed loop. With ``γ = 1`` they lie inside the unit circle;
    with ``γ < 1`` only ``√γ·E`` is guaranteed to (``|E| < 1/√γ``). ``N=None`` is no cross term.
    """
    A, B, Q, R, N = _problem(A, B, Q, R, N)
    gamma = _discount(discount)
    g = np.sqrt(gamma)
    where = "the unit circle" + ("" if gamma == 1.0 else f" (of the system scaled by sqrt(discount) = {g:.6g})")
    try:
        S = scipy.linalg.solve_discrete_are(g * A, g * B, Q, R, s=N)
    except np.linalg.LinAlgError as err:
        raise _no_stabilizing_solution("discrete", where, err) from err
    K = np.linalg.solve(R + gamma * B.T @ S @ B, gamma * B.T @ S @ A + N.T)
    E = np.linalg.eigvals(A - B @ K).astype(complex)
    if not (np.all(np.isfinite(S)) and np.all(g * np.abs(E) < 1.0)):
        raise _no_stabilizing_solution("discrete", where, f"closed-loop eigenvalues {E}")
    return K, S, E


def _problem(A, B, Q, R, N):
    """The checked float arrays ``(A, B, Q, R, N)``; ``N=None`` becomes zeros."""
    A = _matrix("A", A)
    n = A.shape[0]
    if A.shape != (n, n) or n == 0:
        raise ValueError(f"A must be a non-empty square matrix (n x n), got shape {A.shape}")
    B = _matrix("B", B)
    if B.shape[0] != n or B.shape[1] == 0:
        raise ValueError(f"B must be n x m with n = {n} rows (as A) and m >= 1 columns, got shape {B.shape}")
    m = B.shape[1]
    Q = _symmetric("Q", Q, n)
    R = _symmetric("R", R, m)
    eig_r = np.linalg.eigvalsh(R)
    if eig_r[0] <= 0.0 or eig_r[0] <= np.finfo(float).eps * eig_r[-1]:  # scipy's test of a singular R
        raise ValueError(f"R must be positive definite, got eigenvalues from {eig_r[0]:.6g} to {eig_r[-1]:.6g}")
    if N is None:
        N = np.zeros((n, m))
    else:
        N = _matrix("N", N)
        if N.shape != (n, m):
            raise ValueError(f"N must be n x m = {n} x {m} (rows of A, columns of B), got shape {N.shape}")
    return A, B, Q, R, N


def _discount(value) -> float:
    """The discount factor γ, a real number in (0, 1]."""
    try:
        if isinstance(value, (str, bytes, bool, np.bool_)) or np.ndim(value) != 0 or np.iscomplexobj(value):
            raise TypeError
        gamma = float(value)
    except (TypeError, ValueError) as err:
        raise ValueError(f"discount must be a number in (0, 1], got {value!r}") from err
    if not 0.0 < gamma <= 1.0:
        raise ValueError(f"discount must be in (0, 1], got {value!r}")
    return gamma


def _matrix(name: str, value) -> np.ndarray:
    """A finite real 2-D float array (a scalar is 1×1)."""
    if np.iscomplexobj(value):
        raise ValueError(f"{name} must be real, got a complex array")
    arr = validation.finite_array(name, value)
    if arr.ndim == 0:
        return arr.reshape(1, 1)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    return arr


def _symmetric(name: str, value, size: int) -> np.ndarray:
    """A finite symmetric ``size × size`` matrix; an asymmetry within the relative tolerance
    is averaged away (an exactly symmetric matrix comes back unchanged)."""
    arr = _matrix(name, value)
    if arr.shape != (size, size):
        raise ValueError(f"{name} must be {size} x {size}, got shape {arr.shape}")
    asymmetry = float(np.max(np.abs(arr - arr.T)))
    if asymmetry > _SYMMETRY_RTOL * float(np.max(np.abs(arr))):
        raise ValueError(f"{name} must be symmetric, got max |{name} - {name}ᵀ| = {asymmetry:.3g}")
    return 0.5 * (arr + arr.T)


def _no_stabilizing_solution(kind: str, boundary: str, detail) -> ValueError:
    return ValueError(
        f"the {kind}-time Riccati equation has no stabilizing solution: (A, B) must be stabilizable and no mode "
        f"of A on {boundary} may be unobservable in the cost (Q - N R⁻¹ Nᵀ); {detail}"
    )
