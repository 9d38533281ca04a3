"""Nonlinear model-predictive control (MPC) of the reaction-wheel spacecraft on its NOMINAL model.

At every control step the policy solves, from the measured state (``info["measured"]``),

    min_{a_0..a_{N−1}}  Σ_k ℓ(y_k, a_k) + x(y_N)ᵀ P x(y_N)
    s.t.  y_{k+1} = f(y_k, a_k),  y_0 = measured state,  −1 ≤ a_k ≤ 1
          (body action frame: also |−A⁺ a_k| ≤ 1 per wheel, the env's per-wheel limit)

and applies ``a_0`` (receding horizon; Rawlings, Mayne & Diehl 2017, ch. 1–2). ``f`` is the
nominal gyrostat of :mod:`attitude_envs.plants.gyrostat` (``env.unwrapped.model``: nominal
inertia, wheels, torque limit and offset torque, no faults, no disturbance), integrated like
the env: ``n_substeps`` classical RK4 sub-steps with the motor torque held and the quaternion
renormalized after each. ``ℓ`` is the env's own step cost, ``∫ (xᵀQx + u_cᵀRu_c) dt`` by the
same RK4 quadrature (``x`` the error state of
:class:`~attitude_envs.plants.gyrostat_model.ReactionWheelModel`), and ``P`` the discrete
Riccati matrix ``S`` of the LQR's zero-order-hold design (:func:`attitude_envs.lqr.dlqr`): the
unconstrained infinite-horizon cost-to-go of the linearization as terminal cost (Mayne et
al. 2000). The problem is transcribed by direct multiple shooting (Bock & Plitt 1984) and
solved by IPOPT (Wächter & Biegler 2006) through CasADi (Andersson et al. 2019), warm-started
from the previous solution shifted by one step (the first step of an episode from the LQR's
rollout on the model). Left out: the wheel-speed limit and the roll/pitch stop (no state
constraints, so every problem is feasible), the error quaternion's sign flip (the measured
attitude is signed so that ``q_e,w ≥ 0`` at the start of the horizon).

:attr:`MPCPolicy.solve_times_s` holds the wall time of each solve (s), :attr:`MPCPolicy.failures`
the solves IPOPT did not finish (their iterate is used if finite, else the LQR's action).
Works on ReactionWheel-v0 (``action_frame`` ``"wheel"`` or ``"body"``) and AirBearing-v0; one
env at a time. Requires CasADi (``pip install 'attitude-envs[optimal]'``).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.lqr import dlqr
from baselines.allocation import wheel_model
from baselines.lqr import LQRPolicy

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the MPC baseline needs CasADi: pip install 'attitude-envs[optimal]'") from exc

#: IPOPT's return statuses that mean a (locally) optimal point was found
SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
_QUIET = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": 0}


def nominal_step(model, n_substeps: int, integrator_dt_s: float, action_frame: str = "wheel") -> casadi.Function:
    """The nominal model's control step as a CasADi function
    ``(y (7+N), a (n_u), q_T (4)) -> (y⁺, cost)``: ``y = [q (scalar last), ω (rad/s), Ω (rad/s)]``,
    ``a`` the normalized action (not clipped: the caller bounds it), ``q_T`` the target
    attitude, ``cost`` the env's step cost. Equations as :mod:`attitude_envs.plants.gyrostat`
    (``I_eff ω̇ = −ω × (Iω + J_s A Ω) − A u + p × K(q)``, ``Ω̇ = u/J_s − Aᵀω̇``, ``q̇ = ½ q ⊗ [ω, 0]``)."""
    p = model.params
    n = p.n_wheels
    axes = casadi.DM(p.wheel_axes)
    inertia, ieff_inv = casadi.DM(p.inertia_kg_m2), casadi.DM(p.inertia_eff_inv)
    j_s, max_torque = float(p.wheel_inertia_kg_m2), float(p.max_wheel_torque_nm)
    offset = np.asarray(p.offset_torque_nm, dtype=float)
    q_mat, r_mat = casadi.DM(model.cost.Q), casadi.DM(model.cost.R)
    include_h, body_cost = model.include_wheel_momentum, model.cost_input == "body"
    h = float(integrator_dt_s)

    y = casadi.SX.sym("y", 7 + n)
    n_u = 3 if action_frame == "body" else n
    a = casadi.SX.sym("a", n_u)
    target = casadi.SX.sym("q_T", 4)
    u = casadi.mtimes(casadi.DM(model.allocation), a) if action_frame == "body" else a
    u = u * max_torque
    u_c = -casadi.mtimes(axes, u) if body_cost else u
    input_cost = casadi.bilin(r_mat, u_c, u_c)

    def derivative(z):
        q, w, wheel = z[0:4], z[4:7], z[7:]
        torque = -casadi.mtimes(axes, u) - casadi.cross(w, casadi.mtimes(inertia, w) + j_s * casadi.mtimes(axes, wheel))
        if np.any(offset != 0.0):
            qx, qy, qz, qw = q[0], q[1], q[2], q[3]
            k_dir = casadi.vertcat(2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy))
            torque = torque + casadi.cross(casadi.DM(offset), k_dir)
        w_dot = casadi.mtimes(ieff_inv, torque)
        qx, qy, qz, qw = q[0], q[1], q[2], q[3]
        q_dot = 0.5 * casadi.vertcat(
            qw * w[0] + qy * w[2] - qz * w[1],
            qw * w[1] + qz * w[0] - qx * w[2],
            qw * w[2] + qx * w[1] - qy * w[0],
            -(qx * w[0] + qy * w[1] + qz * w[2]),
        )
        return casadi.vertcat(q_dot, w_dot, u / j_s - casadi.mtimes(axes.T, w_dot))

    def state_cost(z):
        x = error_state(z, target, j_s, include_h)
        return casadi.bilin(q_mat, x, x)

    z, cost = y, 0.0
    for _ in range(int(n_substeps)):
        k1 = derivative(z)
        k2 = derivative(z + 0.5 * h * k1)
        k3 = derivative(z + 0.5 * h * k2)
        k4 = derivative(z + h * k3)
        c1, c2 = state_cost(z), state_cost(z + 0.5 * h * k1)
        c3, c4 = state_cost(z + 0.5 * h * k2), state_cost(z + h * k3)
        cost = cost + (h / 6.0) * (c1 + 2.0 * c2 + 2.0 * c3 + c4 + 6.0 * input_cost)
        z = z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        z = casadi.vertcat(z[0:4] / casadi.norm_2(z[0:4]), z[4:])
    return casadi.Function("nominal_step", [y, a, target], [z, cost], ["y", "a", "q_T"], ["y_next", "cost"])


def error_state(y, target, wheel_inertia_kg_m2: float, include_wheel_momentum: bool):
    """``x = [q_e,vec, ω, (J_s Ω)]`` of a symbolic state ``y`` with ``q_e = q_T* ⊗ q/|q|``
    (no sign flip: a smooth function of ``y``)."""
    q = y[0:4] / casadi.norm_2(y[0:4])
    px, py, pz, pw = -target[0], -target[1], -target[2], target[3]
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    vec = casadi.vertcat(
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )
    parts = [vec, y[4:7]]
    if include_wheel_momentum:
        parts.append(wheel_inertia_kg_m2 * y[7:])
    return casadi.vertcat(*parts)


class MPCPolicy:
    """Nonlinear MPC on the nominal gyrostat (see the module docstring).

    Parameters: ``horizon_steps`` (control steps N in the horizon, ≥ 1; default 20),
    ``max_iter`` (IPOPT iterations per solve), ``tol`` (IPOPT tolerance), ``solver_options``
    (further CasADi/IPOPT options), ``name``.
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 20,
        max_iter: int = 100,
        tol: float = 1e-6,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        base = env.unwrapped
        model = wheel_model(env)
        if int(horizon_steps) < 1:
            raise ValueError(f"horizon_steps must be an integer >= 1, got {horizon_steps!r}")
        self.name = name or "mpc"
        self.horizon_steps = n_h = int(horizon_steps)
        self._model = model
        self._frame = getattr(base, "action_frame", "wheel")
        self._lqr = LQRPolicy(env, "zoh")
        lin = self._lqr.linear_model
        #: terminal weight: the discrete Riccati solution of the LQR design, on the error state
        _, self.terminal_weight, _ = dlqr(lin.A, lin.B, lin.Q, lin.R, lin.N)
        self._step = nominal_step(model, base.n_substeps, base.integrator_dt_s, self._frame)
        n = model.params.n_wheels
        self._n_y, self._n_u = 7 + n, self._step.size1_in(1)

        y = casadi.MX.sym("Y", self._n_y, n_h + 1)
        a = casadi.MX.sym("A", self._n_u, n_h)
        y0 = casadi.MX.sym("y0", self._n_y)
        target = casadi.MX.sym("q_T", 4)
        y_next, costs = self._step.map(n_h)(y[:, :n_h], a, casadi.repmat(target, 1, n_h))
        x_n = error_state(y[:, n_h], target, model.params.wheel_inertia_kg_m2, model.include_wheel_momentum)
        objective = casadi.sum2(costs) + casadi.bilin(casadi.DM(self.terminal_weight), x_n, x_n)
        constraints = [y[:, 0] - y0, casadi.vec(y[:, 1:] - y_next)]
        self._n_eq = self._n_y * (n_h + 1)
        if self._frame == "body":  # the env clips each wheel of the allocated demand at its limit
            constraints.append(casadi.vec(casadi.mtimes(casadi.DM(model.allocation), a)))
        nlp = {
            "x": casadi.vertcat(casadi.vec(a), casadi.vec(y)),
            "p": casadi.vertcat(y0, target),
            "f": objective,
            "g": casadi.vertcat(*constraints),
        }
        opts = {
            **_QUIET,
            "expand": True,
            "ipopt.mu_strategy": "adaptive",
            "ipopt.max_iter": int(max_iter),
            "ipopt.tol": float(validation.positive("tol", tol)),
        }
        opts.update(solver_options or {})
        self._solver = casadi.nlpsol("mpc", "ipopt", nlp, opts)
        n_a = self._n_u * n_h
        n_g = self._n_eq + (n * n_h if self._frame == "body" else 0)
        self._lbx = np.r_[-np.ones(n_a), np.full(self._n_y * (n_h + 1), -np.inf)]
        self._ubx = np.r_[np.ones(n_a), np.full(self._n_y * (n_h + 1), np.inf)]
        self._lbg = np.r_[np.zeros(self._n_eq), -np.ones(n_g - self._n_eq)]
        self._ubg = np.r_[np.zeros(self._n_eq), np.ones(n_g - self._n_eq)]
        self.solve_times_s: list[float] = []
        self.failures = 0
        self._guess: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self, seed: int | None = None) -> None:
        self._guess = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step from ``info["measured"]`` (not a batch)."""
        m = info["measured"]
        q = np.asarray(m["attitude"], dtype=float)
        target = np.asarray(m["target_attitude"], dtype=float)
        y0 = np.r_[q if q @ target >= 0.0 else -q, m["rate_rad_s"], m["wheel_speed_rad_s"]]
        if not np.all(np.isfinite(y0)):
            return self._lqr.act(obs, info)  # a dropout: nothing to predict from
        a_guess, y_guess = self._initial_guess(y0, target, obs, info)
        t0 = time.perf_counter()
        sol = self._solver(
            x0=np.r_[a_guess.ravel(order="F"), y_guess.ravel(order="F")],
            p=np.r_[y0, target],
            lbx=self._lbx,
            ubx=self._ubx,
            lbg=self._lbg,
            ubg=self._ubg,
        )
        self.solve_times_s.append(time.perf_counter() - t0)
        w = np.asarray(sol["x"]).ravel()
        n_a = self._n_u * self.horizon_steps
        a_opt = w[:n_a].reshape(self._n_u, -1, order="F")
        y_opt = w[n_a:].reshape(self._n_y, -1, order="F")
        if self._solver.stats()["return_status"] not in SOLVED:
            self.failures += 1
        if not np.all(np.isfinite(w)):
            self._guess = None
            return self._lqr.act(obs, info)
        # warm start of the next step: the solution shifted by one step, its last entry repeated
        self._guess = (
            np.column_stack([a_opt[:, 1:], a_opt[:, -1:]]),
            np.column_stack([y_opt[:, 1:], y_opt[:, -1:]]),
        )
        return np.clip(a_opt[:, 0], -1.0, 1.0).astype(np.float32)

    def _initial_guess(self, y0: np.ndarray, target: np.ndarray, obs, info) -> tuple[np.ndarray, np.ndarray]:
        """The shifted previous solution, or (first step) the LQR's rollout on the nominal model."""
        if self._guess is not None:
            a_guess, y_guess = self._guess
            y_guess = y_guess.copy()
            y_guess[:, 0] = y0
            return a_guess, y_guess
        n_h = self.horizon_steps
        a_guess = np.zeros((self._n_u, n_h))
        y_guess = np.zeros((self._n_y, n_h + 1))
        y_guess[:, 0] = y0
        x = np.asarray(obs, dtype=float)
        for k in range(n_h):
            a_guess[:, k] = self._lqr.act(x, info)
            y_next, _ = self._step(y_guess[:, k], a_guess[:, k], target)
            y_guess[:, k + 1] = np.asarray(y_next).ravel()
            x = self._model.error_state(y_guess[:4, k + 1], y_guess[4:7, k + 1], y_guess[7:, k + 1], target)
        return a_guess, y_guess
