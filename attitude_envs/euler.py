"""3-2-1 Euler angles and their rates from scalar-last quaternions, in scalar math (hot paths).

Same convention as :func:`attitude_envs.quaternion.to_euler_321_deg` (yaw ψ about z, then
pitch θ, then roll φ; ``q`` maps body to inertial axes), without numpy's per-call overhead:
the PID baselines and AirBearing-v0's ``info`` call these every control step.
"""

from __future__ import annotations

import math


def euler_321_rad(q) -> tuple[float, float, float]:
    """``(φ, θ, ψ)`` in rad of the (normalized) quaternion ``q = [x, y, z, w]``; ψ, φ in (−π, π]."""
    x, y, z, w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    n2 = x * x + y * y + z * z + w * w
    roll = math.atan2(2.0 * (w * x + y * z), n2 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x) / n2)))
    yaw = math.atan2(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def euler_321_rates(roll_rad: float, pitch_rad: float, rate_rad_s) -> tuple[float, float, float]:
    """``(φ̇, θ̇, ψ̇)`` in rad/s from the body rate ``ω`` (rad/s), spec 003 eq. 14.

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
