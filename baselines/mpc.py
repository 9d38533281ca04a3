"""Nonlinear model-predictive control (MPC) of the reaction-wheel spacecraft on its NOMINAL model.

At every control step the policy solves, from the measured state (``info["measured"]``),

    min_{a_0..a_{N−1}}  Σ_k ℓ(y_k, a_k) + x(y_N)ᵀ P x(y_N)
    s.t.  y_{k+1} = f(y_k, a_k),  y_0 = measured state,  −1 ≤ a_k ≤ 1
          (body action frame: also |−A⁺ a_k| ≤ 1 per wheel, the env's per-wheel limit)

and applies ``a_0`` (receding horizon; Rawlings, Mayne & Diehl 2017, ch. 1–2). ``f`` and
``ℓ`` come from the shared symbolic model of the gyrostat, the one the optimal-control
yardstick J* builds from the episode's true plant: :func:`attitude_envs.symbolic.gyrostat.step_function`
of :meth:`GyrostatParameters.nominal <attitude_envs.symbolic.gyrostat.GyrostatParameters.nominal>`
(``env.unwrapped.model``: nominal inertia, wheels, torque limit and offset torque, the env's
integrator and action frame; no faults, no disturbance) with ``smooth=True``, kept as
:attr:`MPCPolicy.model_step`. So ``f`` is integrated like the env (``n_substeps`` classical
RK4 sub-steps with the motor torque held, the quaternion renormalized after each; with
``model_substeps``, that many sub-steps over the same period instead) and ``ℓ``
is the env's own step cost, ``∫ (xᵀQx + u_cᵀRu_c) dt`` by the same RK4 quadrature (``x`` the
error state of :class:`~attitude_envs.plants.gyrostat_model.ReactionWheelModel`,
:func:`attitude_envs.symbolic.gyrostat.error_state`); ``P`` is the discrete
Riccati matrix ``S`` of the LQR's zero-order-hold design (:func:`attitude_envs.lqr.dlqr`): the
unconstrained infinite-horizon cost-to-go of the linearization as terminal cost (Mayne et
al. 2000). The problem is transcribed by direct multiple shooting (Bock & Plitt 1984) and
solved by IPOPT (Wächter & Biegler 2006) through CasADi (Andersson et al. 2019), warm-started
from the previous solution shifted by one step (the first step of an episode from the LQR's
rollout on the model). Left out: the action clips (``smooth=True``; the bounds above hold
the actions instead), the error quaternion's sign flip (``smooth=True``; the measured
attitude is signed so that ``q_e,w ≥ 0`` at the start of the horizon), the wheel-speed limit
(``smooth=True`` drops the motor driver's limiter) and the roll/pitch stop (no state
constraints, so every problem is feasible).

:attr:`MPCPolicy.solve_times_s` holds the wall time of each solve (s), :attr:`MPCPolicy.failures`
the solves IPOPT did not finish (their iterate is used if finite, else the LQR's action).
Works on ReactionWheel-v0 (``action_frame`` ``"wheel"`` or ``"body"``) and AirBearing-v0; one
env at a time. Requires CasADi (``pip install 'attitude-envs[optimal]'``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.lqr import dlqr
from attitude_envs.symbolic.gyrostat import GyrostatParameters, error_state, step_function
from attitude_envs.symbolic.problem import QUIET, SOLVED
from baselines.allocation import wheel_model
from baselines.lqr import LQRPolicy

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the MPC baseline needs CasADi: pip install 'attitude-envs[optimal]'") from exc


def model_parameters(env) -> GyrostatParameters:
    """What the MPC knows of the plant of ``env`` (ReactionWheel-v0 or AirBearing-v0): the
    nominal model ``env.unwrapped.model`` with the env's integrator and action frame
    (:meth:`~attitude_envs.symbolic.gyrostat.GyrostatParameters.nominal`; no faults, no
    disturbance, no drawn inertia). ValueError for any other env."""
    base = env.unwrapped
    frame = getattr(base, "action_frame", "wheel")
    return GyrostatParameters.nominal(wheel_model(env), base.n_substeps, base.integrator_dt_s, frame)


def model_step(env) -> casadi.Function:
    """The MPC's prediction model of ``env``: the shared symbolic step
    (:func:`~attitude_envs.symbolic.gyrostat.step_function`) of :func:`model_parameters` with
    ``smooth=True``, ``(y (7+N), a (n_u), t, q_T (4)) -> (y_next, cost)``; ``a`` is not
    clipped (the NLP bounds it) and ``t`` is unused (the nominal model is time-invariant)."""
    return step_function(model_parameters(env), smooth=True)


def shifted(a: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A plan's actions ``a`` (n_u × N) and states ``y`` (n_y × (N+1)) shifted by one step, the
    last entry repeated: the next step's warm start."""
    return np.column_stack([a[:, 1:], a[:, -1:]]), np.column_stack([y[:, 1:], y[:, -1:]])


