"""Offset-free nonlinear model-predictive control (MPC) of FuelSlosh-v0 on its nominal model.

At every control step the policy solves, from the measured full state ``y_0``
(``info["measured"]``) and the current input-disturbance estimate ``d̂``,

    min_{a_0..a_{N−1}}  Σ_k ℓ(y_k, a_k; d̂) + x(y_N)ᵀ S x(y_N)
    s.t.  y_{k+1} = f(y_k, a_k; d̂),   −1 ≤ a_k ≤ 1,   −1 ≤ a_k + d̂/limits ≤ 1

and applies ``a_0`` (receding horizon; Rawlings, Mayne & Diehl 2017, ch. 1–2). ``f`` and ``ℓ``
are the shared symbolic model of the plant, the one the optimal-control yardstick J* uses:
:func:`attitude_envs.symbolic.slosh.nominal_step_function` (the env's kernel constants: the
nominal Navabi & Davoodi two-pendulum plant, eqs. 11–14, its RK4 sub-steps, control period and
stage-cost quadrature ``∫ (xᵀQx + u_cᵀRu_c) dt``; no faults), whose applied inputs are
``a · limits + d̂``. ``x(y)`` is the reduced state ``[v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` and ``S``
the discrete Riccati matrix (:func:`attitude_envs.lqr.dlqr`) of the zero-order-hold
linearization the paper's LQR baseline designs on (:class:`baselines.slosh.SloshLQRPolicy`
with the env's weights), the unconstrained infinite-horizon cost-to-go as terminal cost
(Mayne et al. 2000). Direct multiple shooting (Bock & Plitt 1984) through CasADi (Andersson et
al. 2019), solved by sequential quadratic programming with the exact Hessian (CasADi's
``sqpmethod``, its active-set QP solver ``qrqp`` and a line search; the default) or by IPOPT's
interior point (Wächter & Biegler 2006; ``solver="ipopt"``). An SQP solve that fails (its line
search stalls, or ``max_iter`` iterations pass) is solved again by IPOPT from the same guess
(100 iterations, the same ``tol``, none of ``solver_options``). Every solve starts from the
LQR's rollout on the model (``initial_guess="lqr"``, the default) or from the previous solution
shifted by one step (``"shifted"``). The NLP is nonconvex in the random
starts' transient, and where a solve starts decides which local minimum it finds. On the slosh
campaign's 40 episodes (2026-11-28), ΣJ/ΣJ* nominal and under the thruster faults:

* IPOPT, shifted guess: 1.0207 and 1.1034.
* SQP, LQR guess: 1.0211 and 1.1054. Median solve on seeds 0 and 1 of the nominal cell: 16.1
  and 5.5 ms, against IPOPT's 38.7 and 28.4 ms (benchmarks/results/mpc_solve_times.json, and
  its previous version for IPOPT).
* SQP, shifted guess: 1.0479 and 1.1293. It stays in the local minimum its first solve found,
  2-4 % worse than IPOPT's on most transients.

Offset-free MPC (Pannocchia & Rawlings 2003; Maeder, Borrelli & Morari 2009): the plant is
modelled with a constant additive input disturbance ``d`` (rad, N·m), estimated after every
step from the prediction residual — the ``d`` for which the model's step from the previous
measured state under the previous action reproduces the new measured state (three Gauss–Newton
iterations of the least-squares fit over the 8 non-position states, the model's input Jacobian by
CasADi's AD), filtered as ``d̂ ← d̂ + disturbance_gain · (d_fit − d̂)``. The state is measured, so
this is the disturbance half of the augmented estimator. With ``estimate_effectiveness``
(the default) the fit's applied input ``p = a + d_fit/limits`` (normalized) of the last
``window_steps`` steps is regressed per actuator on the command as ``p = θ a + β`` (ridge
least squares pulled toward θ = 1, β = 0 with weight ``ridge``; θ clipped to [0.05, 1.5]);
the window restarts from the last step alone when the window's fit, the last step included,
misses one of its points by more than ``change_tol`` (a fault's onset: no fit across it). The
window's own fit is the test, not the filtered estimate: with the latter, an estimate still
lagging a loss of effectiveness restarted the window at every step (on the slosh campaign's
thruster faults 3.69 × J*, against 1.10 with this test). The NLP then optimizes the effective
action ``a' = θ a`` with ``d̂ = β · limits`` and applies ``a'/θ``, so a loss of effectiveness
is compensated as a gain, not as a lagged offset. Left out: the env's termination limits (no
state constraints, every problem is feasible).

:attr:`SloshMPCPolicy.solve_times_s` holds the wall time of each solve (s),
:attr:`SloshMPCPolicy.failures` the decisions whose solve did not finish, the IPOPT fallback
included (their iterate is used if finite, else the LQR's action),
:attr:`SloshMPCPolicy.fallbacks` the SQP solves that failed and went to IPOPT,
:attr:`SloshMPCPolicy.disturbance_estimate` the current ``d̂``.
Reads only ``info["measured"]`` (full state: needs ``observe_slosh=True``). Requires CasADi.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.lqr import dlqr
from attitude_envs.plants import slosh
from attitude_envs.plants.slosh_model import REDUCED_INDEX
from baselines.slosh import SloshLQRPolicy

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the fuel-slosh MPC baseline needs CasADi: pip install 'attitude-envs[optimal]'") from exc

from attitude_envs.symbolic.problem import QUIET
from attitude_envs.symbolic.slosh import nominal_step_function
from baselines.compiled_nlp import compiled_nlpsol
from baselines.mpc import shifted

_QUIET_SQP = {
    "print_header": False,
    "print_iteration": False,
    "print_status": False,
    "print_time": False,
    "qpsol": "qrqp",
    "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
}
#: the NLP solvers the policy can use
SOLVERS = ("sqp", "ipopt")
#: where each solve starts: the LQR's rollout on the model, or the previous solution shifted
INITIAL_GUESSES = ("lqr", "shifted")
_IPOPT_MAX_ITER = 100
#: SQP from the LQR's rollout takes 1-4 iterations on the slosh campaign's episodes; one that has
#: not converged in 20 goes to IPOPT instead
_SQP_MAX_ITER = 20
#: the full-state rows the disturbance fit uses (the position is not always measured)
_FIT_ROWS = np.arange(slosh.ITH, slosh.N_STATE)


def measured_full_state(measured: dict[str, Any]) -> np.ndarray:
    """The full state ``y`` (10, :mod:`attitude_envs.plants.slosh`) from ``info["measured"]``
    of FuelSlosh-v0 (position 0 when not measured: it does not enter the dynamics)."""
    if "slosh_angle_rad" not in measured:
        raise ValueError("SloshMPCPolicy needs the slosh states measured (observe_slosh=True)")
    y = np.zeros(slosh.N_STATE)
    y[slosh.IX : slosh.IZ + 1] = measured.get("position_m", (0.0, 0.0))
    y[slosh.ITH] = measured["theta_rad"]
    y[slosh.IPSI1 : slosh.IPSI2 + 1] = measured["slosh_angle_rad"]
    y[slosh.IVX] = measured["v_x_m_s"]
    y[slosh.IVZ] = measured["v_z_m_s"]
    y[slosh.IOM] = measured["pitch_rate_rad_s"]
    y[slosh.IDPSI1 :] = measured["slosh_rate_rad_s"]
    return y


class SloshMPCPolicy:
    """Offset-free nonlinear MPC of FuelSlosh-v0 (see the module docstring); acts at the env's
    ``control_dt_s``.

    Parameters: ``horizon_steps`` (control steps N in the horizon, integer ≥ 1; default 5:
    0.5 s at the campaign's 0.1 s period; the solve time grows about linearly with N),
    ``offset_free`` (estimate the input disturbance; default True), ``disturbance_gain``
    (filter gain of the estimate, in (0, 1]; default 1), ``estimate_effectiveness`` (also
    estimate each actuator's effectiveness θ; default True), ``window_steps`` (steps in its
    regression window, integer ≥ 2; default 10), ``ridge`` (weight of the prior θ = 1, β = 0,
    ≥ 0; default 1e-4), ``change_tol`` (largest normalized misfit of the regression window's points to its fit above
    which the window restarts, > 0; default 1e-4), ``cost_scale`` (factor on the NLP's
    objective, > 0, for IPOPT's tolerances; the optimum is unchanged; default 1e3),
    ``solver`` (``"sqp"``, the default, or ``"ipopt"``: see the module docstring),
    ``initial_guess`` (``"lqr"``, the default, or ``"shifted"``: where each solve starts),
    ``max_iter`` (iterations per solve; default 20 for SQP, 100 for IPOPT), ``tol`` (the
    solver's tolerance: IPOPT's ``tol``, SQP's primal and dual infeasibility),
    ``solver_options`` (further CasADi options of that solver: IPOPT's ``ipopt.*`` keys need
    ``solver="ipopt"``; there ``{"ipopt.mu_init": 1e-4}`` halves the iterations per solve,
    median 9 → 4, but on the slosh campaign's 40 episodes it moved J by −21 % to +30 % per
    episode), ``compiled`` (compile the SQP solver's functions to C with the system's C
    compiler, cached on disk for every later process: :mod:`baselines.compiled_nlp`; the same
    decisions, median solve 4.3 ms against 10.9 ms on seed 0 of the slosh campaign, one core;
    the first build takes about 2 min; default False), ``name``.
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 5,
        offset_free: bool = True,
        disturbance_gain: float = 1.0,
        estimate_effectiveness: bool = True,
        window_steps: int = 10,
        ridge: float = 1e-4,
        change_tol: float = 1e-4,
        cost_scale: float = 1e3,
        solver: str = "sqp",
        initial_guess: str = "lqr",
        max_iter: int | None = None,
        tol: float = 1e-8,
        solver_options: dict[str, Any] | None = None,
        compiled: bool = False,
        name: str | None = None,
    ) -> None:
        base = env.unwrapped
        if not hasattr(base, "kernel_constants") or not hasattr(base, "actuator_limits"):
            raise ValueError("SloshMPCPolicy needs FuelSlosh-v0")
        if isinstance(horizon_steps, bool) or int(horizon_steps) != horizon_steps or int(horizon_steps) < 1:
            raise ValueError(f"horizon_steps must be an integer >= 1, got {horizon_steps!r}")
        self.name = name or "mpc-slosh"
        self.horizon_steps = int(horizon_steps)
        self.offset_free = validation.flag("offset_free", offset_free)
        self.disturbance_gain = validation.in_range("disturbance_gain", disturbance_gain, 0.0, 1.0, open_low=True)
        self.cost_scale = validation.positive("cost_scale", cost_scale)
        self.estimate_effectiveness = validation.flag("estimate_effectiveness", estimate_effectiveness)
        if isinstance(window_steps, bool) or int(window_steps) != window_steps or int(window_steps) < 2:
            raise ValueError(f"window_steps must be an integer >= 2, got {window_steps!r}")
        self.window_steps = int(window_steps)
        self.ridge = validation.nonnegative("ridge", ridge)
        self.change_tol = validation.positive("change_tol", change_tol)
        self.solver = validation.choice("solver", solver, SOLVERS)
        self.initial_guess = validation.choice("initial_guess", initial_guess, INITIAL_GUESSES)
        default_iter = _IPOPT_MAX_ITER if self.solver == "ipopt" else _SQP_MAX_ITER
        self._max_iter = default_iter if max_iter is None else validation.integer("max_iter", max_iter, 1)
        self._tol = validation.positive("tol", tol)
        self._solver_options = dict(solver_options or {})
        self.compiled = validation.flag("compiled", compiled)
        ipopt_keys = sorted(k for k in self._solver_options if str(k).startswith("ipopt."))
        if ipopt_keys and self.solver != "ipopt":
            raise ValueError(f"solver_options {ipopt_keys} are IPOPT's: pass solver='ipopt' with them")
        self.control_dt_s = float(base.control_dt_s)
        self._limits = np.asarray(base.actuator_limits, dtype=float).copy()
        #: the prediction model: ``(y (10), a (2), d (2)) -> (y_next, cost)``
        self.model_step = nominal_step_function(base)
        # the paper's LQR design (its linearization, ZOH at the env's period) with the env's weights
        cost = base.model.cost
        self._lqr = SloshLQRPolicy(env, Q=cost.Q, R=cost.R)
        lin = self._lqr.linear_model
        #: terminal weight on the reduced state: the discrete Riccati solution of that design
        _, self.terminal_weight, _ = dlqr(lin.A, lin.B, lin.Q, lin.R, lin.N)
        self._build_solver()
        d = casadi.SX.sym("d", 2)
        y_prev = casadi.SX.sym("y", slosh.N_STATE)
        a_prev = casadi.SX.sym("a", 2)
        y_next, _ = self.model_step(y_prev, a_prev, d)
        self._residual_jac = casadi.Function(
            "residual", [y_prev, a_prev, d], [y_next, casadi.jacobian(y_next, d)], ["y", "a", "d"], ["y_next", "J"]
        )
        self.solve_times_s: list[float] = []
        self.failures = 0
        #: the SQP solves that failed and were solved again by IPOPT
        self.fallbacks = 0
        self.disturbance_estimate = np.zeros(2)
        #: the estimated effectiveness θ of each actuator (1: nominal)
        self.effectiveness_estimate = np.ones(2)
        self._history: list[tuple[np.ndarray, np.ndarray]] = []
        self._guess: tuple[np.ndarray, np.ndarray] | None = None
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def _build_solver(self) -> None:
        n_h, n_y = self.horizon_steps, slosh.N_STATE
        y = casadi.SX.sym("Y", n_y, n_h + 1)
        a = casadi.SX.sym("A", 2, n_h)
        y0 = casadi.SX.sym("y0", n_y)
        d = casadi.SX.sym("d", 2)
        y_next, costs = self.model_step.map(n_h)(y[:, :n_h], a, casadi.repmat(d, 1, n_h))
        x_n = y[list(REDUCED_INDEX), n_h]
        objective = casadi.sum2(costs) + casadi.bilin(casadi.DM(self.terminal_weight), x_n, x_n)
        nlp = {
            "x": casadi.vertcat(casadi.vec(a), casadi.vec(y)),
            "p": casadi.vertcat(y0, d),
            "f": self.cost_scale * objective,
            "g": casadi.vertcat(y[:, 0] - y0, casadi.vec(y[:, 1:] - y_next)),
        }
        self._nlp = nlp
        self._solver = self._nlpsol(self.solver, self._max_iter, self._solver_options, self.compiled)
        #: IPOPT from the same initial guess where an SQP solve fails (built here: building takes
        #: about a second, which would count in the first failing decision)
        self._fallback = self._nlpsol("ipopt", _IPOPT_MAX_ITER, {}) if self.solver == "sqp" else None
        self._n_a = 2 * n_h
        n_w = n_y * (n_h + 1)
        self._lbg = np.zeros(n_w)
        self._ubg = np.zeros(n_w)
        self._free = np.full(n_w, np.inf)

    def _nlpsol(self, solver: str, max_iter: int, options: dict[str, Any], compiled: bool = False) -> Any:
        """CasADi's solver ``solver`` (``"sqp"`` or ``"ipopt"``) of the MPC's NLP, its functions
        compiled to C when ``compiled`` (:func:`baselines.compiled_nlp.compiled_nlpsol`)."""
        if solver == "ipopt":
            opts = {**QUIET, "ipopt.max_iter": max_iter, "ipopt.tol": self._tol}
        else:
            opts = {**_QUIET_SQP, "max_iter": max_iter, "tol_pr": self._tol, "tol_du": self._tol}
        opts = {**opts, "error_on_fail": False, **options}
        plugin = "sqpmethod" if solver == "sqp" else "ipopt"
        if compiled:
            return compiled_nlpsol(f"mpc_slosh_{solver}", plugin, self._nlp, opts)
        return casadi.nlpsol(f"mpc_slosh_{solver}", plugin, self._nlp, opts)

    def _solve(self, **args: Any) -> tuple[Any, bool]:
        """The NLP's solution from ``args`` (CasADi's solver arguments) and whether it solved:
        SQP first, IPOPT from the same guess where SQP fails (counted in :attr:`fallbacks`)."""
        sol = self._solver(**args)
        solved = bool(self._solver.stats()["success"])
        if solved or self.solver != "sqp":
            return sol, solved
        self.fallbacks += 1
        sol = self._fallback(**args)
        return sol, bool(self._fallback.stats()["success"])

    def reset(self, seed: int | None = None) -> None:
        self._guess = None
        self._last = None
        self.disturbance_estimate = np.zeros(2)
        self.effectiveness_estimate = np.ones(2)
        self._history = []

    def _update_disturbance(self, y: np.ndarray) -> None:
        """Three Gauss–Newton iterations of ``min_d ‖y − f(y_prev, a_prev; d)‖`` over the non-position
        rows, filtered into :attr:`disturbance_estimate` (the offset-free estimator)."""
        if self._last is None or not self.offset_free:
            return
        y_prev, a_prev = self._last
        d = self.disturbance_estimate
        step = np.zeros(2)
        for _ in range(3):  # Gauss–Newton iterations (the step is nonlinear in δ)
            y_pred, jac = self._residual_jac(y_prev, a_prev, d + step)
            r = (y - np.asarray(y_pred).ravel())[_FIT_ROWS]
            delta, *_ = np.linalg.lstsq(np.asarray(jac)[_FIT_ROWS], r, rcond=None)
            step = step + delta
        if not np.all(np.isfinite(step)):
            return
        if not self.estimate_effectiveness:
            self.disturbance_estimate = d + self.disturbance_gain * step
            return
        # the applied input of the last step (normalized), from the fit: p = a_prev + d_fit/limits
        self._update_actuators(a_prev, a_prev + (d + step) / self._limits)

    def _update_actuators(self, command: np.ndarray, applied: np.ndarray) -> None:
        """One step of the actuator model's estimator: the pair (``command``, ``applied``, both
        normalized per actuator) joins the regression window (restarted from this pair alone when
        the window's fit misses one of its points by more than ``change_tol``), and the filtered
        estimates move toward the window's fit ``applied = θ·command + β``."""
        history = [*self._history[-(self.window_steps - 1) :], (np.asarray(command), np.asarray(applied))]
        fit = self._actuator_fit(history)
        if len(history) > 2 and max(r for _, _, r in fit) > self.change_tol:  # the actuators changed:
            history = history[-1:]  # forget the data of the old actuator model
            fit = self._actuator_fit(history)
        self._history = history
        theta, beta = self.effectiveness_estimate.copy(), self.disturbance_estimate / self._limits
        for i, (th_i, b_i, _) in enumerate(fit):
            theta[i] += self.disturbance_gain * (th_i - theta[i])
            beta[i] += self.disturbance_gain * (b_i - beta[i])
        self.effectiveness_estimate = theta
        self.disturbance_estimate = beta * self._limits

    def _actuator_fit(self, history: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[float, float, float]]:
        """Per actuator ``(θ, β, residual)``: the ridge least squares of ``p = θ c + β`` over
        ``history`` (command ``c``, applied input ``p``, normalized) toward θ = 1, β = 0, θ clipped
        to [0.05, 1.5], and the largest misfit of the window's points to it."""
        cmds = np.array([h[0] for h in history])
        outs = np.array([h[1] for h in history])
        out = []
        for i in range(2):
            X = np.column_stack([cmds[:, i], np.ones(len(cmds))])
            lhs = X.T @ X + self.ridge * np.eye(2)
            rhs = X.T @ outs[:, i] + self.ridge * np.array([1.0, 0.0])
            th_i, b_i = np.linalg.solve(lhs, rhs)
            th_i = float(np.clip(th_i, 0.05, 1.5))
            b_i = float(np.mean(outs[:, i] - th_i * cmds[:, i])) if self.ridge == 0.0 else float(b_i)
            out.append((th_i, b_i, float(np.max(np.abs(outs[:, i] - th_i * cmds[:, i] - b_i)))))
        return out

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step from ``info["measured"]`` (not a batch)."""
        y0 = measured_full_state(info["measured"])
        if not np.all(np.isfinite(y0)):
            self._last = None
            return self._lqr.act(obs, info)  # a dropout: nothing to predict from
        self._update_disturbance(y0)
        d, theta = self.disturbance_estimate, self.effectiveness_estimate
        # the NLP's action is the effective one, a' = θ a; bounds: |a| ≤ 1 and the applied input
        # a'·limit + d̂ within the limit
        shift = d / self._limits
        lo, hi = np.maximum(-theta, -1.0 - shift), np.minimum(theta, 1.0 - shift)
        if np.any(lo > hi):  # a disturbance beyond the authority: keep |a| ≤ 1 only
            lo, hi = -theta, theta.copy()
        n_h = self.horizon_steps
        a_guess, y_guess = self._initial_guess(y0, d)
        a_guess = np.clip(a_guess, lo[:, None], hi[:, None])
        t0 = time.perf_counter()
        sol, solved = self._solve(
            x0=np.r_[a_guess.ravel(order="F"), y_guess.ravel(order="F")],
            p=np.r_[y0, d],
            lbx=np.r_[np.tile(lo, n_h), -self._free],
            ubx=np.r_[np.tile(hi, n_h), self._free],
            lbg=self._lbg,
            ubg=self._ubg,
        )
        self.solve_times_s.append(time.perf_counter() - t0)
        w = np.asarray(sol["x"]).ravel()
        if not solved:
            self.failures += 1
        if not np.all(np.isfinite(w)):
            self._guess = None
            action = self._lqr.act(obs, info)
        else:
            a_opt = w[: self._n_a].reshape(2, -1, order="F")
            if self.initial_guess == "shifted":  # the next step's start: shifted by one step, last entry repeated
                y_opt = w[self._n_a :].reshape(slosh.N_STATE, -1, order="F")
                self._guess = shifted(a_opt, y_opt)
            action = np.clip(a_opt[:, 0] / theta, -1.0, 1.0).astype(np.float32)
        self._last = (y0, np.clip(np.asarray(action, dtype=float), -1.0, 1.0))
        return action

    def _initial_guess(self, y0: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(actions (2, N), states (10, N + 1))`` where the solve starts: the LQR's rollout on
        the model (``initial_guess="lqr"``, and every first step), or the previous solution
        shifted by one step (``"shifted"``)."""
        if self.initial_guess == "shifted" and self._guess is not None:
            a_guess, y_guess = self._guess
            y_guess = y_guess.copy()
            y_guess[:, 0] = y0
            return a_guess, y_guess
        n_h = self.horizon_steps
        a_guess = np.zeros((2, n_h))
        y_guess = np.zeros((slosh.N_STATE, n_h + 1))
        y_guess[:, 0] = y0
        for k in range(n_h):
            y = y_guess[:, k]
            delta, moment = self._lqr.physical_inputs(y[REDUCED_INDEX], float(y[slosh.IVX]))
            a_guess[:, k] = np.clip((np.array([delta, moment]) - d) / self._limits, -1.0, 1.0)
            y_next, _ = self.model_step(y, a_guess[:, k], d)
            y_guess[:, k + 1] = np.asarray(y_next).ravel()
        return a_guess, y_guess
