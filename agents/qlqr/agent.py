"""The Q-learning LQR agent, :class:`QLearningLQR`: validates its options, composes the
strategies they name and exposes the policy interface.

Which option selects which strategy (the dispatch tables below, the only place the names
meet the classes):

* ``method`` — :data:`METHODS`: ``"value_iteration"`` (:mod:`agents.qlqr.value_iteration`),
  ``"policy_iteration"`` and ``"lspi"`` (:mod:`agents.qlqr.policy_iteration`; LSPI reuses
  one batch), the latter with a ``stabilize`` strategy from :data:`STABILIZERS`
  (:mod:`agents.qlqr.stabilizers`);
* ``estimator`` — :data:`ESTIMATORS`: ``"batch"``, ``"rls"`` (:mod:`agents.qlqr.estimators`);
* ``td_estimator`` — :data:`TD_ESTIMATORS`: ``"lstd"``, ``"lstd_gls"``, ``"ols"``,
  ``"matrix_bellman"`` (:mod:`agents.qlqr.evaluation`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from threadpoolctl import threadpool_limits

from agents.qlqr.basis import QuadraticBasis
from agents.qlqr.certainty_equivalence import ce_gain
from agents.qlqr.context import Context
from agents.qlqr.data import EnvAdapter, Transitions
from agents.qlqr.estimators import BatchLeastSquares, Estimator, RecursiveLeastSquares
from agents.qlqr.evaluation import LSTDQ, BellmanResidualOLS, FeasibleGLSLSTDQ, MatrixBellman, PolicyEvaluation
from agents.qlqr.nominal import optimal_gain as nominal_optimal_gain
from agents.qlqr.nominal import reporting_model
from agents.qlqr.policy_iteration import PolicyIteration
from agents.qlqr.sampling import Sampler
from agents.qlqr.stabilizers import DiscountAnnealing, Stabilizer, ValueIterationWarmup
from agents.qlqr.trace import Trace
from agents.qlqr.truth import relative_error
from agents.qlqr.value_iteration import ValueIteration
from attitude_envs import validation

Method = ValueIteration | PolicyIteration

#: ``estimator`` → factory(agent) of the least-squares strategy
ESTIMATORS: dict[str, Callable[[QLearningLQR], Estimator]] = {
    "batch": lambda agent: BatchLeastSquares(),
    "rls": lambda agent: RecursiveLeastSquares(agent.rls_initial_covariance, agent.rls_forgetting),
}
#: ``td_estimator`` → policy-evaluation strategy class, built with (basis, estimator)
TD_ESTIMATORS: dict[str, Callable[[QuadraticBasis, Estimator], PolicyEvaluation]] = {
    "lstd": LSTDQ,
    "lstd_gls": FeasibleGLSLSTDQ,
    "ols": BellmanResidualOLS,
    "matrix_bellman": MatrixBellman,
}
#: ``stabilize`` → factory(agent) of policy iteration's warm-up strategy
STABILIZERS: dict[str, Callable[[QLearningLQR], Stabilizer]] = {
    "discount_annealing": lambda agent: DiscountAnnealing(agent.initial_discount, agent.max_warmup_iterations),
    "value_iteration": lambda agent: ValueIterationWarmup(agent.max_warmup_iterations),
}
#: ``method`` → factory(agent) of the method strategy
METHODS: dict[str, Callable[[QLearningLQR], Method]] = {
    "policy_iteration": lambda agent: PolicyIteration(STABILIZERS[agent.stabilize](agent), agent.reuse_data, agent.tol),
    "lspi": lambda agent: PolicyIteration(STABILIZERS[agent.stabilize](agent), agent.reuse_data, agent.tol),
    "value_iteration": lambda agent: ValueIteration(agent.reuse_data, agent.tol),
}
#: ``method`` → whether one batch is reused by default (``reuse_data=None``)
REUSES_DATA = {"policy_iteration": False, "lspi": True, "value_iteration": True}
SAMPLING = ("reset", "trajectory")


class Strategies(NamedTuple):
    """The strategies an agent composes (:attr:`QLearningLQR.strategies`)."""

    method: Method
    estimator: Estimator
    evaluation: PolicyEvaluation


def _component(component: str, attr: str, doc: str) -> property:
    def get(self):
        return getattr(getattr(self, component), attr)

    def set_(self, value) -> None:
        setattr(getattr(self, component), attr, value)

    return property(get, set_, doc=doc)


class QLearningLQR:
    """Model-free Q-learning LQR agent; also a :class:`baselines.base.Policy`.

    Parameters (units are the env's physical ones: state as measured, input as commanded):

    * ``env`` — observation = error state x (n), action = the m inputs (normalized).
    * ``method`` — ``"value_iteration"`` (default, the paper), ``"policy_iteration"``, ``"lspi"``.
    * ``estimator`` — ``"batch"`` or ``"rls"``; ``seed`` — the agent's RNG (exploration,
      sampled states) and the env's reset seed.
    * ``initial_gain`` (m×n, u = −Kx) — PI start/behaviour gain; default: obtained from data
      by ``stabilize`` = ``"discount_annealing"`` (default; from ``initial_discount``) or
      ``"value_iteration"``, within ``max_warmup_iterations``. Annealing gives gains with a
      stability margin: on the Heravi & Novinzadeh 2017 plant the first PI evaluation has cond ≈ 60 after it,
      ≈ 1e13 after the value-iteration warm-up (whose first accepted gain is barely stable).
    * ``discount`` γ ∈ (0, 1]; ``exploration_std`` σ_η (scalar or m, input units; default
      ``0.5·action_scale``); ``state_std`` (scalar or n) — spread of sampled start states.
    * ``sampling`` — ``"reset"`` (i.i.d. one-step samples from set states; default when
      the env supports it) or ``"trajectory"``; ``reuse_data`` (default: True for VI/LSPI).
    * ``td_estimator`` — ``"lstd"`` (LSTD-Q), legacy ``"ols"`` (Bellman-residual OLS,
      biased under noise) or ``"matrix_bellman"`` (Lopez, Alsalti & Müller 2023, eq. 29: all
      pairwise products of the data, ``H = Λ + γ Mᵀ H M`` with the data matrix
      ``M = Y Z⁺``; algebraically certainty equivalence) or ``"lstd_gls"``
      (feasible GLS LSTD-Q: a second LSTD-Q pass with every TD equation weighted by the
      inverse of its noise variance, fitted as a quadratic in z from the first pass's
      residuals; :func:`agents.qlqr.estimators.variance_weights`); ``constant_feature`` —
      the constant regressor of the noisy Bellman equation (default: on when a batch has
      more than p samples); ``row_normalize`` — divide each equation by ``‖z_k‖²``
      (default: when ‖z‖² spans more than 10⁴ in the batch).
    * ``tol`` — stopping tolerance on the (estimated) relative gain change/error;
      ``cond_limit``/``cond_warn`` — excitation guard thresholds.
    * ``rls_initial_covariance`` (``None`` = exact init, else β of ``P₀ = βI``),
      ``rls_forgetting`` λ ∈ (0, 1].
    * ``state_to_options``, ``action_scale``, ``input_map`` — see
      :class:`agents.qlqr.data.EnvAdapter` (``input_map`` lets a 4-wheel spacecraft learn
      in body-torque coordinates). ``exploration_std`` is then in the learner's input units.

    After :meth:`learn`: ``gain`` (m×n), ``kernel`` (H, (n+m)², physical units; the
    per-step Q-function), ``history`` (one dict per iteration: ``iteration``, ``phase``,
    ``samples_used``, ``rank``, ``n_unknowns``, ``cond``, ``delta_H``, ``delta_K``,
    ``spectral_radius`` (ρ(A − BK) of the env's nominal model, reporting only; ``None``
    without a model, and in VI between every 100th iteration after the first 100), ``huu_eig_ratio``,
    ``input_signal_ratio``,
    ``constant`` (λ̂), ``gain``), ``stop_reason``, ``data`` (last batch), ``reference``
    (certainty equivalence on the same data, :meth:`compare_with_certainty_equivalence`;
    with the env's nominal model also the gap of the learned gain to it).

    The agent composes strategies chosen by name (:attr:`strategies`): the ``method``
    (:class:`~agents.qlqr.value_iteration.ValueIteration` or
    :class:`~agents.qlqr.policy_iteration.PolicyIteration` with a ``stabilize`` strategy from
    :mod:`agents.qlqr.stabilizers`), the ``estimator`` (:mod:`agents.qlqr.estimators`) and the
    policy ``evaluation`` (``td_estimator``, :mod:`agents.qlqr.evaluation`); its components
    are the ``sampler`` (:class:`~agents.qlqr.sampling.Sampler`), the feature ``basis``
    (:class:`~agents.qlqr.basis.QuadraticBasis`) and the ``trace``
    (:class:`~agents.qlqr.trace.Trace`) that holds ``gain``, ``kernel``, ``history`` and
    ``stop_reason``.
    """

    gain = _component("trace", "gain", "Learned gain K (m×n, physical units, u = −Kx).")
    kernel = _component("trace", "kernel", "Learned kernel H ((n+m)², physical units); ``None`` before learning.")
    history = _component("trace", "history", "One dict per iteration of the last :meth:`learn`.")
    stop_reason = _component("trace", "stop_reason", "Why the last :meth:`learn` stopped.")
    data = _component("sampler", "data", "The last batch of transitions (``None`` before learning).")
    samples_used = _component("sampler", "samples_used", "Env transitions used so far.")
    rng = _component("sampler", "rng", "The agent's random generator (from ``seed``).")

    def __init__(
        self,
        env,
        method: str = "value_iteration",
        estimator: str = "batch",
        seed: int | None = 0,
        *,
        initial_gain=None,
        discount: float = 1.0,
        exploration_std=None,
        state_std=1.0,
        sampling: str | None = None,
        reuse_data: bool | None = None,
        td_estimator: str = "lstd",
        constant_feature: bool | None = None,
        row_normalize: bool | None = None,
        tol: float = 1e-10,
        cond_limit: float = 1e13,
        cond_warn: float = 1e10,
        input_signal_limit: float = 1e-9,
        rls_initial_covariance: float | None = None,
        rls_forgetting: float = 1.0,
        state_to_options=None,
        action_scale=None,
        input_map=None,
        stabilize: str = "discount_annealing",
        initial_discount: float = 1e-3,
        max_warmup_iterations: int = 10_000,
        name: str | None = None,
    ) -> None:
        _choose("method", method, METHODS)
        _choose("estimator", estimator, ESTIMATORS)
        _choose("td_estimator", td_estimator, TD_ESTIMATORS)
        if not 0.0 < float(discount) <= 1.0:
            raise ValueError(f"discount must be in (0, 1], got {discount!r}")
        if not 0.0 < float(rls_forgetting) <= 1.0:
            raise ValueError(f"rls_forgetting must be in (0, 1], got {rls_forgetting!r}")
        if rls_initial_covariance is not None and not float(rls_initial_covariance) > 0:
            raise ValueError(f"rls_initial_covariance must be > 0 or None, got {rls_initial_covariance!r}")
        for key, val in (("tol", tol), ("cond_limit", cond_limit), ("cond_warn", cond_warn)):
            if not (np.isfinite(val) and val > 0):
                raise ValueError(f"{key} must be in (0, inf), got {val!r}")
        self.adapter = EnvAdapter(env, state_to_options, action_scale, input_map)
        n, m = self.adapter.n, self.adapter.m
        if sampling is None:
            sampling = "reset" if self.adapter.can_set_state else "trajectory"
        _choose("sampling", sampling, SAMPLING)
        if sampling == "reset" and not self.adapter.can_set_state:
            raise ValueError("sampling='reset' needs state_to_options for this env")
        self.env = env
        self.method = "policy_iteration" if method == "lspi" else method
        self.reuse_data = REUSES_DATA[method] if reuse_data is None else bool(reuse_data)
        self.estimator = estimator
        self.td_estimator = td_estimator
        self.discount = float(discount)
        self.sampling = sampling
        self.constant_feature = constant_feature
        self.row_normalize = row_normalize
        self.tol, self.cond_limit, self.cond_warn = float(tol), float(cond_limit), float(cond_warn)
        self.input_signal_limit = validation.nonnegative("input_signal_limit", input_signal_limit)
        self.rls_initial_covariance = rls_initial_covariance
        self.rls_forgetting = float(rls_forgetting)
        self.max_warmup_iterations = int(max_warmup_iterations)
        if stabilize not in STABILIZERS:
            raise ValueError(f"stabilize must be 'value_iteration' or 'discount_annealing', got {stabilize!r}")
        if not 0.0 < float(initial_discount) <= float(discount):
            raise ValueError(f"initial_discount must be in (0, discount], got {initial_discount!r}")
        self.stabilize = stabilize
        self.initial_discount = float(initial_discount)
        self.n, self.m = n, m
        self.basis = QuadraticBasis(n, m, row_normalize, self.cond_limit, self.cond_warn)
        self.p = self.basis.p
        if exploration_std is None:
            sigma = 0.5 * (self.adapter.action_scale if input_map is None else np.min(self.adapter.action_scale))
        else:
            sigma = exploration_std
        self.exploration_std = _vector("exploration_std", sigma, m, positive=True)
        self.state_std = _vector("state_std", state_std, n, positive=False)
        if sampling == "reset" and not np.any(self.state_std > 0):
            raise ValueError("state_std must have a positive entry for sampling='reset'")
        self.initial_gain = None if initial_gain is None else _matrix("initial_gain", initial_gain, (m, n))
        self.seed = seed
        self.name = name or f"q-lqr-{method}"
        self.reference: dict[str, Any] | None = None
        self._report = reporting_model(env, self.adapter.input_map)
        self.sampler = Sampler(
            self.adapter, self.exploration_std, self.state_std, sampling, self.input_signal_limit, self.p, seed
        )
        gain = np.zeros((m, n)) if self.initial_gain is None else self.initial_gain.copy()
        self.trace = Trace(gain, self.sampler, self._report)
        estimator_strategy = ESTIMATORS[estimator](self)
        self.strategies = Strategies(
            method=METHODS[method](self),
            estimator=estimator_strategy,
            evaluation=TD_ESTIMATORS[td_estimator](self.basis, estimator_strategy),
        )

    # ------------------------------------------------------------------ public API
    def learn(
        self,
        max_iterations: int | None = None,
        samples_per_iteration: int | None = None,
        data: Transitions | None = None,
    ) -> QLearningLQR:
        """Run the chosen method; returns ``self``. ``samples_per_iteration`` is the size of
        each fresh batch (PI, or VI with ``reuse_data=False``) or of the single reused batch
        (LSPI, VI); default ``2(p+1)``. ``max_iterations`` default: 30 (PI), 10⁵ (VI).
        ``data`` (e.g. another agent's ``.data``) replaces the first collected batch: learning
        from a given data set, off-policy."""
        if data is not None:
            if data.X.shape[1:] != (self.n,) or data.U.shape[1:] != (self.m,) or len(data) < 1:
                raise ValueError(f"data must hold transitions with n = {self.n} states and m = {self.m} inputs")
            samples_per_iteration = len(data) if samples_per_iteration is None else samples_per_iteration
        self.sampler.given = data
        N = 2 * (self.p + 1) if samples_per_iteration is None else int(samples_per_iteration)
        if N < 1:
            raise ValueError(f"samples_per_iteration must be >= 1, got {samples_per_iteration!r}")
        method = self.strategies.method
        if max_iterations is None:
            max_iterations = method.default_max_iterations
        if int(max_iterations) < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations!r}")
        self.basis.constant = (N >= self.p + 1) if self.constant_feature is None else bool(self.constant_feature)
        self.trace.start()
        self.reference = None
        context = Context(
            sampler=self.sampler,
            basis=self.basis,
            estimator=self.strategies.estimator,
            evaluation=self.strategies.evaluation,
            trace=self.trace,
            discount=self.discount,
            batch_size=N,
            initial_gain=self.initial_gain,
        )
        # The linear algebra here is small (p ≲ 150 columns): BLAS threads only add
        # synchronization cost, which is severe on a loaded machine.
        with threadpool_limits(1, user_api="blas"):
            method.run(context, int(max_iterations))
            try:  # reported beside the learned gain; never part of learning
                self.reference = self.compare_with_certainty_equivalence()
            except (ValueError, np.linalg.LinAlgError) as err:
                self.reference = {"ce_gain": None, "ce_failed": f"{type(err).__name__}: {err}"}
        return self

    def reset(self, seed: int | None = None) -> None:
        """Policy interface: nothing to reset (the gain is fixed after learning)."""

    def act(self, obs: np.ndarray, info: dict[str, Any] | None = None) -> np.ndarray:
        """Policy interface: normalized action for ``u = −gain·x`` (clipped); one observation
        (n,) → (m,) or a batch (E, n) → (E, m), row by row."""
        x = np.asarray(obs, dtype=float)
        x = x.reshape(self.n) if x.ndim <= 1 else x.reshape(len(x), self.n)
        return self.adapter.action(-(x @ self.gain.T))

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """Stable-Baselines3-style ``(action, state)``; accepts one observation or a batch."""
        return self.act(observation), None

    def certainty_equivalence_gain(self, data: Transitions | None = None) -> np.ndarray:
        """Reference gain of a least-squares model + Riccati on the same data
        (:mod:`agents.qlqr.certainty_equivalence`)."""
        data = self.data if data is None else data
        if data is None:
            raise ValueError("certainty_equivalence_gain needs data: call learn() first")
        with threadpool_limits(1, user_api="blas"):
            return ce_gain(data, self.discount)

    def compare_with_certainty_equivalence(self, optimal_gain=None) -> dict[str, Any]:
        """The Q-learner beside certainty equivalence (CE) on the same data (:attr:`data`, the
        last batch: all the data of LSPI and VI, the last of on-policy PI's fresh batches).

        Returns ``ce_gain`` (least-squares model + Riccati, the costs fitted from the data) and
        ``difference`` = ‖K − K_CE‖/‖K_CE‖. With a reference optimum — ``optimal_gain``
        (m×n, u = −Kx), else the DARE gain of the env's nominal linear model when it has one
        (reporting only, as for ``spectral_radius``) — also ``optimal_gain``, ``error`` and
        ``ce_error`` (relative gain errors ‖·−K*‖/‖K*‖) and ``gap`` = error/ce_error (the
        Q-learner's sample-efficiency gap to CE; 1 for ``td_estimator="matrix_bellman"``)."""
        K_ce = self.certainty_equivalence_gain()
        out: dict[str, Any] = {"ce_gain": K_ce, "difference": relative_error(self.gain, K_ce)}
        K_star = (
            nominal_optimal_gain(self._report, self.discount)
            if optimal_gain is None
            else _matrix("optimal_gain", optimal_gain, (self.m, self.n))
        )
        if K_star is not None:
            e, e_ce = relative_error(self.gain, K_star), relative_error(K_ce, K_star)
            gap = e / e_ce if e_ce > 0 else (1.0 if e == 0 else float("inf"))
            out.update(optimal_gain=K_star, error=e, ce_error=e_ce, gap=gap)
        return out


def _choose(name: str, value, accepted) -> None:
    if value not in accepted:
        raise ValueError(f"{name} must be one of {sorted(accepted)}, got {value!r}")


def _vector(name: str, value, size: int, positive: bool) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    arr = np.broadcast_to(arr, (size,)).copy() if arr.ndim == 0 else arr
    if arr.shape != (size,) or not np.all(np.isfinite(arr)) or np.any(arr < 0) or (positive and np.any(arr <= 0)):
        rng = "(0, inf)" if positive else "[0, inf)"
        raise ValueError(f"{name} must be a scalar or length-{size} vector with entries in {rng}, got {value!r}")
    return arr


def _matrix(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite {shape[0]}x{shape[1]} matrix (u = -K x), got shape {arr.shape}")
    return arr
