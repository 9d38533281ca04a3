"""Quaternion and rotation helpers, scalar-last ``[x, y, z, w]`` everywhere.

The convention matches :class:`scipy.spatial.transform.Rotation`: a quaternion ``q``
maps body-frame vectors to the inertial frame, ``v_I = R(q) v_B``. Kinematics are
``q̇ = ½ q ⊗ [ω, 0]`` with ``ω`` the body rate in body axes (the feedback-linearization paper, eq. 3).
"""

from __future__ import annotations

import math

import numpy as np


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` of scalar-last quaternions."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array(
        [
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz,
        ]
    )


def conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion)."""
    return np.array([-q[0], -q[1], -q[2], q[3]])


def error(q: np.ndarray, q_target: np.ndarray) -> np.ndarray:
    """Attitude of the body relative to the target, ``q_e = q_T* ⊗ q``, sign with w ≥ 0.

    ``q_e = [0, 0, 0, 1]`` at the target; its vector part obeys ``d/dt q_e,vec = ½ ω``
    near the target, which is the linear model of Heravi & Novinzadeh 2017, eq. 58. The
    feedback-linearization paper's ``q_E = q_S* ⊗ q_T`` (its eq. 61) is the conjugate:
    ``q_E,vec = -q_e,vec``.
    """
    qe = multiply(conjugate(q_target), q)
    return -qe if qe[3] < 0.0 else qe


def error_angle_rad(q: np.ndarray, q_target: np.ndarray) -> float:
    """Eigen-axis angle between attitude and target, rad, in [0, π] (the feedback-linearization paper, eq. 13)."""
    qe = multiply(conjugate(q_target), q)
    return float(2.0 * np.arccos(min(1.0, abs(qe[3]))))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for 3-vectors without ``np.cross``'s overhead (hot paths: per-step controllers)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(a) @ b == a × b``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (body → inertial) of a unit quaternion."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _norm(v: np.ndarray) -> float:
    """``np.linalg.norm`` of a float vector (the same ``sqrt(v·v)``) without its overhead."""
    return math.sqrt(v.dot(v))


def from_axis_angle(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle_rad`` about the unit ``axis``."""
    axis = np.asarray(axis, dtype=float)
    half = 0.5 * angle_rad
    q = np.empty(4)
    q[:3] = np.sin(half) * axis / _norm(axis)
    q[3] = np.cos(half)
    return q


def from_euler_321_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Quaternion of 3-2-1 Euler angles (yaw ψ about z, then pitch θ, then roll φ), degrees.

    Equals ``Rotation.from_euler('ZYX', [ψ, θ, φ], degrees=True).as_quat()`` (as for the targets of the feedback-linearization paper's Table 1).
    """
    return from_euler_321_half_angles(*(np.radians([roll_deg, pitch_deg, yaw_deg]) * 0.5))


def from_euler_321_half_angles(phi, theta, psi, xp=np):
    """The quaternion of 3-2-1 Euler half-angles ``φ/2, θ/2, ψ/2`` (rad) in the array namespace
    ``xp`` (numpy, ``jax.numpy``): the one formula of :func:`from_euler_321_deg` and the JAX
    plants' start attitudes."""
    sf, cf, st, ct, sp, cp = xp.sin(phi), xp.cos(phi), xp.sin(theta), xp.cos(theta), xp.sin(psi), xp.cos(psi)
    return xp.stack(
        [
            sf * ct * cp - cf * st * sp,
            cf * st * cp + sf * ct * sp,
            cf * ct * sp - sf * st * cp,
            cf * ct * cp + sf * st * sp,
        ]
    )


def to_euler_321_deg(q: np.ndarray) -> np.ndarray:
    """3-2-1 Euler angles ``[roll φ, pitch θ, yaw ψ]`` in degrees of a unit quaternion."""
    x, y, z, w = q
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.degrees([roll, pitch, yaw])


def random_within_angle(rng: np.random.Generator, max_angle_deg: float) -> np.ndarray:
    """Rotation about a uniformly random axis by an angle uniform in [0, max_angle_deg]."""
    axis = rng.normal(size=3)
    while _norm(axis) < 1e-9:  # pragma: no cover - measure-zero event
        axis = rng.normal(size=3)
    angle = np.radians(rng.uniform(0.0, max_angle_deg))
    return from_axis_angle(axis, angle)


def from_rotvec(v: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation vector ``v`` (axis × angle, rad): ``exp(v / 2)``."""
    v = np.asarray(v, dtype=float)
    angle = float(np.sqrt(v @ v))
    if angle < 1e-8:  # second-order series, exact to rounding at this size
        q = np.concatenate([0.5 * v, [1.0 - angle * angle / 8.0]])
        return q / np.linalg.norm(q)
    return np.concatenate([np.sin(0.5 * angle) / angle * v, [np.cos(0.5 * angle)]])


def to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a unit quaternion, angle in [0, π] (sign chosen with w ≥ 0)."""
    q = np.asarray(q, dtype=float)
    if q[3] < 0.0:
        q = -q
    s = float(np.linalg.norm(q[:3]))
    if s < 1e-12:
        return 2.0 * q[:3]
    return 2.0 * np.arctan2(s, q[3]) / s * q[:3]
