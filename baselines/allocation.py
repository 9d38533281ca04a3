"""Wheel-torque allocation: body torque demand → normalized wheel actions (the feedback-linearization
paper, Modares Mech. Eng., eqs. 9–12).

The nominal distribution matrix is the env's wheel-axis matrix ``A`` (3×N); the body receives
``T = −A u`` from motor torques ``u`` (see :mod:`attitude_envs.plants.gyrostat`), so the
minimum-norm allocation is ``u = −A⁺ T`` (the paper's eq. 11: the right pseudo-inverse). For the
paper's pyramid ``A⁺ = (√3/4)·[[1,1,1],[−1,1,1],[−1,−1,1],[1,−1,1]]`` (eq. 12).

Saturation awareness (``saturation=``):

* ``"scale"`` (default): if a wheel would exceed ``max_wheel_torque_nm``, first use the null
  space of ``A`` (N > 3 wheels) to minimize the largest wheel torque while keeping ``A u``
  unchanged (a small linear program); if that still exceeds the limit, scale the whole vector
  down so the body torque keeps its *direction* (the limit is met exactly on the largest wheel).
* ``"clip"``: clip each wheel independently (distorts the torque direction; what a naive
  controller gets from the env's own clipping).

The wheel-speed limit is enforced by the env's motor driver, not here.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from attitude_envs import validation

SATURATION_MODES = {"scale", "clip"}


def wheel_model(env):
    """The nominal model of a reaction-wheel env (``env.unwrapped.model`` with ``params.wheel_axes``:
    ReactionWheel-v0, AirBearing-v0); a ``ValueError`` for any other env."""
    model = getattr(env.unwrapped, "model", None)
    if not hasattr(getattr(model, "params", None), "wheel_axes"):
        raise ValueError("env must be ReactionWheel-v0 or AirBearing-v0 (a nominal model with wheel_axes)")
    return model


class WheelAllocator:
    """Maps a body torque demand (N·m, body axes) to the env's normalized wheel action.

    Built from the *nominal* model only (``env.unwrapped.model``): ``wheel_axes`` and
    ``max_wheel_torque_nm``. With ``action_frame="body"`` (an env whose action is a body
    torque demand, which the env allocates itself) :meth:`action` returns the demand
    normalized by ``max_wheel_torque_nm``.
    """

    def __init__(self, model, saturation: str = "scale", action_frame: str = "wheel") -> None:
        self.saturation = validation.choice("saturation", saturation, SATURATION_MODES)
        self.action_frame = validation.choice("action_frame", action_frame, {"wheel", "body"})
        axes = model.params.wheel_axes
        self.max_torque_nm = float(model.params.max_wheel_torque_nm)
        self.matrix = -np.linalg.pinv(axes)  # N×3, u = matrix @ T
        self._axes = axes
        self._null = scipy.linalg.null_space(axes)  # N×(N−3)
        self.saturated_calls = 0

    def motor_torque_nm(self, body_torque_nm: np.ndarray) -> np.ndarray:
        """Wheel motor torques (N·m) that deliver ``body_torque_nm`` within the torque limit;
        one demand (3,) or a batch (E, 3) → (E, N), row by row."""
        demand = np.asarray(body_torque_nm, dtype=float)
        limit = self.max_torque_nm
        if demand.ndim == 2:
            u = demand @ self.matrix.T
            peaks = np.max(np.abs(u), axis=1)
            for i in np.flatnonzero(peaks > limit):
                u[i] = self._saturated(u[i], float(peaks[i]))
            return u
        u = self.matrix @ demand
        peak = float(np.max(np.abs(u)))
        return u if peak <= limit else self._saturated(u, peak)

    def action(self, body_torque_nm: np.ndarray) -> np.ndarray:
        """Normalized action in [-1, 1] (float32) for the env; (3,) → (N,), (E, 3) → (E, N)
        (the normalized demand itself, (3,) or (E, 3), for a body-frame env)."""
        if self.action_frame == "body":
            return np.clip(np.asarray(body_torque_nm, dtype=float) / self.max_torque_nm, -1.0, 1.0).astype(np.float32)
        u = self.motor_torque_nm(body_torque_nm) / self.max_torque_nm
        return np.clip(u, -1.0, 1.0).astype(np.float32)

    def _saturated(self, u: np.ndarray, peak: float) -> np.ndarray:
        """Motor torques ``u`` whose largest magnitude ``peak`` exceeds the limit, brought within it."""
        self.saturated_calls += 1
        limit = self.max_torque_nm
        if self.saturation == "clip":
            return np.clip(u, -limit, limit)
        if self._null.shape[1] > 0:
            u = self._min_peak(u)
            peak = float(np.max(np.abs(u)))
        return u if peak <= limit else u * (limit / peak)

    @classmethod
    def for_env(cls, env, saturation: str = "scale") -> WheelAllocator:
        """The allocator for ``env``'s nominal model and action frame."""
        base = env.unwrapped
        return cls(base.model, saturation, getattr(base, "action_frame", "wheel"))

    def _min_peak(self, u0: np.ndarray) -> np.ndarray:
        """``u0 + Z c`` minimizing ``max|u|`` over the null-space coordinates ``c`` (LP)."""
        n, k = self._null.shape
        # variables [c (k), s]; minimize s subject to ±(u0 + Z c) ≤ s
        cost = np.zeros(k + 1)
        cost[-1] = 1.0
        ones = np.ones((n, 1))
        a_ub = np.vstack([np.hstack([self._null, -ones]), np.hstack([-self._null, -ones])])
        b_ub = np.concatenate([-u0, u0])
        import scipy.optimize  # only here: it costs ~1 s of every command line's start-up

        res = scipy.optimize.linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * (k + 1), method="highs")
        if not res.success:  # pragma: no cover - the LP is always feasible and bounded
            return u0
        return u0 + self._null @ res.x[:k]