class MPCPolicy:
    """Nonlinear MPC on the nominal gyrostat (see the module docstring).

    Parameters: ``horizon_steps`` (control steps N in the horizon, ≥ 1; default 20),
    ``max_iter`` (IPOPT iterations per solve), ``tol`` (IPOPT tolerance), ``solver_options``
    (further CasADi/IPOPT options), ``model_substeps`` (RK4 sub-steps of the prediction model
    per control period, ≥ 1; None: the env's own, so the model is the env's step; fewer make a
    smaller NLP: AirBearing-v0 at the air-bearing campaign's 0.5 s period integrates 50 sub-steps
    of 0.01 s), ``name``.
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 20,
        max_iter: int = 100,
        tol: float = 1e-6,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
        model_substeps: int | None = None,
    ) -> None:
        model = wheel_model(env)
        if int(horizon_steps) < 1:
            raise ValueError(f"horizon_steps must be an integer >= 1, got {horizon_steps!r}")
        self.name = name or "mpc"
        self.horizon_steps = int(horizon_steps)
        self._model = model
        #: what the MPC knows of the plant (:func:`model_parameters`), integrated by
        #: ``model_substeps`` RK4 sub-steps per control period when given
        self.model_parameters = model_parameters(env)
        if model_substeps is not None:
            k = validation.integer("model_substeps", model_substeps, 1)
            period = self.model_parameters.n_substeps * self.model_parameters.integrator_dt_s
            self.model_parameters = replace(self.model_parameters, n_substeps=k, integrator_dt_s=period / k)
        #: its prediction model (:func:`model_step`): ``(y, a, t, q_T) -> (y_next, cost)``
        self.model_step = step_function(self.model_parameters, smooth=True)
        self._frame = self.model_parameters.action_frame
        self._lqr = LQRPolicy(env, "zoh")
        lin = self._lqr.linear_model
        #: terminal weight: the discrete Riccati solution of the LQR design, on the error state
        _, self.terminal_weight, _ = dlqr(lin.A, lin.B, lin.Q, lin.R, lin.N)
        n = model.params.n_wheels
        self._n_y, self._n_u = 7 + n, self.model_step.size1_in(1)
        self._max_iter, self._tol = int(max_iter), float(validation.positive("tol", tol))
        self._solver_options = dict(solver_options or {})
        self._build_solver()
        self.solve_times_s: list[float] = []
        self.failures = 0
        self._guess: tuple[np.ndarray, np.ndarray] | None = None

    def _build_solver(self) -> None:
        """The NLP of :attr:`model_step` and :attr:`terminal_weight` (direct multiple shooting),
        its IPOPT solver and bounds; called again by subclasses that change the model."""
        model, n_h = self._model, self.horizon_steps
        n = model.params.n_wheels
        y = casadi.MX.sym("Y", self._n_y, n_h + 1)
        a = casadi.MX.sym("A", self._n_u, n_h)
        y0 = casadi.MX.sym("y0", self._n_y)
        target = casadi.MX.sym("q_T", 4)
        y_next, costs = self._stage_dynamics(y[:, :n_h], a, target)
        x_n = error_state(self.model_parameters, y[:, n_h], target, smooth=True)
        objective = casadi.sum2(costs) + casadi.bilin(casadi.DM(self.terminal_weight), x_n, x_n)
        constraints = [y[:, 0] - y0, casadi.vec(y[:, 1:] - y_next)]
        self._n_eq = self._n_y * (n_h + 1)
        if self._frame == "body":  # the env clips each wheel of the allocated demand at its limit
            constraints.append(casadi.vec(casadi.mtimes(casadi.DM(model.allocation), a)))
        extra_p, extra_rows, extra_lb, extra_ub = self._path_constraints(y, a)
        constraints.extend(extra_rows)
        nlp = {
            "x": casadi.vertcat(casadi.vec(a), casadi.vec(y)),
            "p": casadi.vertcat(y0, target, extra_p),
            "f": objective,
            "g": casadi.vertcat(*constraints),
        }
        opts = {
            **QUIET,
            "expand": True,
            "ipopt.mu_strategy": "adaptive",
            "ipopt.max_iter": self._max_iter,
            "ipopt.tol": self._tol,
        }
        opts.update(self._solver_options)
        self._solver = casadi.nlpsol("mpc", "ipopt", nlp, opts)
        n_a = self._n_u * n_h
        n_g = self._n_eq + (n * n_h if self._frame == "body" else 0)
        self._lbx = np.r_[-np.ones(n_a), np.full(self._n_y * (n_h + 1), -np.inf)]
        self._ubx = np.r_[np.ones(n_a), np.full(self._n_y * (n_h + 1), np.inf)]
        self._lbg = np.r_[np.zeros(self._n_eq), -np.ones(n_g - self._n_eq), extra_lb]
        self._ubg = np.r_[np.zeros(self._n_eq), np.ones(n_g - self._n_eq), extra_ub]

    def _path_constraints(self, y, a) -> tuple[Any, list, np.ndarray, np.ndarray]:
        """Further rows of the NLP on the horizon's states ``y`` (n_y × (N+1), MX) and actions
        ``a``: ``(p, rows, lb, ub)`` with ``p`` the MX parameters they use (appended to the NLP's
        ``[y0, q_T]``; their values per step from :meth:`_parameter_values`), ``rows`` MX
        column vectors (appended after the action-limit rows) and their bounds. None here; a
        subclass adds state constraints (:mod:`baselines.mpc_constrained`)."""
        return casadi.MX(0, 1), [], np.zeros(0), np.zeros(0)

    def _parameter_values(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The values of :meth:`_path_constraints`' parameters for this step (none here)."""
        return np.zeros(0)

    def _stage_dynamics(self, y, a, target):
        """``(y_next, costs)`` (MX) of the horizon's stages from their states ``y`` (n_y × N)
        and actions ``a`` (n_u × N): :attr:`model_step` mapped over the stages."""
        n_h = y.shape[1]
        times = casadi.DM.zeros(1, n_h)  # the model is time-invariant
        return self.model_step.map(n_h)(y, a, times, casadi.repmat(target, 1, n_h))

    def reset(self, seed: int | None = None) -> None:
        self._guess = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step from ``info["measured"]`` (not a batch)."""
        m = info["measured"]
        q = np.asarray(m["attitude"], dtype=float)
        target = np.asarray(m["target_attitude"], dtype=float)
        y0 = np.r_[q if q @ target >= 0.0 else -q, m["rate_rad_s"], m["wheel_speed_rad_s"]]
        if not np.all(np.isfinite(y0)):
            return self._fallback_action(obs, info)  # a dropout: nothing to predict from
        a_guess, y_guess = self._initial_guess(y0, target, obs, info)
        t0 = time.perf_counter()
        sol = self._solver(
            x0=np.r_[a_guess.ravel(order="F"), y_guess.ravel(order="F")],
            p=np.r_[y0, target, self._parameter_values(obs, info)],
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
            held = self._failed_solve_action()
            if held is not None:
                return held
        if not np.all(np.isfinite(w)):
            self._guess = None
            return self._fallback_action(obs, info)
        self._guess = shifted(a_opt, y_opt)  # warm start of the next step
        return np.clip(a_opt[:, 0], -1.0, 1.0).astype(np.float32)

    def _failed_solve_action(self) -> np.ndarray | None:
        """The action of a step whose solve IPOPT did not finish, or None to use its iterate
        (here: None)."""
        return None

    def _fallback_action(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action when there is nothing to solve from or the solve diverged: the LQR's."""
        return self._lqr.act(obs, info)

    def _initial_guess(self, y0: np.ndarray, target: np.ndarray, obs, info) -> tuple[np.ndarray, np.ndarray]:
        """The shifted previous solution, or (first step) the LQR's rollout on the nominal model."""
        if self._guess is not None:
            a_guess, y_guess = self._guess
            y_guess = y_guess.copy()
            y_guess[:, 0] = y0
            return a_guess, y_guess
        start = np.asarray(obs, dtype=float)

        def lqr(k: int, y: np.ndarray) -> np.ndarray:
            x = start if k == 0 else self._model.error_state(y[:4], y[4:7], y[7:], target)
            return self._lqr.act(x, info)

        return self._rollout_guess(y0, target, lqr)

    def _rollout_guess(
        self, y0: np.ndarray, target: np.ndarray, act: Callable[[int, np.ndarray], np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        """A first guess: ``act(k, y_k)`` (normalized actions) rolled out on the nominal model
        from ``y0`` over the horizon."""
        n_h = self.horizon_steps
        a_guess = np.zeros((self._n_u, n_h))
        y_guess = np.zeros((self._n_y, n_h + 1))
        y_guess[:, 0] = y0
        for k in range(n_h):
            a_guess[:, k] = act(k, y_guess[:, k])
            y_next, _ = self.model_step(y_guess[:, k], a_guess[:, k], 0.0, target)
            y_guess[:, k + 1] = np.asarray(y_next).ravel()
        return a_guess, y_guess
