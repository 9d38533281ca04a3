"""The operation set a plant definition is written against, and the executors that provide it.

A plant's equations of motion, error state, stage cost and limit checks are written once, as
plain Python on scalars and indexable sequences, inside a ``define(ops)`` factory that takes
its few non-arithmetic operations from an :class:`Ops`. The same source then runs as

* compiled numba code (:data:`NUMBA`: ``math`` functions, every helper ``njit``-ed, cached),
  the CPU hot path the envs' kernels call;
* plain numpy (:data:`NUMPY`): vectorized over a batch when each entry is an array, or
  plain Python on floats (:data:`PYTHON`), for a few scalars called from Python code;
* traced ``jax.numpy`` (``attitude_envs.jax.ops.JAX``) for the JAX twins;
* CasADi expressions (``attitude_envs.symbolic.ops.CASADI``) for J*, the MPC and Jacobians.

Arithmetic (``+ − × /``, unary minus, comparisons for ``where``) and integer indexing are
what every executor shares; a definition uses nothing else except the members below. The
order of operations is the definition's, so every executor rounds as the others do (XLA may
still fuse ``a·b + c`` into an FMA: JAX agrees to ulps, the others bit for bit).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit


def _identity(fn: Callable) -> Callable:
    return fn


@dataclass(frozen=True)
class Ops:
    """The non-arithmetic operations of a plant definition.

    ``sin``, ``cos``, ``sqrt``, ``fabs``, ``asin`` act on one scalar (or elementwise);
    ``where(c, a, b)`` selects elementwise; ``fmin``, ``fmax`` (the smaller, the larger of
    two), ``round`` (to the nearest integer, half to even) and ``sign`` (−1, 0 or 1) act
    elementwise; ``compile`` wraps each helper a definition defines, so helpers can call each
    other (``numba.njit`` for numba, the identity for the tracing executors)."""

    name: str
    sin: Callable
    cos: Callable
    sqrt: Callable
    fabs: Callable
    asin: Callable
    where: Callable
    fmin: Callable
    fmax: Callable
    round: Callable
    sign: Callable
    compile: Callable[[Callable], Callable] = _identity


@njit(cache=True, error_model="numpy", inline="always")
def _select(condition, a, b):
    return a if condition else b


#: compiled numba: ``math`` on float64 scalars, helpers ``njit(cache=True, error_model="numpy",
#: inline="always")`` (inlined into the kernels that call them, so their loops vectorize)
NUMBA = Ops(
    "numba",
    sin=math.sin,
    cos=math.cos,
    sqrt=math.sqrt,
    fabs=math.fabs,
    asin=math.asin,
    where=_select,
    fmin=np.minimum,
    fmax=np.maximum,
    round=np.round,
    sign=np.sign,
    compile=njit(cache=True, error_model="numpy", inline="always"),
)


#: each operation's name in the array namespaces (numpy, ``jax.numpy``) and in CasADi (None: it
#: has none); an operation added to :class:`Ops` gets its row here
LIBRARY_NAMES = {
    "sin": ("sin", "sin"),
    "cos": ("cos", "cos"),
    "sqrt": ("sqrt", "sqrt"),
    "fabs": ("abs", "fabs"),
    "asin": ("arcsin", "asin"),
    "where": ("where", "if_else"),
    "fmin": ("minimum", "fmin"),
    "fmax": ("maximum", "fmax"),
    "round": ("round", None),
    "sign": ("sign", "sign"),
}


def library_ops(name: str, module, library: str = "array", **given: Callable) -> Ops:
    """The executor that takes its operations from ``module`` by their :data:`LIBRARY_NAMES`
    (``library``: ``"array"`` for numpy's names, ``"casadi"``), uncompiled (a tracing library
    traces the helpers); ``given`` supplies or replaces operations by member name."""
    libraries = ("array", "casadi")
    if library not in libraries:
        raise ValueError(f"library must be one of {list(libraries)}, got {library!r}")
    column = libraries.index(library)
    members = {op: given[op] if op in given else getattr(module, names[column]) for op, names in LIBRARY_NAMES.items()}
    return Ops(name, **members)


#: plain numpy, uncompiled: vectorized when the entries are arrays (a batch along the last axis)
NUMPY = library_ops("numpy", np)


#: plain Python on floats, uncompiled: the cheapest for a few scalars per call from Python code
PYTHON = Ops(
    "python",
    sin=math.sin,
    cos=math.cos,
    sqrt=math.sqrt,
    fabs=math.fabs,
    asin=math.asin,
    where=_select.py_func,
    fmin=lambda a, b: a if a != a or a <= b else b,  # NaN propagates, as np.minimum
    fmax=lambda a, b: a if a != a or a >= b else b,
    round=lambda x: float(round(x)) if math.isfinite(x) else x,
    sign=lambda x: 1.0 if x > 0 else -1.0 if x < 0 else x * 0.0,  # NaN stays NaN, as np.sign
)


def define_quad_form(ops: Ops) -> Callable:
    """``quad_form(M, v, n, total=0.0)``: ``total + vᵀ M v`` over the first ``n`` entries of
    ``v``, summed row by row onto ``total`` (``Σ_i v_i (Σ_j M_ij v_j)``, each row's sum from
    0.0), the one summation order of every stage cost. ``M`` is indexed ``M[i, j]``; ``v`` is
    any indexable of scalars."""

    @ops.compile
    def quad_form(M, v, n, total=0.0):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += M[i, j] * v[j]
            total += v[i] * acc
        return total

    return quad_form
