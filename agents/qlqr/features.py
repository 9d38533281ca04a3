"""Orthonormal quadratic features: ``zᵀHz = φ(z)ᵀ svec(H)``.

``svec`` stacks the upper triangle of a symmetric d×d matrix row by row, with √2 on the
off-diagonal entries, so ``H ↔ θ`` is an isometry in the Frobenius norm and
``φ(z) = svec(zzᵀ)`` has p = d(d+1)/2 entries. (Heravi & Novinzadeh 2017's basis, eq. 21, stores
``2H_ij`` without the √2; it is the same space, worse scaled.)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

SQRT2 = float(np.sqrt(2.0))


def n_features(d: int) -> int:
    """``p = d(d+1)/2`` unknowns of a symmetric d×d kernel."""
    return d * (d + 1) // 2


@lru_cache(maxsize=64)
def _indices(d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    i, j = np.triu_indices(d)
    weight = np.where(i == j, 1.0, SQRT2)
    return i, j, weight


def svec(H: np.ndarray) -> np.ndarray:
    """Orthonormal half-vectorization of a symmetric matrix (uses the upper triangle)."""
    i, j, w = _indices(H.shape[0])
    return H[i, j] * w


def smat(theta: np.ndarray, d: int) -> np.ndarray:
    """Inverse of :func:`svec`: the symmetric d×d matrix with ``svec(H) = theta``."""
    i, j, w = _indices(d)
    H = np.zeros((d, d))
    H[i, j] = theta / w
    H[j, i] = H[i, j]
    return H


def quadratic_features(Z: np.ndarray) -> np.ndarray:
    """Rows ``φ(z_k) = svec(z_k z_kᵀ)`` for the rows ``z_k`` of ``Z`` (N×d → N×p)."""
    Z = np.atleast_2d(Z)
    i, j, w = _indices(Z.shape[1])
    return Z[:, i] * Z[:, j] * w
