"""Argument checks shared by every env: each raises ``ValueError`` naming the parameter."""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import numpy as np


def finite_array(name: str, value, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """Return ``value`` as a float array, checking its shape and that it is finite. Strings
    are refused, numeric or not (no coercion, as Gymnasium's envs)."""
    try:
        raw = np.asarray(value)
        if raw.dtype.kind in "US" or (raw.dtype.kind == "O" and any(isinstance(v, (str, bytes)) for v in raw.flat)):
            raise ValueError("strings are not numbers")
        arr = np.asarray(raw, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric (numbers, not strings), got {value!r}") from exc
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf), got {arr.tolist()}")
    return arr


def number(name: str, value, accepted: str = "a number") -> float:
    """``value`` as a float when it is a real number (a Python or numpy int or float, or a
    0-d numeric array), else a ``ValueError`` naming ``name``, the value and what is
    ``accepted`` (e.g. ``"a number in (0, inf)"``). Booleans and strings are refused,
    numeric strings too: as Gymnasium's envs, no coercion (YAML reads ``1e-3`` as a string;
    the message says so)."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return float(value)
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        return float(value)
    hint = ""
    if isinstance(value, str):
        try:
            float(value)
            hint = f"; pass {name}={value.strip()}, a number, not a string"
            if "e" in value.lower() and "." not in value:
                hint += " (YAML reads 1e-3 as a string: write 1.0e-3)"
        except ValueError:
            pass
    raise ValueError(f"{name} must be {accepted}, got {value!r} ({type(value).__name__}){hint}")


def interval(low: float, high: float, open_low: bool = False, open_high: bool = False) -> str:
    """The interval as an error message writes it: ``[0, 1)``, ``(0, inf)`` (an infinite end is open)."""
    left = "(" if open_low or math.isinf(low) else "["
    right = ")" if open_high or math.isinf(high) else "]"
    return f"{left}{low:g}, {high:g}{right}"


def in_range(
    name: str, value, low: float = -math.inf, high: float = math.inf, *, open_low: bool = False, open_high: bool = False
) -> float:
    """A finite number in the interval from ``low`` to ``high`` (closed unless ``open_low`` /
    ``open_high``), as a float; a ``ValueError`` naming ``name``, the value and the interval."""
    accepted = interval(low, high, open_low, open_high)
    v = number(name, value, f"a number in {accepted}")
    inside = (v > low if open_low else v >= low) and (v < high if open_high else v <= high)
    if not (math.isfinite(v) and inside):
        raise ValueError(f"{name} must be in {accepted}, got {value!r}")
    return v


def positive(name: str, value: float, allow_inf: bool = False) -> float:
    """A strictly positive number (``inf`` allowed only when ``allow_inf``)."""
    accepted = "(0, inf]" if allow_inf else "(0, inf)"
    v = number(name, value, f"a number in {accepted}")
    ok = v > 0 and (allow_inf or np.isfinite(v))
    if not ok:
        raise ValueError(f"{name} must be in {accepted}, got {value!r}")
    return v


def nonnegative(name: str, value: float) -> float:
    """A finite number ≥ 0."""
    return in_range(name, value, 0.0)


def integer(name: str, value, minimum: int) -> int:
    """A whole number ≥ ``minimum`` (an int, or a float with an integral value such as
    ``1.0e3``), as an int; a ``ValueError`` naming ``name``, the value and the range."""
    accepted = f"an integer >= {minimum}"
    v = number(name, value, accepted)
    if not (math.isfinite(v) and v == int(v) and v >= minimum):
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return int(v)


def flag(name: str, value) -> bool:
    """A boolean switch: ``True``/``False`` (or a numpy bool); a ``ValueError`` naming ``name``
    otherwise (``bool("false")`` would be True)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise ValueError(f"{name} must be True or False, got {value!r} ({type(value).__name__})")


def unit_quaternion(name: str, value, tol: float = 1e-6) -> np.ndarray:
    """A scalar-last unit quaternion ``[x, y, z, w]`` (norm within ``tol`` of 1), renormalized."""
    q = finite_array(name, value, (4,))
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > tol:
        raise ValueError(f"{name} must be a unit quaternion [x, y, z, w] (|q| = 1 ± {tol}), got |q| = {norm:.9g}")
    return q / norm


def inertia(name: str, value) -> np.ndarray:
    """A physically valid inertia tensor, kg·m²: symmetric, positive definite, and whose
    principal moments satisfy the triangle inequality ``I1 + I2 ≥ I3`` (all permutations)."""
    inertia_matrix = finite_array(name, value, (3, 3))
    scale = float(np.max(np.abs(inertia_matrix)))
    if not np.allclose(inertia_matrix, inertia_matrix.T, rtol=0.0, atol=1e-12 * max(scale, 1.0)):
        raise ValueError(f"{name} must be symmetric, got {inertia_matrix.tolist()}")
    moments = np.linalg.eigvalsh(inertia_matrix)
    if moments[0] <= 0:
        raise ValueError(f"{name} must be positive definite, got principal moments {moments.tolist()}")
    if moments[0] + moments[1] < moments[2] * (1.0 - 1e-12):
        raise ValueError(
            f"{name} violates the triangle inequality of principal moments (I1 + I2 >= I3): {moments.tolist()}"
        )
    return 0.5 * (inertia_matrix + inertia_matrix.T)


def psd_matrix(name: str, value, n: int, definite: bool = False) -> np.ndarray:
    """A symmetric positive semi-definite (or definite) ``n × n`` weight matrix; a vector
    of length ``n`` or a scalar is taken as a diagonal."""
    arr = finite_array(name, value)
    if arr.ndim == 0:
        arr = np.eye(n) * float(arr)
    elif arr.ndim == 1:
        if arr.shape != (n,):
            raise ValueError(f"{name} must be a scalar, a length-{n} diagonal or an {n}x{n} matrix, got {arr.shape}")
        arr = np.diag(arr)
    if arr.shape != (n, n):
        raise ValueError(f"{name} must be {n}x{n}, got {arr.shape}")
    if not np.allclose(arr, arr.T, atol=1e-12 * max(1.0, float(np.max(np.abs(arr))))):
        raise ValueError(f"{name} must be symmetric")
    low = float(np.min(np.linalg.eigvalsh(arr))) if n else 0.0
    tol = 1e-12 * max(1.0, float(np.max(np.abs(arr)))) if n else 0.0
    if definite and low <= 0:
        raise ValueError(f"{name} must be positive definite, smallest eigenvalue {low:.3g}")
    if low < -tol:
        raise ValueError(f"{name} must be positive semi-definite, smallest eigenvalue {low:.3g}")
    return 0.5 * (arr + arr.T)


def choice(name: str, value, accepted) -> str:
    """One of a fixed set of strings."""
    if value not in accepted:
        raise ValueError(f"{name} must be one of {sorted(accepted)}, got {value!r}")
    return value


def action(value, n: int) -> np.ndarray:
    """A finite action vector of length ``n`` (normalized units), as float64. Hot path."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action must be numeric with shape ({n},), got {value!r}") from exc
    if arr.shape != (n,):
        raise ValueError(f"action must have shape ({n},), got {arr.shape}")
    # A finite sum proves every entry finite; only a non-finite sum (NaN/inf, or an
    # overflow of huge finite entries) needs the exact element-wise check.
    if not math.isfinite(arr.sum()) and not np.isfinite(arr).all():
        raise ValueError(f"action must be finite (no NaN or inf), got {arr.tolist()}")
    return arr


def known_keys(where: str, mapping, accepted) -> None:
    """Raise a ``ValueError`` naming ``where``, the unknown keys and the accepted ones."""
    unknown = set(mapping) - set(accepted)
    if unknown:
        raise ValueError(f"{where} has unknown keys {sorted(unknown)}; accepted: {sorted(accepted)}")


def mapping(name: str, value) -> dict:
    """``value`` (a mapping, or None for an empty one) as a dict; a ``ValueError`` naming
    ``name`` otherwise (``dict("x")`` would say only "dictionary update sequence element")."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{name} must be a mapping (dict) or None, got {value!r} ({type(value).__name__})")
    return dict(value)


def reset_options(options, accepted: set[str]) -> dict:
    """``reset(options=...)`` as a dict (a mapping or None), rejecting unknown keys."""
    options = mapping("reset options", options)
    known_keys("reset options", options, accepted)
    return options
