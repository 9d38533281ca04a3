"""Constrained nonlinear MPC of ConstrainedSlew-v0 (:mod:`attitude_envs.envs.constrained_slew`):
the gyrostat MPC of :mod:`baselines.mpc` with the env's path constraints.

At every control step the policy solves :class:`~baselines.mpc.MPCPolicy`'s problem (the
nominal gyrostat's step and the env's step cost, the LQR's Riccati matrix as terminal cost,
the per-wheel torque limit of the body action frame) with, at every predicted state
``y_1 … y_N``, the rows of J*'s problem (:mod:`attitude_envs.symbolic.constrained_slew`,
:func:`~attitude_envs.symbolic.constrained_slew.cone_row` and
:func:`~attitude_envs.symbolic.constrained_slew.limit_rows`, each ``≤ 0``):

* one row per keep-out cone slot, ``cos θ − cos α + b`` with ``cos θ = d · (R(q) b_s)``;
* the body-rate limit per axis and sign, ``(±ω_k − L_ω) / L_ω + b``;
* the wheel-speed limit per wheel and sign, ``(±Ω_i − L_Ω) / L_Ω + b``;

``b`` the same back-off as J*'s (:func:`~attitude_envs.symbolic.constrained_slew.backoff`:
1e-6 in the lab). The solver is built once for the env: the cones are NLP parameters, one
slot per :data:`~attitude_envs.envs.constrained_slew.CONE_KINDS` entry (its boresight a
constant of the env), each step's inertial direction ``d = R(q̂) s_B`` from the observation's
cone block (``s_B`` the direction in body axes, ``q̂`` the measured attitude) and ``cos α``
from the same block; an inactive slot is ``d = 0``, ``cos α = 1`` (a constant row). This is
state-constrained receding-horizon control with a terminal cost and no terminal constraint
(Rawlings, Mayne & Diehl 2017, ch. 2; Mayne et al. 2000): no recursive-feasibility guarantee,
but on the lab's exact model a solved plan stays feasible when followed, which the policy uses:
when IPOPT does not finish (a failed or iteration-limited solve) the policy plays the next
action of its last solved plan (shifted once per step, while it lasts; :attr:`held_steps`
counts them), and only without one falls back to :class:`~baselines.mpc.MPCPolicy`'s (the
iterate if finite, else the LQR's action).

Warm start: the previous solution shifted by one step (:class:`~baselines.mpc.MPCPolicy`); the
first step of an episode from the rate-limited eigenaxis slew's rollout on the model
(:class:`baselines.cbf.EigenaxisSlewPolicy`, the cones ignored), which, unlike the LQR's,
keeps the body-rate limit. Requires CasADi (``pip install 'attitude-envs[optimal]'``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.envs.constrained_slew import CONE_FEATURES, CONE_KINDS, MAX_CONES
from attitude_envs.symbolic import constrained_slew as cs
from baselines.cbf import EigenaxisSlewPolicy
from baselines.measured import MeasuredState
from baselines.mpc import MPCPolicy, shifted

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the MPC baseline needs CasADi: pip install 'attitude-envs[optimal]'") from exc

__all__ = ["ConstrainedSlewMPCPolicy"]

#: the parameters of one cone slot: the inertial direction (3) and cos α
_SLOT = 4


class ConstrainedSlewMPCPolicy(MPCPolicy):
    """Nonlinear MPC with ConstrainedSlew-v0's keep-out cones, body-rate and wheel-speed limits
    as path constraints (see the module).

    Parameters: :class:`~baselines.mpc.MPCPolicy`'s (``horizon_steps`` N, ``max_iter``, ``tol``,
    ``solver_options``, ``model_substeps``, ``name``); ``backoff``: the back-off of every
    appended row (None: J*'s, :func:`attitude_envs.symbolic.constrained_slew.backoff`);
    ``constr_viol_tol``: IPOPT's (default 1e-9, below the back-off, so that a solved plan keeps
    every row ``≤ 0`` to the env's check); ``replan_steps``: env steps per solve, the plan's
    actions played open loop in between (1: a solve every step).

    Defaults: a 15 s look-ahead (N = 30 at the env's 0.5 s), two RK4 sub-steps of 0.25 s per
    control period in the prediction model (``model_substeps=2``: 2/5 of the NLP's evaluation
    time of the env's five; its one-step prediction differs from the env's by at most 8e-8 in
    the attitude matrix and 5e-8 of the rate limit over random states and actions within the
    limits, measured, well inside the 1e-6 back-off, where one sub-step differs by 1.3e-6),
    a solve every step, 30 IPOPT iterations at most per solve (warm-started solves take 4–13).
    On the default episodes (seeds 0–19, ``benchmarks/constrained_slew_optimum.py``) one 120 s
    episode cost 17–24 s of CPU (median 19 s, policy build included), ΣJ/ΣJ* = 1.004 with no
    violation; N = 20 cost about 12 s and ΣJ/ΣJ* = 1.029 (its 10 s look-ahead cuts corners
    worse on the long slews: seed 15 6688 against 6081 at N = 30, J* 6002).
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 30,
        max_iter: int = 30,
        tol: float = 1e-6,
        backoff: float | None = None,
        constr_viol_tol: float = 1e-9,
        replan_steps: int = 1,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
        model_substeps: int | None = 2,
    ) -> None:
        base = env.unwrapped
        if not hasattr(base, "cones") or not hasattr(base, "body_rate_limit"):
            raise ValueError(f"{type(self).__name__} needs ConstrainedSlew-v0, got {base.env_name}")
        #: the boresight of each cone slot (body axes), constants of the env
        self.boresights = [np.asarray(base.boresights[kind[1]], dtype=float) for kind in CONE_KINDS]
        self.rate_limit_rad_s = float(base.body_rate_limit.limit_rad_s)
        self.wheel_speed_limit_rad_s = float(base.wheel_speed_limit.limit_rad_s)
        self.backoff = cs.backoff(base) if backoff is None else validation.nonnegative("backoff", backoff)
        #: env steps per solve: the plan's actions are played open loop in between
        self.replan_steps = validation.integer("replan_steps", replan_steps, 1)
        options = {
            "ipopt.constr_viol_tol": validation.positive("constr_viol_tol", constr_viol_tol),
            **(solver_options or {}),
        }
        self._slew = EigenaxisSlewPolicy(env)
        super().__init__(env, horizon_steps, max_iter, tol, options, name or "mpc-constrained", model_substeps)
        #: the steps that played the last solved plan's next action (a solve not finished)
        self.held_steps = 0
        self._plan_left = 0
        self._replan_left = 0

    # ------------------------------------------------------------------ the NLP's rows
    def _path_constraints(self, y, a) -> tuple[Any, list, np.ndarray, np.ndarray]:
        """The cone, body-rate and wheel-speed rows at ``y_1 … y_N`` with the cone slots as
        parameters ``[d_1, cos α_1, d_2, cos α_2, d_3, cos α_3]``."""
        n_w = self._model.params.n_wheels
        x = casadi.SX.sym("x", self._n_y)
        p = casadi.SX.sym("cones", _SLOT * MAX_CONES)
        rows = [
            cs.cone_row(x, b, p[_SLOT * i : _SLOT * i + 3], p[_SLOT * i + 3], self.backoff)
            for i, b in enumerate(self.boresights)
        ]
        rows += cs.limit_rows(x, self.rate_limit_rad_s, self.wheel_speed_limit_rad_s, n_w, self.backoff)
        row_fn = casadi.Function("path_rows", [x, p], [casadi.vertcat(*rows)])
        n_h = self.horizon_steps
        cones = casadi.MX.sym("cones", _SLOT * MAX_CONES)
        g = casadi.vec(row_fn.map(n_h)(y[:, 1:], casadi.repmat(cones, 1, n_h)))
        n = g.shape[0]
        return cones, [g], np.full(n, -np.inf), np.zeros(n)

    def cone_parameters(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The cone slots' parameters of this step: each active slot's inertial direction
        ``R(q̂) s_B`` (``s_B`` from the observation, normalized; ``q̂`` the measured attitude)
        and ``cos α``; an inactive slot ``[0, 0, 0, 1]``."""
        block = np.asarray(obs, dtype=float)[-CONE_FEATURES * MAX_CONES :].reshape(MAX_CONES, CONE_FEATURES)
        rotation = quaternion.to_matrix(np.asarray(info["measured"]["attitude"], dtype=float))
        out = np.tile([0.0, 0.0, 0.0, 1.0], MAX_CONES)
        for i, slot in enumerate(block):
            if slot[4] >= 0.5:
                s_b = slot[:3] / np.linalg.norm(slot[:3])
                out[_SLOT * i : _SLOT * i + 3] = rotation @ s_b
                out[_SLOT * i + 3] = slot[3]
        return out

    def _parameter_values(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.cone_parameters(obs, info)

    # ------------------------------------------------------------------ acting
    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.held_steps = 0
        self._plan_left = 0
        self._replan_left = 0

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step from ``info["measured"]`` and the observation's cones:
        a new solve every ``replan_steps`` steps, the last solved plan's next action between."""
        if self._replan_left > 0 and self._plan_left > 0 and self._guess is not None:
            self._replan_left -= 1
            return self._next_planned_action()
        failures, solves = self.failures, len(self.solve_times_s)
        action = super().act(obs, info)
        if len(self.solve_times_s) > solves and self.failures == failures:  # a solved plan to follow
            self._plan_left = self.horizon_steps - 1
            self._replan_left = self.replan_steps - 1
        return action

    def _next_planned_action(self) -> np.ndarray:
        """The last solved plan's next action (the guess is that plan, shifted); the guess
        shifted once more."""
        a_plan, y_plan = self._guess
        self._guess = shifted(a_plan, y_plan)
        self._plan_left -= 1
        return np.clip(a_plan[:, 0], -1.0, 1.0).astype(np.float32)

    def _failed_solve_action(self) -> np.ndarray | None:
        """The last solved plan's next action (:attr:`held_steps` counts them); None when no
        solved plan is left."""
        if self._guess is None or self._plan_left <= 0:
            return None
        self.held_steps += 1
        return self._next_planned_action()

    def _initial_guess(self, y0: np.ndarray, target: np.ndarray, obs, info) -> tuple[np.ndarray, np.ndarray]:
        """The shifted previous solution, or (first step) the eigenaxis slew's rollout on the
        nominal model."""
        if self._guess is not None:
            return super()._initial_guess(y0, target, obs, info)

        def slew(k: int, y: np.ndarray) -> np.ndarray:
            state = MeasuredState(attitude=y[:4], rate_rad_s=y[4:7], wheel_speed_rad_s=y[7:], target_attitude=target)
            return self._slew.action(self._slew.body_torque_nm(state))

        return self._rollout_guess(y0, target, slew)
