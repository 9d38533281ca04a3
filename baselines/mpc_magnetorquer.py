"""Nonlinear model-predictive control (MPC) of Magnetorquer-v0 (Sadigh, Kashaninia & Dehghan 2022
nano-satellite: three magnetorquers and one y wheel on an elliptic orbit) on its NOMINAL model.

At every control step (the env's ``control_dt_s``, any multiple of its ``integrator_dt_s``) the
policy solves, from the measured state ``y_0 = [q, ω_bo, Ω]`` (``info["measured"]``),

    min_{a_0..a_{N−1}}  Σ_k ℓ_k(y_k, a_k) + T_hold · x(y_N)ᵀ Q x(y_N)
    s.t.  y_{k+1} = f_k(y_k, ê ⊙ a_k; d̂),  −1 ≤ a_k ≤ 1

and applies ``a_0`` (receding horizon; Rawlings, Mayne & Diehl 2017, ch. 1–2). ``f_k`` and ``ℓ_k``
are the SHARED symbolic model of the env (:func:`attitude_envs.symbolic.magnetorquer.nominal_step_function`,
the step J* is built from, with no faults): RK4 sub-steps of the gyrostat equations (Sadigh et al.
2022 eqs. 1–8) and the env's own stage cost ``∫ xᵀQx + uᵀRu dt`` by the same quadrature, with what
a controller may know: the nominal inertia (no ΔJ(t) of eq. 35, no drawn dispersion), the
episode's orbit (the known ephemeris) and the field model along it
(:func:`~attitude_envs.symbolic.magnetorquer.nominal_step_parameters`: the field is a known
function of time), the reference, the actuator limits as NLP bounds on the normalized action.
The wheel's momentum limit is in the step (torque blocked); the tumble limit is not imposed.

Terminal cost: ``T_hold · x_Nᵀ Q x_N``, the running cost of the terminal error state held for
``terminal_hold_s`` seconds (the env's own ``termination_cost="hold"`` charge): a scaled Q. (The
linearization about the reference is time-varying through the field, so a stationary Riccati
solution does not exist.) The magnetorquers are weak (≈1.5e-5 N·m, the size of the eq. 39
disturbance), so an error left at the horizon's end costs for a long time: on the campaign's
slew (seeds 0 and 2, 2 s period, 30 s horizon) Σ J / Σ J* was 1.470, 1.445, 1.396, 1.367, 1.352
and 1.347 with ``T_hold`` = 0, 10, 60, 200, 600 and 1500 s; the default is 1000 s.

Unknown torques: a disturbance observer on the prediction residual. After each step the model
is re-run from the previous measured state with the applied action; the rate residual
``r = ω_measured − ω_predicted`` is mapped to a body torque by the model's own sensitivity
``G = ∂ω_{k+1}/∂d`` (CasADi Jacobian of the step, ≈ I_eff⁻¹ Δt), ``d_raw = d̂ + G⁻¹ r``, and
low-pass filtered, ``d̂ ← d̂ + α (d_raw − d̂)`` (a discrete disturbance observer in the sense of
Chen, Yang, Guo & Li 2016, "Disturbance-observer-based control and related methods", IEEE TIE
63(2), eq. for the lumped disturbance; the estimate enters the prediction as a constant input
disturbance over the horizon as in offset-free MPC, Pannocchia & Rawlings 2003, AIChE J. 49(2)).
The estimate lumps the paper's disturbance (eq. 39), ΔJ(t) (eq. 35) and, with
``estimate_effectiveness=False``, the actuator faults. With ``estimate_effectiveness=True`` the
magnetorquer effectiveness ``ê`` is estimated jointly with ``d̂`` by recursive least squares
with exponential forgetting (Ljung & Söderström 1983, ch. 2) on the same residual, regressors
``[G, ∂ω_{k+1}/∂e]`` from the step's Jacobian, ``ê`` clipped to ``[e_min, 1]``.

Faults are left to the disturbance observer (the default ``estimate_effectiveness=False``): on
the eq. 40 faults (seeds 0 and 2, 2 s period, 30 s horizon, ``T_hold`` 600 s) the lumped
estimate gave Σ J / Σ J* = 1.309 and the joint RLS of ``d̂, ê`` 1.508 (λ = 0.98, untuned: the
effectiveness regressors are nearly collinear with the disturbance while the dipoles sit at
their limits, and ΔJ(t) of eq. 35 feeds the same residual).

Measured (``python -m benchmarks.mpc_magnetorquer_eval --seeds 0-19``: the campaign's slew,
300 s, 3 s period, 45 s horizon, RK4 model sub-steps of 3 s, ``T_hold`` 1000 s; 2 shared CPU
cores): Σ J / Σ J* = 1.397 healthy and 1.347 with the eq. 40 faults; median solve 0.14 s and
0.17 s (5–6 % of the period), maximum 1.9 s; 12 and 7 of 2000 solves stopped at ``max_iter``.

The NLP is transcribed by direct multiple shooting (Bock & Plitt 1984) and solved by IPOPT
(Wächter & Biegler 2006) through CasADi (Andersson et al. 2019), warm-started from the previous
solution shifted by one step (the first solve from a rollout of the zero action).
:attr:`MagnetorquerMPCPolicy.solve_times_s` holds the wall time of each solve (s),
:attr:`MagnetorquerMPCPolicy.failures` the solves IPOPT did not finish (their iterate is used
if finite, else the shifted previous plan, else zero). Reads only ``info["measured"]`` and
``info["time_s"]`` (never the truth or the faults); one env at a time. Requires CasADi
(``pip install 'attitude-envs[optimal]'``).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from attitude_envs import validation
from attitude_envs.symbolic import magnetorquer as sym

try:
    import casadi
except ImportError as exc:  # casadi is an optional extra
    raise ImportError("the magnetorquer MPC needs CasADi: pip install 'attitude-envs[optimal]'") from exc

from attitude_envs.symbolic.problem import QUIET, SOLVED  # noqa: E402  (after the CasADi check: its message names this MPC)
from baselines.mpc import shifted  # noqa: E402

_N_Y, _N_U = 8, 4


class MagnetorquerMPCPolicy:
    """Nonlinear MPC of Magnetorquer-v0 on its nominal symbolic model with a disturbance
    observer (see the module docstring).

    Parameters:

    * ``horizon_s``: prediction horizon (s, ≥ the control period; rounded to whole periods;
      default 45).
    * ``model_integrator_dt_s``: RK4 sub-step of the prediction model (s; divides the control
      period; default: the period split into the fewest equal sub-steps of at most 3 s). The
      attitude dynamics are slow: at a 2 s period the MPC's episode J was the same to 7 digits
      with 1 s and 2 s model sub-steps (seeds 0 and 2), at 2–4× less solve time than 0.5 s.
    * ``terminal_hold_s``: the terminal cost is the terminal error's running cost held this
      long (s, ≥ 0; default 1000: see the module docstring).
    * ``disturbance_gain``: the observer's low-pass gain α per control step, in (0, 1]
      (default 0.5; 1 takes the last step's residual torque as is).
    * ``estimate_effectiveness``: also estimate the magnetorquer effectiveness (RLS; default
      False), with ``forgetting`` λ in (0, 1] (default 0.98) and ``min_effectiveness`` in
      [0, 1) (default 0.2, the clip of ê).
    * ``max_iter``, ``tol``: IPOPT's iteration limit and tolerance; ``solver_options``: further
      CasADi/IPOPT options; ``name``.
    """

    def __init__(
        self,
        env,
        horizon_s: float = 45.0,
        model_integrator_dt_s: float | None = None,
        terminal_hold_s: float = 1000.0,
        disturbance_gain: float = 0.5,
        estimate_effectiveness: bool = False,
        forgetting: float = 0.98,
        min_effectiveness: float = 0.2,
        max_iter: int = 50,
        tol: float = 1e-6,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        base = env.unwrapped
        if getattr(base, "env_name", None) != "Magnetorquer-v0":
            raise ValueError(f"env must be Magnetorquer-v0, got {getattr(base, 'env_name', type(base).__name__)!r}")
        self.name = name or "mpc-magnetorquer"
        self._env = base
        self.control_dt_s = dt = float(base.control_dt_s)
        horizon_s = validation.positive("horizon_s", horizon_s)
        if horizon_s < dt - 1e-9:
            raise ValueError(f"horizon_s must be >= the control period {dt} s, got {horizon_s!r}")
        self.horizon_steps = n_h = max(1, round(horizon_s / dt))
        if model_integrator_dt_s is None:  # RK4 sub-steps of at most 3 s (see the class docstring)
            model_integrator_dt_s = dt / math.ceil(dt / 3.0 - 1e-9)
        self.model_integrator_dt_s, self._n_sub = sym.nominal_substeps(base, dt, model_integrator_dt_s)
        self.terminal_hold_s = validation.nonnegative("terminal_hold_s", terminal_hold_s)
        self.disturbance_gain = float(disturbance_gain)
        if not (0.0 < self.disturbance_gain <= 1.0):
            raise ValueError(f"disturbance_gain must be in (0, 1], got {disturbance_gain!r}")
        self.estimate_effectiveness = validation.flag("estimate_effectiveness", estimate_effectiveness)
        self.forgetting = float(forgetting)
        if not (0.0 < self.forgetting <= 1.0):
            raise ValueError(f"forgetting must be in (0, 1], got {forgetting!r}")
        self.min_effectiveness = float(min_effectiveness)
        if not (0.0 <= self.min_effectiveness < 1.0):
            raise ValueError(f"min_effectiveness must be in [0, 1), got {min_effectiveness!r}")
        if int(max_iter) < 1:
            raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")

        #: the prediction model: the shared symbolic step of the healthy nominal plant
        self.model_step = sym.nominal_step_function(base, dt, self.model_integrator_dt_s)
        self._n_p = self.model_step.size1_in(2)
        self._dist_cols = sym.disturbance_columns(self._n_sub)
        self._error = sym.error_function(base)
        q_mat = np.asarray(base.model.cost.Q, dtype=float)
        #: terminal weight on the error state x_N (6×6): ``terminal_hold_s · Q``
        self.terminal_weight = self.terminal_hold_s * q_mat

        # the observer's model: y_next(y, a, p, d, e) and its sensitivities to d and e
        ys, as_, ps = casadi.SX.sym("y", _N_Y), casadi.SX.sym("a", _N_U), casadi.SX.sym("p", self._n_p)
        ds, es = casadi.SX.sym("d", 3), casadi.SX.sym("e", 3)
        p_d = casadi.SX(ps)
        for j, col in enumerate(self._dist_cols):
            p_d[int(col)] = ds[j % 3]
        y_next, _ = self.model_step(ys, casadi.vertcat(es * as_[:3], as_[3]), p_d)
        w_next = y_next[4:7]
        self._observer = casadi.Function(
            "observer",
            [ys, as_, ps, ds, es],
            [w_next, casadi.jacobian(w_next, ds), casadi.jacobian(w_next, es)],
        )

        # the NLP: multiple shooting over n_h steps, parameters [y0, P (n_p × n_h), e (3)]
        y = casadi.MX.sym("Y", _N_Y, n_h + 1)
        a = casadi.MX.sym("A", _N_U, n_h)
        y0 = casadi.MX.sym("y0", _N_Y)
        pars = casadi.MX.sym("P", self._n_p, n_h)
        eff = casadi.MX.sym("e", 3)
        a_eff = casadi.vertcat(a[:3, :] * casadi.repmat(eff, 1, n_h), a[3, :])
        y_next, costs = self.model_step.map(n_h)(y[:, :n_h], a_eff, pars)
        c_end = pars[self._n_p - sym.N_FIELDS :, n_h - 1]  # the last context of the last step: its end
        x_n = self._error(y[:, n_h], c_end)
        objective = casadi.sum2(costs) + casadi.bilin(casadi.DM(self.terminal_weight), x_n, x_n)
        constraints = casadi.vertcat(y[:, 0] - y0, casadi.vec(y[:, 1:] - y_next))
        nlp = {
            "x": casadi.vertcat(casadi.vec(a), casadi.vec(y)),
            "p": casadi.vertcat(y0, casadi.vec(pars), eff),
            "f": objective,
            "g": constraints,
        }
        opts = {
            **QUIET,
            "expand": True,
            "ipopt.mu_strategy": "adaptive",
            "ipopt.max_iter": int(max_iter),
            "ipopt.tol": float(validation.positive("tol", tol)),
        }
        opts.update(solver_options or {})
        self._solver = casadi.nlpsol("mpc_magnetorquer", "ipopt", nlp, opts)
        n_a = _N_U * n_h
        self._n_a = n_a
        self._lbx = np.r_[-np.ones(n_a), np.full(_N_Y * (n_h + 1), -np.inf)]
        self._ubx = np.r_[np.ones(n_a), np.full(_N_Y * (n_h + 1), np.inf)]
        self._lbg = self._ubg = np.zeros(_N_Y * (n_h + 1))
        self.solve_times_s: list[float] = []
        #: IPOPT iterations of each solve
        self.iterations: list[int] = []
        self.failures = 0
        self.reset()

    # ------------------------------------------------------------------ policy interface
    def reset(self, seed: int | None = None) -> None:
        """Forget the episode: plan, estimates and the cached time contexts (the orbit is
        read again at the next :meth:`act`)."""
        self._guess: tuple[np.ndarray, np.ndarray] | None = None
        self._constants: tuple[np.ndarray, np.ndarray] | None = None
        self._params: dict[int, np.ndarray] = {}
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # y, a, p of the last step
        #: the disturbance estimate d̂ (N·m, body axes)
        self.disturbance_nm = np.zeros(3)
        #: the magnetorquer effectiveness estimate ê (1: healthy)
        self.effectiveness = np.ones(3)
        self._cov = np.diag(np.r_[np.full(3, 1e-8), np.full(3, 1.0)])  # RLS covariance of [d (N·m), e]
        self.history: dict[str, list] = {"time_s": [], "disturbance_nm": [], "effectiveness": []}

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action ``[m_x, m_y, m_z, T_w] / limits`` for one step, from
        ``info["measured"]`` (attitude, ω_bo in rad/s, wheel speed in rad/s) and
        ``info["time_s"]`` (s)."""
        m = info["measured"]
        y0 = np.r_[m["attitude"], m["rate_rad_s"], m["wheel_speed_rad_s"]].astype(float)
        t = float(info["time_s"])
        k = round(t / self.control_dt_s)
        if k == 0 or self._constants is None:
            self._constants = sym.nominal_constants(self._env)
            self._params = {}
        if not np.all(np.isfinite(y0)):  # a dropout: nothing to predict from
            self._last = None
            return self._fallback()
        self._update_estimates(y0)
        pars = self._horizon_params(k)
        a_guess, y_guess = self._initial_guess(y0, pars)
        t0 = time.perf_counter()
        sol = self._solver(
            x0=np.r_[a_guess.ravel(order="F"), y_guess.ravel(order="F")],
            p=np.r_[y0, pars.ravel(order="F"), self.effectiveness],
            lbx=self._lbx,
            ubx=self._ubx,
            lbg=self._lbg,
            ubg=self._ubg,
        )
        self.solve_times_s.append(time.perf_counter() - t0)
        stats = self._solver.stats()
        self.iterations.append(int(stats.get("iter_count", -1)))
        if stats["return_status"] not in SOLVED:
            self.failures += 1
        w = np.asarray(sol["x"]).ravel()
        if not np.all(np.isfinite(w)):
            action = self._fallback()
            self._guess = None
        else:
            a_opt = w[: self._n_a].reshape(_N_U, -1, order="F")
            y_opt = w[self._n_a :].reshape(_N_Y, -1, order="F")
            action = np.clip(a_opt[:, 0], -1.0, 1.0)
            self._guess = shifted(a_opt, y_opt)  # warm start of the next step
        action = action.astype(np.float32)
        self._last = (y0, action.astype(float), pars[:, 0].copy())
        self.history["time_s"].append(t)
        self.history["disturbance_nm"].append(self.disturbance_nm.copy())
        self.history["effectiveness"].append(self.effectiveness.copy())
        return action

    # ------------------------------------------------------------------ internals
    def _fallback(self) -> np.ndarray:
        """The shifted previous plan's first action, else zero."""
        if self._guess is not None:
            return np.clip(self._guess[0][:, 0], -1.0, 1.0).astype(np.float32)
        return np.zeros(_N_U, dtype=np.float32)

    def _step_params(self, k: int) -> np.ndarray:
        """The nominal parameter row of step ``k`` (cached per episode), disturbance zero."""
        row = self._params.get(k)
        if row is None:
            row = sym.nominal_step_parameters(
                self._env, [k * self.control_dt_s], self.control_dt_s, self.model_integrator_dt_s, self._constants
            )[0]
            self._params[k] = row
        return row

    def _horizon_params(self, k: int) -> np.ndarray:
        """``(n_p, N)``: the rows of steps ``k … k+N−1`` with d̂ in their disturbance entries."""
        pars = np.column_stack([self._step_params(k + i) for i in range(self.horizon_steps)])
        pars[self._dist_cols, :] = np.tile(self.disturbance_nm, 2 * self._n_sub + 1)[:, None]
        return pars

    def _update_estimates(self, y0: np.ndarray) -> None:
        """The observer: the residual of the last step's prediction from its measured start
        with the applied action and the current estimates, turned into d̂ (and ê)."""
        if self._last is None:
            return
        y_prev, a_prev, p_prev = self._last
        w_pred, g_d, g_e = (
            np.asarray(v) for v in self._observer(y_prev, a_prev, p_prev, self.disturbance_nm, self.effectiveness)
        )
        r = y0[4:7] - w_pred.ravel()
        if not self.estimate_effectiveness:
            self.disturbance_nm = self.disturbance_nm + self.disturbance_gain * np.linalg.solve(g_d, r)
            return
        # RLS with forgetting on θ = [d, e]: r ≈ G_d (d − d̂) + G_e (e − ê)
        h = np.hstack([g_d, g_e])
        lam = self.forgetting
        s = h @ self._cov @ h.T + np.eye(3) * 1e-14
        gain = self._cov @ h.T @ np.linalg.inv(s)
        step = gain @ r
        self._cov = (self._cov - gain @ h @ self._cov) / lam
        self.disturbance_nm = self.disturbance_nm + step[:3]
        self.effectiveness = np.clip(self.effectiveness + step[3:], self.min_effectiveness, 1.0)

    def _initial_guess(self, y0: np.ndarray, pars: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The shifted previous solution (its first state replaced by ``y0``), or (first
        solve) the zero action's rollout on the model."""
        if self._guess is not None:
            a_guess, y_guess = self._guess
            y_guess = y_guess.copy()
            y_guess[:, 0] = y0
            return a_guess, y_guess
        n_h = self.horizon_steps
        a_guess = np.zeros((_N_U, n_h))
        y_guess = np.zeros((_N_Y, n_h + 1))
        y_guess[:, 0] = y0
        for i in range(n_h):
            y_next, _ = self.model_step(y_guess[:, i], a_guess[:, i], pars[:, i])
            y_guess[:, i + 1] = np.asarray(y_next).ravel()
        return a_guess, y_guess
