"""Fault-tolerant nonlinear MPC: the IMM fault detector of :mod:`attitude_envs.estimation.fdi`
feeding the MPC of :mod:`baselines.mpc` (active fault-tolerant control by reconfiguration).

The policy is :class:`~baselines.mpc.MPCPolicy` on the nominal model while the IMM bank
(:class:`~attitude_envs.estimation.fdi.ActuatorFDI`) sees no fault. The FDI is run exactly as
:class:`~baselines.fault_tolerant.FaultTolerantLQRPolicy` runs it (that policy is composed here
as the monitor): it is fed only what the flight computer knows — its own commanded motor
torques (``info["commanded"]``), the measured rate and wheel speeds (``info["measured"]``),
the time and, on an air bearing, the nominal offset torque at the measured attitude — and it
is restarted with each isolated fault known, so a second wheel is isolated after the first.

When wheel ``i`` is isolated at effectiveness ``e_i`` (0: an outage) the MPC's prediction model
becomes the shared symbolic gyrostat with that effectiveness
(:func:`attitude_envs.symbolic.gyrostat.with_effectiveness`: wheel ``i`` delivers ``e_i`` of
its command), and

* wheel action frame: the failed wheels' action variables are fixed at 0 (their columns
  removed: the MPC commands nothing to them); a degraded wheel keeps its variable;
* body action frame (the env allocates every demand over all wheels, ``u = −A⁺ a τ_max``):
  the demand stays 3-dimensional; the per-wheel limit ``|A⁺ a| ≤ 1`` is dropped for the
  failed wheels (their command is lost anyway) and kept for the others;
* the terminal cost is the infinite-horizon cost-to-go of the linearization with the
  degraded actuators (:func:`degraded_terminal_weight`). With two of four pyramid wheels out,
  or the air bearing's yaw wheel out, the linearization at rest is not stabilizable (one body
  axis has no torque and the gyroscopic coupling vanishes at rest). Our choice: the discrete
  Riccati solution of the linearization restricted to its controllable subspace (Kalman
  decomposition, :func:`baselines.fault_tolerant.controllable_subspace`; exact ZOH
  discretization of plant and cost, Franklin, Powell & Workman 1998, ch. 9) on that subspace,
  plus — ``uncontrollable_weight="nominal"`` (default) — the nominal design's Riccati matrix
  projected on the uncontrollable complement, so the terminal cost still charges an attitude
  or rate error about the lost axis (the healthy spacecraft's cost-to-go: a lower bound of the
  degraded one) instead of ignoring it (``"zero"``). The stage cost over the horizon is the
  env's exact cost, so the nonlinear (gyroscopic) authority over the lost axis is used by the
  optimizer within the horizon.

Terminal costs from the Riccati equation of the linearization follow Mayne et al. (2000);
FDI + reconfiguration follows Zhang & Jiang (2008). Works on ReactionWheel-v0 (``action_frame``
``"wheel"`` or ``"body"``) and AirBearing-v0, one env at a time; at any ``control_dt_s`` the env
is built with (the FDI and the MPC use the env's period). Never reads ``info["truth"]``.
Requires CasADi.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import casadi
import numpy as np

from attitude_envs.linearization import LinearModel
from attitude_envs.lqr import dlqr
from attitude_envs.symbolic.gyrostat import step_function, with_effectiveness
from baselines.fault_tolerant import FaultTolerantLQRPolicy, _orth, controllable_subspace
from baselines.mpc import MPCPolicy

UNCONTROLLABLE_WEIGHTS = ("nominal", "zero")


def degraded_terminal_weight(
    model,
    effectiveness: Sequence[float],
    control_dt_s: float,
    nominal_weight: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Terminal weight ``P`` (n_x × n_x, on the cost's error state; J per (error-state unit)²)
    of the MPC with the wheels' assumed ``effectiveness`` (N values in [0, 1]) and the
    orthonormal basis (n_x × r) of the controllable subspace it was designed on.

    The continuous linearization of ``model`` (:class:`ReactionWheelModel`) about the target
    at rest with wheel torques ``u = −(A E)⁺ U v``, ``v`` the body torque (N·m) in an
    orthonormal basis ``U`` of ``range(A E)`` (what the healthy wheels can deliver; the input
    of :class:`~baselines.fault_tolerant.FaultTolerantLQRPolicy`), the cost's ``R`` on the
    delivered torque, is restricted to its controllable subspace ``V`` (Kalman decomposition),
    discretized exactly over ``control_dt_s`` (ZOH: plant and cost, with the cross term) and
    solved by the discrete Riccati equation: ``P = V S Vᵀ``. With ``nominal_weight`` (the
    healthy design's ``P``), ``C P_nom C`` is added, ``C = I − V Vᵀ`` the projector on the
    uncontrollable complement (zero when the degraded linearization is controllable).
    ValueError for a bad ``effectiveness`` or ``control_dt_s``."""
    p = model.params
    eff = np.asarray(effectiveness, dtype=float)
    if eff.shape != (p.n_wheels,) or not np.all((eff >= 0.0) & (eff <= 1.0)):
        raise ValueError(f"effectiveness must be {p.n_wheels} values in [0, 1] (one per wheel), got {effectiveness!r}")
    if not float(control_dt_s) > 0.0:
        raise ValueError(f"control_dt_s must be > 0 (s), got {control_dt_s!r}")
    lin = model.linearize(input="wheel")
    n_x = lin.A.shape[0]
    a_eff = p.wheel_axes @ np.diag(eff)
    u_basis = _orth(a_eff)  # 3 × r: the body torques the wheels can still deliver
    if u_basis.shape[1] == 0:
        basis = np.zeros((n_x, 0))
        weight = np.zeros((n_x, n_x))
    else:
        to_cmd = -np.linalg.pinv(a_eff) @ u_basis  # v -> commanded motor torques (N·m)
        b_v = lin.B @ np.diag(eff) @ to_cmd
        if model.cost_input == "body":
            r_v = u_basis.T @ model.cost.R @ u_basis
        else:
            g = np.diag(eff) @ to_cmd
            r_v = g.T @ model.cost.R @ g
        basis = controllable_subspace(lin.A, b_v)
        reduced = LinearModel(basis.T @ lin.A @ basis, basis.T @ b_v, basis.T @ lin.Q @ basis, r_v)
        reduced = reduced.discretize(float(control_dt_s))
        _, s_r, _ = dlqr(reduced.A, reduced.B, reduced.Q, reduced.R, reduced.N)
        weight = basis @ s_r @ basis.T
    if nominal_weight is not None:
        c = np.eye(n_x) - basis @ basis.T
        weight = weight + c @ np.asarray(nominal_weight, dtype=float) @ c
    return 0.5 * (weight + weight.T), basis


