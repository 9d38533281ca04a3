"""Generic LQR from an env's nominal linearization: the reference for every learner."""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import validation


class LQRPolicy:
    """State feedback ``u = −K x`` on the error state, ``K`` from :mod:`attitude_envs.lqr`.

    ``discretization="zoh"`` (default) designs on the exact ZOH discretization of plant
    *and* cost over the env's control period (the optimal sampled-data controller);
    ``"continuous"`` uses the continuous-time gain. ``Q`` and ``R`` default to the env's
    cost. For ``cost_input="body"`` envs the gain gives a body torque that is allocated to
    the wheels by the minimum-norm pseudo-inverse of the nominal wheel matrix.
    """

    def __init__(self, env, discretization: str = "zoh", Q=None, R=None, name: str | None = None) -> None:
        model = env.unwrapped.model
        validation.choice("discretization", discretization, {"zoh", "continuous"})
        self.name = name or f"lqr-{discretization}"
        lin = model.linearize()
        if Q is not None or R is not None:
            q_mat = lin.Q if Q is None else validation.psd_matrix("Q", Q, lin.n)
            r_mat = lin.R if R is None else validation.psd_matrix("R", R, lin.m, definite=True)
            lin = type(lin)(lin.A, lin.B, q_mat, r_mat)
        self.linear_model = lin if discretization == "continuous" else lin.discretize(model.control_dt_s)
        self.gain = self.linear_model.lqr_gain()
        self._n = lin.n
        body_action = getattr(env.unwrapped, "action_frame", "wheel") == "body"
        if body_action and model.cost_input != "body":
            raise ValueError("action_frame='body' needs cost_input='body' for the LQR (its input is the body torque)")
        self._to_motor = model.allocation if model.cost_input == "body" and not body_action else np.eye(lin.m)
        self._max_torque = model.params.max_wheel_torque_nm

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized wheel torques for one observation (n,) or a batch (E, n)."""
        x = np.asarray(obs, dtype=float)[..., : self._n]
        motor = (x @ -self.gain.T) @ self._to_motor.T
        return np.clip(motor / self._max_torque, -1.0, 1.0).astype(np.float32)
