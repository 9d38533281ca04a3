"""Constrained linear model-predictive control (MPC) of LinearSystem-v0 on its nominal model.

At every decision step the policy solves, from the measured state ``x_0`` (``info["measured"]``),
the quadratic program

    min_{u_0..u_{N−1}}  Σ_k (x_kᵀQx_k + 2x_kᵀNu_k + u_kᵀRu_k) + x_Nᵀ S x_N
    s.t.  x_{k+1} = A x_k + B u_k,   −action_scale ≤ u_k ≤ action_scale

and applies ``u_0 / action_scale`` (receding horizon; Rawlings, Mayne & Diehl 2017, ch. 1–2).
The model and stage cost are the shared symbolic ones
(:func:`attitude_envs.symbolic.linear.model_step_function`) of the matrices of the period the
policy acts at (:func:`decision_matrices`: ``env.unwrapped.decision_model`` when the env has
one, else ``env.unwrapped.model`` with the env's cost), and ``S`` is their discrete Riccati
solution (:func:`attitude_envs.lqr.dlqr`), the unconstrained infinite-horizon cost-to-go. With
that terminal cost the unconstrained minimizer's first move is the discrete LQR's ``−K x_0``
for any horizon (Bitmead, Gevers & Wertz 1990; Scokaert & Rawlings 1998), so where no bound is
active the MPC is the LQR, and where bounds are active it is the constrained optimum over the
horizon (with the LQR's cost-to-go beyond it).

The states are eliminated (condensed QP in the inputs only; Maciejowski 2002, §3.1): the
Hessian ``H`` and the map ``G`` from ``x_0`` to the gradient are computed once from the
symbolic rollout by CasADi's automatic differentiation, and each step solves ``min ½UᵀHU +
(G x_0)ᵀU`` with box bounds by a CasADi ``conic`` QP solver (default qpOASES, Ferreau et al.
2014; warm-started from the shifted previous solution). With ``unconstrained_shortcut`` (the
default) the unconstrained minimizer ``−H⁻¹G x_0`` is used when it satisfies every bound: it
then satisfies the QP's KKT conditions with no active constraint, so it IS the QP's solution
(exact, no solver call).

:attr:`LinearMPCPolicy.solve_times_s` holds the wall time of each decision (s, shortcut or
QP), :attr:`LinearMPCPolicy.qp_solves` how many decisions called the QP solver and
:attr:`LinearMPCPolicy.failures` the QP solves that did not succeed (their iterate is used if
finite and clipped to the bounds, else the LQR action). Requires CasADi.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.lqr import dlqr

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the linear MPC baseline needs CasADi: pip install 'attitude-envs[optimal]'") from exc

from attitude_envs.symbolic.linear import model_step_function

#: QP solvers accepted for ``qp_solver`` (those a CasADi wheel usually ships)
QP_SOLVERS = ("qpoases", "osqp", "qrqp", "proxqp", "highs")


@dataclass(frozen=True)
class DecisionMatrices:
    """The discrete model of one decision period: ``x⁺ = A x + B u``, step cost
    ``xᵀQx + 2xᵀNu + uᵀRu`` (``u`` physical), period ``dt_s`` (s)."""

    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    N: np.ndarray
    dt_s: float


def _field(obj: Any, *names: str) -> Any:
    """The first attribute of ``obj`` among ``names`` (e.g. ``"A"``, ``"A_k"``)."""
    for name in names:
        value = getattr(obj, name, None)
        if value is not None:
            return value
    raise ValueError(f"the env's decision model has none of the attributes {list(names)}")


def decision_matrices(env) -> DecisionMatrices:
    """The matrices of the period the policy acts at, of LinearSystem-v0 ``env``.

    THE ONE PLACE that picks them: ``env.unwrapped.decision_model`` (the k-step matrices
    ``A_k``, ``B_k`` and the exactly discretized cost ``Q_k``, ``R_k``, ``N_k`` of an env
    with a ``control_dt_s`` longer than its model step) when the env has one, else
    ``env.unwrapped.model`` (``A``, ``B``, ``dt_s``) with the env's stage cost
    ``env.unwrapped.cost`` (``Q``, ``R``; no cross term)."""
    base = env.unwrapped
    decision = getattr(base, "decision_model", None)
    if decision is not None:
        A, B = _field(decision, "A", "A_k"), _field(decision, "B", "B_k")
        Q, R = _field(decision, "Q", "Q_k"), _field(decision, "R", "R_k")
        N = getattr(decision, "N", None)
        N = getattr(decision, "N_k", None) if N is None else N
        dt = _field(decision, "dt_s", "control_dt_s")
    else:
        model = getattr(base, "model", None)
        if model is None or getattr(model, "dt_s", None) is None or not hasattr(base, "action_scale"):
            raise ValueError("LinearMPCPolicy needs LinearSystem-v0 (a discrete LinearModel and action_scale)")
        A, B, dt = model.A, model.B, model.dt_s
        cost = getattr(base, "cost", None)
        Q, R = (model.Q, model.R) if cost is None else (cost.Q, cost.R)
        N = None
    A, B = np.asarray(A, float), np.asarray(B, float)
    N = np.zeros(B.shape) if N is None else np.asarray(N, float)
    return DecisionMatrices(A, B, np.asarray(Q, float), np.asarray(R, float), N, float(dt))


class LinearMPCPolicy:
    """Constrained linear MPC with the DARE terminal cost (see the module docstring).

    Parameters: ``horizon_steps`` (decision steps N in the horizon, integer ≥ 1; default 20),
    ``qp_solver`` (one of :data:`QP_SOLVERS` that the installed CasADi has; default
    ``"qpoases"``), ``unconstrained_shortcut`` (use the unconstrained minimizer when it is
    feasible; default True), ``solver_options`` (further CasADi/QP-solver options), ``name``.
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 20,
        qp_solver: str = "qpoases",
        unconstrained_shortcut: bool = True,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        if isinstance(horizon_steps, bool) or int(horizon_steps) != horizon_steps or int(horizon_steps) < 1:
            raise ValueError(f"horizon_steps must be an integer >= 1, got {horizon_steps!r}")
        validation.choice("qp_solver", qp_solver, set(QP_SOLVERS))
        if not casadi.has_conic(qp_solver):
            available = [s for s in QP_SOLVERS if casadi.has_conic(s)]
            raise ValueError(f"qp_solver {qp_solver!r} is not in this CasADi build; accepted: {available}")
        self.name = name or "mpc-linear"
        self.horizon_steps = n_h = int(horizon_steps)
        self.matrices = mats = decision_matrices(env)
        n, m = mats.B.shape
        self._n, self._m = n, m
        self._scale = np.broadcast_to(np.asarray(env.unwrapped.action_scale, dtype=float), (m,)).copy()
        #: the prediction model: the shared symbolic step ``(x, u) -> (x_next, cost)``
        self.model_step = model_step_function(mats.A, mats.B, mats.Q, mats.R, mats.N)
        #: the LQR gain K (u = −K x) and the terminal weight S (discrete Riccati solution)
        self.gain, self.terminal_weight, _ = dlqr(mats.A, mats.B, mats.Q, mats.R, mats.N)
        self.unconstrained_shortcut = validation.flag("unconstrained_shortcut", unconstrained_shortcut)
        # condensed QP: J(U, x0) = ½ UᵀHU + (G x0)ᵀU + const, from the symbolic rollout
        u_sym = casadi.SX.sym("U", m * n_h)
        x0 = casadi.SX.sym("x0", n)
        x, total = x0, 0
        for k in range(n_h):
            x, cost = self.model_step(x, u_sym[k * m : (k + 1) * m])
            total = total + cost
        total = total + casadi.bilin(casadi.DM(self.terminal_weight), x, x)
        grad = casadi.gradient(total, u_sym)
        hess_fn = casadi.Function("H", [u_sym, x0], [casadi.jacobian(grad, u_sym), casadi.jacobian(grad, x0)])
        h_dm, g_dm = hess_fn(np.zeros(m * n_h), np.zeros(n))
        self._H = np.asarray(h_dm)
        self._H = 0.5 * (self._H + self._H.T)
        self._G = np.asarray(g_dm)
        #: the unconstrained minimizer's map: U* = L x0
        self._L = -np.linalg.solve(self._H, self._G)
        opts = {"printLevel": "none"} if qp_solver == "qpoases" else {}
        if qp_solver == "osqp":
            opts = {"osqp": {"verbose": False, "eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 10000}}
        opts["error_on_fail"] = False
        opts.update(solver_options or {})
        sparsity = casadi.DM(self._H).sparsity()
        self._qp = casadi.conic("linear_mpc", qp_solver, {"h": sparsity, "a": casadi.Sparsity(0, m * n_h)}, opts)
        self._lb = np.tile(-self._scale, n_h)
        self._ub = np.tile(self._scale, n_h)
        self.solve_times_s: list[float] = []
        self.qp_solves = 0
        self.failures = 0
        self._guess: np.ndarray | None = None

    def reset(self, seed: int | None = None) -> None:
        self._guess = None

    def plan(self, x0: np.ndarray, use_shortcut: bool | None = None) -> np.ndarray:
        """The optimal physical inputs ``U`` (N × m) of the QP from ``x0``; records the solve."""
        shortcut = self.unconstrained_shortcut if use_shortcut is None else use_shortcut
        t0 = time.perf_counter()
        u_free = self._L @ x0
        if shortcut and np.all(u_free >= self._lb) and np.all(u_free <= self._ub):
            u = u_free
        else:
            guess = self._guess if self._guess is not None else np.clip(u_free, self._lb, self._ub)
            sol = self._qp(h=self._H, g=self._G @ x0, lbx=self._lb, ubx=self._ub, x0=guess)
            self.qp_solves += 1
            if not self._qp.stats().get("success", False):
                self.failures += 1
            u = np.asarray(sol["x"]).ravel()
            if not np.all(np.isfinite(u)):
                u = np.clip(np.tile(-self.gain @ x0, self.horizon_steps), self._lb, self._ub)
            u = np.clip(u, self._lb, self._ub)
        self.solve_times_s.append(time.perf_counter() - t0)
        m = self._m
        self._guess = np.r_[u[m:], u[-m:]]  # warm start: shifted, last move repeated
        return u.reshape(self.horizon_steps, m)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step from ``info["measured"]`` (the state; not a batch)."""
        x0 = np.asarray(info["measured"], dtype=float)[: self._n]
        if not np.all(np.isfinite(x0)):
            return np.zeros(self._m, dtype=np.float32)  # a dropout: nothing to predict from
        u = self.plan(x0)
        return np.clip(u[0] / self._scale, -1.0, 1.0).astype(np.float32)