class FaultTolerantMPCPolicy(MPCPolicy):
    """Nonlinear MPC + IMM FDI + reconfiguration of its actuator model (module docstring).

    Parameters: ``horizon_steps``, ``max_iter``, ``tol``, ``solver_options``, ``model_substeps`` (as
    :class:`~baselines.mpc.MPCPolicy`), ``degraded_effectiveness`` (the FDI's fault levels,
    default ``(0.0, 0.5)``: outage and half effectiveness), ``fdi`` (further
    :class:`~attitude_envs.estimation.fdi.ActuatorFDI` keywords), ``uncontrollable_weight``
    (``"nominal"`` or ``"zero"``: the terminal weight on the degraded linearization's
    uncontrollable subspace, see :func:`degraded_terminal_weight`), ``coarse_steps`` (≥ 0,
    default 0: off) stages of ``coarse_dt_s`` (s, default 1.0) integrated by
    ``coarse_substeps`` RK4 sub-steps appended to the horizon after a reconfiguration (a
    longer look-ahead; the nominal horizon is never changed), ``name`` (default ``"mpc-ft"``).

    :attr:`effectiveness` is the assumed effectiveness per wheel (1 healthy), :attr:`isolated`
    the FDI's isolations so far (``{"index", "time_s", "effectiveness", "probability"}``),
    :attr:`reconfigure_times_s` the wall time (s) of each rebuild of the NLP after an
    isolation (not in :attr:`solve_times_s`).
    """

    def __init__(
        self,
        env,
        horizon_steps: int = 20,
        max_iter: int = 100,
        tol: float = 1e-6,
        solver_options: dict[str, Any] | None = None,
        degraded_effectiveness: float | Sequence[float] = (0.0, 0.5),
        fdi: dict[str, Any] | None = None,
        uncontrollable_weight: str = "nominal",
        coarse_steps: int = 0,
        coarse_dt_s: float = 1.0,
        coarse_substeps: int = 2,
        name: str | None = None,
        model_substeps: int | None = None,
    ) -> None:
        if int(coarse_steps) < 0:
            raise ValueError(f"coarse_steps must be an integer >= 0, got {coarse_steps!r}")
        if not float(coarse_dt_s) > 0.0:
            raise ValueError(f"coarse_dt_s must be > 0 (s), got {coarse_dt_s!r}")
        if int(coarse_substeps) < 1:
            raise ValueError(f"coarse_substeps must be an integer >= 1, got {coarse_substeps!r}")
        self.coarse_steps, self.coarse_dt_s, self.coarse_substeps = (
            int(coarse_steps),
            float(coarse_dt_s),
            int(coarse_substeps),
        )
        self._coarse_active = False
        if uncontrollable_weight not in UNCONTROLLABLE_WEIGHTS:
            raise ValueError(
                f"uncontrollable_weight must be one of {list(UNCONTROLLABLE_WEIGHTS)}, got {uncontrollable_weight!r}"
            )
        super().__init__(
            env, horizon_steps, max_iter, tol, solver_options, name=name or "mpc-ft", model_substeps=model_substeps
        )
        self.uncontrollable_weight = uncontrollable_weight
        #: the FDI and the fault-tolerant LQR (fallback action of a failed solve)
        self.monitor = FaultTolerantLQRPolicy(env, "zoh", degraded_effectiveness, fdi)
        self._nominal = self._configuration()
        self._configurations: dict[tuple[float, ...], tuple] = {self._key(self._nominal_eff()): self._nominal}
        self._active = self._key(self._nominal_eff())
        self._last_fallback: np.ndarray | None = None
        self.reconfigure_times_s: list[float] = []

    # ------------------------------------------------------------------ state
    @property
    def effectiveness(self) -> np.ndarray:
        """The assumed effectiveness per wheel (1 healthy, 0 an outage)."""
        return self.monitor.effectiveness

    @property
    def isolated(self) -> list[dict[str, Any]]:
        """The FDI's isolations so far this episode."""
        return self.monitor.isolated

    def _nominal_eff(self) -> np.ndarray:
        return np.ones(self._model.params.n_wheels)

    @staticmethod
    def _key(eff: np.ndarray) -> tuple[float, ...]:
        return tuple(float(e) for e in eff)

    #: what one actuator configuration of the MPC consists of (cached per effectiveness pattern)
    _CONFIGURATION = (
        "horizon_steps",
        "_coarse_active",
        "model_parameters",
        "model_step",
        "terminal_weight",
        "_solver",
        "_lbx",
        "_ubx",
        "_lbg",
        "_ubg",
    )

    def _configuration(self) -> tuple:
        return tuple(getattr(self, name) for name in self._CONFIGURATION)

    def _apply(self, config: tuple) -> None:
        for name, value in zip(self._CONFIGURATION, config, strict=True):
            setattr(self, name, value)

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.monitor.reset(seed)
        self._apply(self._nominal)
        self._active = self._key(self._nominal_eff())

    # ------------------------------------------------------------------ acting
    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one step (not a batch); reads ``info["measured"]``,
        ``info["commanded"]`` and ``info["time_s"]``, never the truth."""
        # the monitor updates the FDI with the step that just ended and gives the
        # fault-tolerant LQR's action, the fallback of a failed solve
        self._last_fallback = self.monitor.act(obs, info)
        key = self._key(self.effectiveness)
        if key != self._active:
            self._reconfigure(key)
        a = super().act(obs, info)
        if self._frame != "body":
            a = np.where(np.asarray(key) == 0.0, 0.0, a).astype(np.float32)  # nothing to a failed wheel
        return a

    def _stage_dynamics(self, y, a, target):
        """The degraded horizon with ``coarse_steps``: the first ``horizon_steps`` stages at the
        control period, then ``coarse_steps`` stages of ``coarse_dt_s`` (action held, the
        env's cost integrated by ``coarse_substeps`` RK4 sub-steps): a longer look-ahead for
        the nonholonomic manoeuvres about an unactuated axis at the same NLP size."""
        if not self._coarse_active:
            return super()._stage_dynamics(y, a, target)
        n_f = self._nominal[0]
        n_c = y.shape[1] - n_f
        fine_y, fine_c = self.model_step.map(n_f)(
            y[:, :n_f], a[:, :n_f], casadi.DM.zeros(1, n_f), casadi.repmat(target, 1, n_f)
        )
        coarse_params = replace(
            self.model_parameters,
            n_substeps=self.coarse_substeps,
            integrator_dt_s=self.coarse_dt_s / self.coarse_substeps,
        )
        coarse = step_function(coarse_params, smooth=True)
        coarse_y, coarse_c = coarse.map(n_c)(
            y[:, n_f:], a[:, n_f:], casadi.DM.zeros(1, n_c), casadi.repmat(target, 1, n_c)
        )
        return casadi.horzcat(fine_y, coarse_y), casadi.horzcat(fine_c, coarse_c)

    def _fallback_action(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self._last_fallback if self._last_fallback is not None else self._lqr.act(obs, info)

    def _reconfigure(self, key: tuple[float, ...]) -> None:
        """Switch the NLP to the assumed effectiveness ``key`` (built once per episode set)."""
        t0 = time.perf_counter()
        old_horizon = self.horizon_steps
        if key not in self._configurations:
            eff = np.asarray(key)
            base_params = self._nominal[2]
            self.model_parameters = with_effectiveness(base_params, eff)
            self.model_step = step_function(self.model_parameters, smooth=True)
            nominal_p = self._nominal[4] if self.uncontrollable_weight == "nominal" else None
            self.terminal_weight, _ = degraded_terminal_weight(self._model, eff, self._model.control_dt_s, nominal_p)
            if self.coarse_steps:
                self.horizon_steps = self._nominal[0] + self.coarse_steps
                self._coarse_active = True
            self._build_solver()
            failed = np.flatnonzero(eff == 0.0)
            n_h = self.horizon_steps
            if self._frame == "body":  # no per-wheel limit on a wheel whose command is lost
                n = self._model.params.n_wheels
                rows = self._n_eq + (failed[:, None] + n * np.arange(n_h)[None, :]).ravel()
                self._lbg[rows], self._ubg[rows] = -np.inf, np.inf
            else:  # the failed wheels' action variables fixed at 0
                cols = (failed[:, None] + self._n_u * np.arange(n_h)[None, :]).ravel()
                self._lbx[cols], self._ubx[cols] = 0.0, 0.0
            self._configurations[key] = self._configuration()
        shape_changed = self._configurations[key][0] != old_horizon
        self._apply(self._configurations[key])
        self._active = key
        if shape_changed:
            self._guess = None  # a new horizon: restart from the LQR's rollout
        if self._guess is not None and self._frame != "body":
            a_guess, y_guess = self._guess
            a_guess = a_guess.copy()
            a_guess[np.asarray(key) == 0.0, :] = 0.0
            self._guess = (a_guess, y_guess)
        self.reconfigure_times_s.append(time.perf_counter() - t0)
