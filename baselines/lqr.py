"""Generic LQR from an env's nominal linearization: the reference for every learner."""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.lqr import dlqr


class LQRPolicy:
    """State feedback ``u = −K x`` on the error state, ``K`` from :mod:`attitude_envs.lqr`.

    ``discretization="zoh"`` (default) designs on the exact ZOH discretization of plant
    *and* cost over the env's control period (the optimal sampled-data controller);
    ``"continuous"`` uses the continuous-time gain. ``Q`` and ``R`` default to the env's
    cost. For ``cost_input="body"`` envs the gain gives a body torque that is allocated to
    the wheels by the minimum-norm pseudo-inverse of the nominal wheel matrix.

    ``delay_steps`` (``"zoh"`` only): the command acts that many control periods late (the
    flight conditions' computation delay, :mod:`attitude_envs.conditions`); ``"env"`` takes
    the env's ``conditions.delay_steps``, a known design value. The gain is then the LQR of
    the state augmented with the commands still in flight, ``z = [x, p₁ … p_d]`` with
    ``x⁺ = A x + B p₁`` and the new command entering last, the stage cost that of the applied
    ``p₁`` (the ZOH cost's ``Q``, ``N``, ``R``) plus ``10⁻⁸ R`` on the new command so the
    Riccati equation is regular; the policy remembers its last ``d`` commands. 0 (default):
    the nominal LQR, which ignores any delay.

    Without a delay the action is ``clip(((x @ −Kᵀ) @ Tᵀ) / u_max, −1, 1)`` on the first
    ``n_state`` observation entries ``x``, with ``gain`` ``K``, ``to_motor`` ``T`` (the
    allocation, or the identity) and ``max_torque`` ``u_max`` (N·m).
    """

    def __init__(
        self, env, discretization: str = "zoh", Q=None, R=None, name: str | None = None, delay_steps: int | str = 0
    ) -> None:
        model = env.unwrapped.model
        validation.choice("discretization", discretization, {"zoh", "continuous"})
        self.name = name or f"lqr-{discretization}"
        lin = model.linearize()
        if Q is not None or R is not None:
            q_mat = lin.Q if Q is None else validation.psd_matrix("Q", Q, lin.n)
            r_mat = lin.R if R is None else validation.psd_matrix("R", R, lin.m, definite=True)
            lin = type(lin)(lin.A, lin.B, q_mat, r_mat)
        self.linear_model = lin if discretization == "continuous" else lin.discretize(model.control_dt_s)
        if delay_steps == "env":
            delay_steps = env.unwrapped.conditions.delay_steps
        self.delay_steps = validation.integer("delay_steps", delay_steps, 0)
        if self.delay_steps and discretization != "zoh":
            raise ValueError("delay_steps > 0 needs discretization='zoh' (the delay is in control periods)")
        self.gain = (
            self.linear_model.lqr_gain() if not self.delay_steps else _delay_gain(self.linear_model, self.delay_steps)
        )
        self._pending = np.zeros((self.delay_steps, lin.m))
        self.n_state = lin.n
        body_action = getattr(env.unwrapped, "action_frame", "wheel") == "body"
        if body_action and model.cost_input != "body":
            raise ValueError("action_frame='body' needs cost_input='body' for the LQR (its input is the body torque)")
        self.to_motor = model.allocation if model.cost_input == "body" and not body_action else np.eye(lin.m)
        self.max_torque = model.params.max_wheel_torque_nm

    def reset(self, seed: int | None = None) -> None:
        self._pending[:] = 0.0

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized wheel torques for one observation (n,) or a batch (E, n; without a delay)."""
        x = np.asarray(obs, dtype=float)[..., : self.n_state]
        if self.delay_steps:
            if x.ndim != 1:
                raise ValueError(
                    "a delay-compensating LQR acts on one observation at a time (it remembers its commands)"
                )
            u = -self.gain @ np.concatenate([x, self._pending.ravel()])
            self._pending = np.vstack([self._pending[1:], u])
            motor = u @ self.to_motor.T
        else:
            motor = (x @ -self.gain.T) @ self.to_motor.T
        return np.clip(motor / self.max_torque, -1.0, 1.0).astype(np.float32)


def _delay_gain(model, d: int) -> np.ndarray:
    """The LQR gain of ``model`` (discrete, ZOH cost) with its input delayed ``d`` periods, on
    ``z = [x, p₁ … p_d]`` (see :class:`LQRPolicy`)."""
    n, m = model.n, model.m
    k = n + d * m
    A = np.zeros((k, k))
    A[:n, :n] = model.A
    A[:n, n : n + m] = model.B
    for i in range(d - 1):  # p_i⁺ = p_{i+1}
        A[n + i * m : n + (i + 1) * m, n + (i + 1) * m : n + (i + 2) * m] = np.eye(m)
    B = np.zeros((k, m))
    B[n + (d - 1) * m :, :] = np.eye(m)
    Q = np.zeros((k, k))
    Q[:n, :n] = model.Q
    Q[n : n + m, n : n + m] = model.R
    if model.N is not None:
        Q[:n, n : n + m] = model.N
        Q[n : n + m, :n] = model.N.T
    return dlqr(A, B, 0.5 * (Q + Q.T), 1e-8 * model.R)[0]
