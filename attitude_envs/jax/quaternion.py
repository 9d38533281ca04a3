"""Scalar-last quaternions in JAX, the operations of :mod:`attitude_envs.quaternion` that the
JAX plants need (the same formulas, so the same numbers in x64)."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def multiply(p: jax.Array, q: jax.Array) -> jax.Array:
    """The Hamilton product ``p ⊗ q`` (:func:`attitude_envs.quaternion.multiply`)."""
    px, py, pz, pw = p[0], p[1], p[2], p[3]
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    return jnp.stack(
        [
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz,
        ]
    )


def from_axis_angle(axis: jax.Array, angle_rad) -> jax.Array:
    """The rotation by ``angle_rad`` about ``axis`` (any length): with a standard normal
    ``axis`` and a uniform angle, :func:`attitude_envs.quaternion.random_within_angle`'s law."""
    half = 0.5 * angle_rad
    return jnp.concatenate([jnp.sin(half) * axis / jnp.sqrt(axis @ axis), jnp.cos(half)[None]])


def from_rotvec(v: jax.Array) -> jax.Array:
    """:func:`attitude_envs.quaternion.from_rotvec` (its second-order series below 10⁻⁸ rad)."""
    angle = jnp.sqrt(v @ v)
    small = angle < 1e-8
    safe = jnp.where(small, 1.0, angle)
    series = jnp.concatenate([0.5 * v, (1.0 - angle * angle / 8.0)[None]])
    series = series / jnp.sqrt(series @ series)
    exact = jnp.concatenate([jnp.sin(0.5 * safe) / safe * v, jnp.cos(0.5 * safe)[None]])
    return jnp.where(small, series, exact)
