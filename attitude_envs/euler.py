"""3-2-1 Euler angles and their rates from scalar-last quaternions, in scalar math (hot paths).

Same convention as :func:`attitude_envs.quaternion.to_euler_321_deg` (yaw ψ about z, then
pitch θ, then roll φ; ``q`` maps body to inertial axes), without numpy's per-call overhead:
the PID baselines and AirBearing-v0's ``info`` call these every control step. The ``_batch``
variants evaluate the same expressions on the rows of arrays (batched policies).
"""

from __future__ import annotations

import math

import numpy as np


def euler_321_rad(q) -> tuple[float, float, float]:
    """``(φ, θ, ψ)`` in rad of the (normalized) quaternion ``q = [x, y, z, w]``; ψ, φ in (−π, π]."""
    x, y, z, w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    n2 = x * x + y * y + z * z + w * w
    roll = math.atan2(2.0 * (w * x + y * z), n2 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x) / n2)))
    yaw = math.atan2(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def euler_321_rates(roll_rad: float, pitch_rad: float, rate_rad_s) -> tuple[float, float, float]:
    """``(φ̇, θ̇, ψ̇)`` in rad/s from the body rate ``ω`` (rad/s), Ahangarani Farahani et al. eq. 14.

    Singular at θ = ±90° (out of reach of the air bearing's ±40° travel); raises
    ``ValueError`` within 1e-9 of it.
    """
    wx, wy, wz = float(rate_rad_s[0]), float(rate_rad_s[1]), float(rate_rad_s[2])
    sf, cf = math.sin(roll_rad), math.cos(roll_rad)
    ct = math.cos(pitch_rad)
    if abs(ct) < 1e-9:
        raise ValueError(f"pitch must be away from ±90 deg for Euler rates, got {math.degrees(pitch_rad)!r}")
    tt = math.sin(pitch_rad) / ct
    roll_dot = wx + (sf * wy + cf * wz) * tt
    pitch_dot = cf * wy - sf * wz
    yaw_dot = (sf * wy + cf * wz) / ct
    return roll_dot, pitch_dot, yaw_dot


def euler_321_rad_batch(q: np.ndarray) -> np.ndarray:
    """:func:`euler_321_rad` for the rows of ``q`` (N × 4, scalar last): N × 3 ``[φ, θ, ψ]``, rad."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    n2 = x * x + y * y + z * z + w * w
    roll = np.arctan2(2.0 * (w * x + y * z), n2 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.maximum(-1.0, np.minimum(1.0, 2.0 * (w * y - z * x) / n2)))
    yaw = np.arctan2(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1)


def euler_321_rates_batch(angles_rad: np.ndarray, rate_rad_s: np.ndarray) -> np.ndarray:
    """:func:`euler_321_rates` for the rows of ``angles_rad`` (N × 3, rad) and body rates
    ``rate_rad_s`` (N × 3, rad/s): N × 3 ``[φ̇, θ̇, ψ̇]``, rad/s; ``ValueError`` near θ = ±90°."""
    roll, pitch = angles_rad[:, 0], angles_rad[:, 1]
    wx, wy, wz = rate_rad_s[:, 0], rate_rad_s[:, 1], rate_rad_s[:, 2]
    sf, cf = np.sin(roll), np.cos(roll)
    ct = np.cos(pitch)
    if np.any(np.abs(ct) < 1e-9):
        bad = float(np.degrees(pitch[np.argmin(np.abs(ct))]))
        raise ValueError(f"pitch must be away from ±90 deg for Euler rates, got {bad!r}")
    tt = np.sin(pitch) / ct
    roll_dot = wx + (sf * wy + cf * wz) * tt
    pitch_dot = cf * wy - sf * wz
    yaw_dot = (sf * wy + cf * wz) / ct
    return np.stack([roll_dot, pitch_dot, yaw_dot], axis=1)
