"""Model-free Q-learning LQR: learns the optimal linear state feedback from data only.

Implements quadratic Q-function ``Q(x, u) = [x; u]ᵀH[x; u]`` learners (Bradtke, Ydstie & Barto
1994; Lewis & Vrabie 2009) and the method of the Q-learning LQR paper (Heravi & Novinzadeh 2017, 1000 kg·m²
satellite):

* ``method="value_iteration"`` — the paper's method (eqs. 17–30):
  ``H_{j+1} = argmin Σ (φ(z_k)ᵀθ − r_k − γ x_{k+1}ᵀ P_j x_{k+1})²`` from ``H₀ = 0``, with
  ``P_j = H_xx − H_xu K_j`` (eq. 16) and the greedy gain ``K_j = H_uu⁻¹H_ux`` (eq. 13, u = −Kx).
  By default one batch is reused for every iteration (fitted-Q iteration): each
  iteration is then a p-dimensional affine map, so 10⁵ iterations cost seconds.
  ``reuse_data=False`` collects a fresh batch per iteration, as the paper does.
* ``method="policy_iteration"`` — Bradtke/Lewis PI: evaluate the current gain
  from on-policy data (fresh batch per iteration, behaviour ``u = −K_j x + η``), improve
  greedily. ``reuse_data=True`` (or ``method="lspi"``) is off-policy LSPI on one batch
  (Lagoudakis & Parr 2003). Evaluation is LSTD-Q (instrument ``φ(z_k)``, consistent under process
  noise) with an optional constant feature, or the legacy OLS Bellman-residual fit
  (``td_estimator="ols"``, biased under noise). PI needs a stabilizing initial gain:
  ``initial_gain`` or, if ``None``, discount annealing (policy iteration from K = 0 at a
  small discount, raised while the data Lyapunov test ``T_Kᵀ Ĥ_K T_K ≻ 0`` passes) or, with ``stabilize="value_iteration"``, value iteration on the first batch until
  the greedy gain passes that test.

Estimators: ``"batch"`` (QR of row-normalized, column-scaled features) or ``"rls"``
(instrumental-variable recursive least squares, exact initialization by default).
Features are orthonormal svec monomials of the *scaled* ``z = [x/s_x; u/s_u]`` (scales
from the first batch's RMS); kernels and gains are reported in physical units.

The agent reads only what a flight computer has: its measured state (``info["measured"]``,
or the observation), the input it commanded (``info["commanded"]``) and ``info["cost"]``
(:mod:`agents.qlqr.data`), never the ground truth ``info["truth"]``; the env's model is used
for one diagnostic (closed-loop spectral radius), never for learning.
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from agents.qlqr import estimators as est
from agents.qlqr.certainty_equivalence import ce_gain
from agents.qlqr.data import EnvAdapter, Transitions, collect
from agents.qlqr.features import n_features, quadratic_features, smat, svec
from agents.qlqr.truth import dare_gain, relative_error
from attitude_envs import validation

METHODS = {"policy_iteration", "lspi", "value_iteration"}
ESTIMATORS = {"batch", "rls"}
TD_ESTIMATORS = {"lstd", "lstd_gls", "ols", "matrix_bellman"}
SAMPLING = {"reset", "trajectory"}


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
    """

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
        if method not in METHODS:
            raise ValueError(f"method must be one of {sorted(METHODS)}, got {method!r}")
        if estimator not in ESTIMATORS:
            raise ValueError(f"estimator must be one of {sorted(ESTIMATORS)}, got {estimator!r}")
        if td_estimator not in TD_ESTIMATORS:
            raise ValueError(f"td_estimator must be one of {sorted(TD_ESTIMATORS)}, got {td_estimator!r}")
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
        if sampling not in SAMPLING:
            raise ValueError(f"sampling must be one of {sorted(SAMPLING)}, got {sampling!r}")
        if sampling == "reset" and not self.adapter.can_set_state:
            raise ValueError("sampling='reset' needs state_to_options for this env")
        self.env = env
        self.method = "policy_iteration" if method == "lspi" else method
        self.reuse_data = (method != "policy_iteration") if reuse_data is None else bool(reuse_data)
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
        if stabilize not in {"value_iteration", "discount_annealing"}:
            raise ValueError(f"stabilize must be 'value_iteration' or 'discount_annealing', got {stabilize!r}")
        if not 0.0 < float(initial_discount) <= float(discount):
            raise ValueError(f"initial_discount must be in (0, discount], got {initial_discount!r}")
        self.stabilize = stabilize
        self.initial_discount = float(initial_discount)
        self.n, self.m = n, m
        self.p = n_features(n + m)
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
        self.rng = np.random.default_rng(seed)
        self.name = name or f"q-lqr-{method}"
        self.gain = np.zeros((m, n)) if self.initial_gain is None else self.initial_gain.copy()
        self.kernel: np.ndarray | None = None
        self.history: list[dict[str, Any]] = []
        self.reference: dict[str, Any] | None = None
        self.stop_reason: str | None = None
        self.data: Transitions | None = None
        self.samples_used = 0
        self._scale: np.ndarray | None = None
        self._given: Transitions | None = None
        self._report = _reporting_model(env, self.adapter.input_map)

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
        self._given = data
        N = 2 * (self.p + 1) if samples_per_iteration is None else int(samples_per_iteration)
        if N < 1:
            raise ValueError(f"samples_per_iteration must be >= 1, got {samples_per_iteration!r}")
        if max_iterations is None:
            max_iterations = 30 if self.method == "policy_iteration" else 100_000
        if int(max_iterations) < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations!r}")
        self._const = (N >= self.p + 1) if self.constant_feature is None else bool(self.constant_feature)
        self._N = N
        self.history = []
        self.stop_reason = None
        self.reference = None
        # The linear algebra here is small (p ≲ 150 columns): BLAS threads only add
        # synchronization cost, which is severe on a loaded machine.
        with threadpool_limits(1, user_api="blas"):
            if self.method == "value_iteration":
                self._value_iteration(int(max_iterations))
            else:
                self._policy_iteration(int(max_iterations))
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
            self._optimal_gain() if optimal_gain is None else _matrix("optimal_gain", optimal_gain, (self.m, self.n))
        )
        if K_star is not None:
            e, e_ce = relative_error(self.gain, K_star), relative_error(K_ce, K_star)
            gap = e / e_ce if e_ce > 0 else (1.0 if e == 0 else float("inf"))
            out.update(optimal_gain=K_star, error=e, ce_error=e_ce, gap=gap)
        return out

    def _optimal_gain(self) -> np.ndarray | None:
        """DARE gain of the env's nominal model (reporting only); ``None`` without a model."""
        if self._report is None or self._report.Q is None or self._report.R is None:
            return None
        A, B, Q, R, N = self._report
        try:
            return dare_gain(A, B, Q, R, self.discount, N)[0]
        except (ValueError, np.linalg.LinAlgError):
            return None

    # ------------------------------------------------------------------ data and features
    def _collect(self, n_samples: int, gain: np.ndarray) -> Transitions:
        if self._given is not None:
            data, self._given = self._given, None
        else:
            env_seed = None if self.samples_used else int(self.rng.integers(2**31 - 1))
            data = collect(
                self.adapter,
                n_samples,
                gain,
                self.exploration_std,
                self._sample_std(gain),
                self.rng,
                env_seed,
                self.sampling,
            )
        self.samples_used += len(data)
        self.data = data  # kept even when a guard below refuses it, for inspection
        self._input_signal = self._check_input_signal(data)
        if self._scale is None:
            # RMS of the *directions* z_k/‖z_k‖: the typical proportions of the coordinates,
            # not dominated by the largest rows when the data span many orders of magnitude
            # (unstable trajectories)
            Z = np.hstack([data.X, data.U])
            norms = np.linalg.norm(Z, axis=1)
            Z = Z[norms > 0] / norms[norms > 0, None]
            s = np.sqrt(np.mean(Z**2, axis=0)) if len(Z) else np.ones(self.n + self.m)
            s[~(s > 0)] = 1.0
            self._scale = s
            self._outer = np.outer(s, s)
        self.data = data
        return data

    def _sample_std(self, gain: np.ndarray) -> np.ndarray:
        """Spread of the sampled start states for a behaviour gain: ``state_std``, shrunk so
        that the feedback part ``−gain·x`` of the action stays within half the actuator range
        (RMS), since saturated inputs carry no excitation (one-step samples of a linear
        plant are equally informative at any scale; a nonlinear one is more linear there)."""
        M = np.eye(self.m) if self.adapter.input_map is None else self.adapter.input_map
        rms = np.sqrt(((M @ gain) ** 2) @ (self.state_std**2))
        limit = 0.5 * self.adapter.action_scale
        with np.errstate(divide="ignore"):
            shrink = float(np.min(np.where(rms > 0, limit / rms, np.inf)))
        return self.state_std * min(1.0, shrink)

    def _check_input_signal(self, data: Transitions) -> float:
        """Excitation guard that feature scaling cannot hide (a probe too small
        relative to the state). Per sample, the next-state change the probe of each input
        causes, ``‖b̂_j‖·|u_kj|`` (``B̂`` from a row-normalized least-squares fit
        ``x⁺ ≈ Âx + B̂u``, a diagnostic only), relative to ``‖x⁺_k‖``; the p-th largest over the
        samples (p equations must carry the input's effect), minimized over the inputs. Below
        ``input_signal_limit`` the input's effect is lost in floating-point round-off."""
        Z = np.hstack([data.X, data.U])
        s = np.sqrt(np.mean(Z**2, axis=0))
        s[s == 0] = 1.0
        row = np.linalg.norm(Z / s, axis=1)
        row[row == 0] = 1.0
        coef = est.lstsq_tall(Z / s / row[:, None], data.Xn / row[:, None]) / s[:, None]
        b_norm = np.linalg.norm(coef[self.n :], axis=1)  # ‖b̂_j‖ per input
        size = np.linalg.norm(data.Xn, axis=1)
        size[size == 0] = np.finfo(float).tiny
        per_sample = np.abs(data.U) * b_norm / size[:, None]
        k = min(self.p, len(per_sample))
        ratio = float(np.min(np.sort(per_sample, axis=0)[-k]))
        if not ratio >= self.input_signal_limit:
            raise est.InsufficientExcitationError(
                f"the probing input changes the next state by only {ratio:.2g} of its size (< input_signal_limit "
                f"{self.input_signal_limit:.2g}): its effect is lost in round-off; raise exploration_std"
            )
        if ratio < 1e-6:
            warnings.warn(
                f"the probing input changes the next state by only {ratio:.2g} of its size: expect "
                "round-off-limited accuracy; raise exploration_std",
                stacklevel=4,
            )
        return ratio

    def _features(self, data: Transitions) -> tuple[np.ndarray, np.ndarray]:
        """Instrument rows ``f_k = [φ(z_k); 1]`` and row weights (scaled coordinates)."""
        Zs = np.hstack([data.X, data.U]) / self._scale
        F = quadratic_features(Zs)
        if self._const:
            F = np.hstack([F, np.ones((len(F), 1))])
        sq = np.sum(Zs**2, axis=1)
        normalize = self.row_normalize
        if normalize is None:  # when ‖z‖² spans more than 10⁴ (1st to 99th percentile)
            lo, hi = np.percentile(sq, [1.0, 99.0])
            normalize = bool(hi > 1e4 * max(float(lo), 1e-300))
        if normalize:  # an all-zero z_k gives the equation 0 = 0: weight 0
            w = np.divide(1.0, sq, out=np.zeros_like(sq), where=sq > 0)
        else:
            w = np.ones(len(F))
        return F, w

    def _kernel(self, theta: np.ndarray) -> tuple[np.ndarray, float | None]:
        d = self.n + self.m
        H = smat(theta[: self.p], d) / self._outer
        return H, (float(theta[self.p]) if self._const else None)

    def _design(self, F: np.ndarray, w: np.ndarray, what: str) -> est.Design:
        return est.Design(F, w, self.cond_limit, self.cond_warn, what)

    # ------------------------------------------------------------------ policy evaluation
    def _evaluate(self, data, F, w, design, K) -> tuple[np.ndarray, float | None, est.Excitation]:
        """Q-function of gain ``K`` from data: LSTD-Q or OLS."""
        Xn_s = data.Xn / self._scale[: self.n]
        Un_s = (-data.Xn @ K.T) / self._scale[self.n :]
        Phi_next = quadratic_features(np.hstack([Xn_s, Un_s]))
        Psi = F.copy()
        Psi[:, : self.p] -= self.discount * Phi_next  # the constant column is not differenced
        if self.td_estimator == "matrix_bellman":
            return self._matrix_bellman(data, design, K)
        if self.td_estimator == "ols":
            theta, exc = est.ordinary_least_squares(Psi, data.r, w, self.cond_limit, self.cond_warn)
        else:
            theta, exc = self._lstd(F, Psi, data.r, w, design)
            if self.td_estimator == "lstd_gls":
                theta, exc = self._lstd_gls(F, Psi, data.r, theta, exc)
        H, c = self._kernel(theta)
        return H, c, exc

    def _lstd(self, F, Psi, r, w, design) -> tuple[np.ndarray, est.Excitation]:
        """LSTD-Q (instrument ``F``, regressor ``Psi``, row weights ``w``): batch or RLS."""
        if self.estimator == "rls":
            theta = est.recursive_least_squares(F, Psi, r, w, self.rls_initial_covariance, self.rls_forgetting)
            return theta, design.excitation
        return design.instrumental(Psi, r)

    def _lstd_gls(self, F, Psi, r, theta, exc) -> tuple[np.ndarray, est.Excitation]:
        """Second stage of feasible-GLS LSTD-Q: reweight every TD equation by the inverse of
        its conditional noise variance, fitted from the first stage's residuals
        (:func:`agents.qlqr.estimators.variance_weights`); no model is used."""
        F1 = F if self._const else np.hstack([F, np.ones((len(F), 1))])
        # residuals within 1e-10 of the largest cost are round-off of exact (noise-free) data
        w = est.variance_weights(F1, r - Psi @ theta, noise_free=1e-10 * float(np.max(np.abs(r), initial=0.0)))
        if w is None:  # noise-free data: the first stage is exact
            return theta, exc
        return self._lstd(F, Psi, r, w, self._design(F, w, "GLS policy evaluation"))

    def _matrix_bellman(self, data, design, K) -> tuple[np.ndarray, float | None, est.Excitation]:
        """Policy evaluation by the matrix Bellman equation (Lopez et al. 2023, eq. 29): ``ZᵀHZ = ZᵀΛZ + γ YᵀHY`` for all sample pairs; with ``M = Y Z⁺`` it reduces to
        the Stein equation ``H = Λ + γ MᵀHM``. The stage-cost kernel Λ is fitted from the
        observed costs (the agent is not told Q and R)."""
        n, s = self.n, self._scale
        Zs = np.hstack([data.X, data.U]) / s
        Ys = np.hstack([data.Xn, -data.Xn @ K.T]) / s
        M = est.lstsq_tall(Zs, Ys).T
        lam_theta = design.least_squares(data.r)
        Lam = smat(lam_theta[: self.p], n + self.m)
        Hs = scipy.linalg.solve_discrete_lyapunov(np.sqrt(self.discount) * M.T, Lam)
        return 0.5 * (Hs + Hs.T) / np.outer(s, s), None, design.excitation

    def _lyapunov_ok(self, data, F, w, design, K) -> bool:
        """Data Lyapunov test: ``T_Kᵀ Ĥ_K T_K ≻ 0`` ⇒ K stabilizing (exact data)."""
        try:
            with warnings.catch_warnings():  # probing near the stability boundary is ill-conditioned by design
                warnings.simplefilter("ignore")
                H, _, _ = self._evaluate(data, F, w, design, K)
        except (est.InsufficientExcitationError, np.linalg.LinAlgError):
            return False
        T = np.vstack([np.eye(self.n), -K])
        P = T.T @ H @ T
        s = self._scale[: self.n]
        return bool(np.min(np.linalg.eigvalsh(0.5 * (P + P.T) * np.outer(s, s))) > 0)

    # ------------------------------------------------------------------ value iteration
    def _vi_maps(self, data: Transitions, design: est.Design, F: np.ndarray, w: np.ndarray):
        """``θ_{j+1} = a + G·svec(P_j in scaled x)`` for the batch (fitted-Q iteration): the target
        ``r_k + γ x⁺ᵀP_j x⁺`` is linear in svec(P_j), so one solve with n(n+1)/2 + 1
        right-hand sides serves every iteration."""
        Phi_x = quadratic_features(data.Xn / self._scale[: self.n])
        Y = np.hstack([data.r[:, None], self.discount * Phi_x])
        if self.estimator == "rls":
            AG = est.recursive_least_squares(F, F, Y, w, self.rls_initial_covariance, self.rls_forgetting)
        else:
            AG = design.least_squares(Y)
        return AG[:, 0], AG[:, 1:]

    def _vi_run(self, data, max_iterations, phase, gate=None):
        """Iterate VI on one batch; ``gate(K)`` (warm-up) stops at the first gain it accepts."""
        F, w = self._features(data)
        design = self._design(F, w, "value iteration")
        a, G = self._vi_maps(data, design, F, w)
        n = self.n
        sxx = self._outer[:n, :n]
        P = np.zeros((n, n))
        K = np.zeros((self.m, n))
        H_prev = None
        d_hist: list[float] = []
        for j in range(max_iterations):
            if not self.reuse_data and j > 0 and gate is None:
                data = self._collect(self._N, K)
                F, w = self._features(data)
                design = self._design(F, w, "value iteration")
                a, G = self._vi_maps(data, design, F, w)
            theta = a + G @ svec(P * sxx)
            H, c = self._kernel(theta)
            try:
                K_new, ratio = est.greedy_gain(H, n)
            except est.NotPositiveDefiniteError:
                self.stop_reason = "H_uu not positive definite"
                raise
            P = H[:n, :n] - H[:n, n:] @ K_new
            P = 0.5 * (P + P.T)
            dK = _rel(K_new, K)
            dH = _rel(H, H_prev) if H_prev is not None else 1.0
            # the (reporting-only) spectral radius costs an eigensolve: every iteration early on,
            # then every 100th (None in between)
            self._record(j, phase, design.excitation, dH, dK, K_new, ratio, c, rho=j < 100 or j % 100 == 0)
            K, H_prev = K_new, H
            self.gain, self.kernel = K, H
            d_hist.append(dK)
            if gate is not None:
                if np.any(K) and gate(K):
                    return K
                continue
            if _vi_converged(d_hist, self.tol):
                self.stop_reason = "converged"
                self.history[-1]["spectral_radius"] = self._spectral_radius(K)
                return K
        if self.history:
            self.history[-1]["spectral_radius"] = self._spectral_radius(K)
        self.stop_reason = "max_iterations" if gate is None else "no stabilizing gain found"
        return None if gate is not None else K

    def _value_iteration(self, max_iterations: int) -> None:
        data = self._collect(self._N, self.gain if self.initial_gain is not None else np.zeros((self.m, self.n)))
        self._vi_run(data, max_iterations, "value_iteration")

    def _anneal(self, data, F, w, design) -> np.ndarray | None:
        """Discount annealing (Lamperski 2020): K = 0 is stabilizing for a
        small enough discount γ₀; policy iteration at γ, then raise γ towards the target
        while the data Lyapunov test at the new γ accepts the current gain (bisection for
        the largest such γ, 90 % of the way). Phase ``"annealing"`` in the history."""
        target = self.discount
        gamma = self.initial_discount
        K = np.zeros((self.m, self.n))
        j = 0
        try:
            for _ in range(self.max_warmup_iterations):
                self.discount = gamma
                for _ in range(30):  # PI at this discount, on the same batch
                    H, c, exc = self._evaluate(data, F, w, design, K)
                    K_new, ratio = est.greedy_gain(H, self.n)
                    dK = _rel(K_new, K)
                    self._record(j, "annealing", exc, 1.0, dK, K_new, ratio, c)
                    self.history[-1]["discount"] = gamma
                    j += 1
                    K = K_new
                    if dK < 1e-6:
                        break
                if gamma >= target:
                    return K

                def ok(g: float, gain=K) -> bool:
                    self.discount = g
                    return self._lyapunov_ok(data, F, w, design, gain)

                if ok(target):
                    gamma = target
                    continue
                lo, hi = gamma, target
                for _ in range(30):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if ok(mid) else (lo, mid)
                if lo <= gamma * (1 + 1e-9):
                    return None
                gamma = gamma + 0.9 * (lo - gamma)
            return None
        finally:
            self.discount = target

    # ------------------------------------------------------------------ policy iteration
    def _policy_iteration(self, max_iterations: int) -> None:
        behaviour = self.initial_gain if self.initial_gain is not None else np.zeros((self.m, self.n))
        data = self._collect(self._N, behaviour)
        K = self.initial_gain
        if K is None:
            F, w = self._features(data)
            design = self._design(F, w, "value-iteration warm-up")

            def gate(gain):
                return self._lyapunov_ok(data, F, w, design, gain)

            if self.stabilize == "discount_annealing":
                K = self._anneal(data, F, w, design)
            else:
                K = self._vi_run(data, self.max_warmup_iterations, "vi_warmup", gate)
            if K is None:
                raise est.InsufficientExcitationError(
                    "no stabilizing gain passed the data Lyapunov test within max_warmup_iterations "
                    f"= {self.max_warmup_iterations}; pass initial_gain"
                )
            self.stop_reason = None
        F, w = self._features(data)
        design = self._design(F, w, "policy evaluation")
        d_prev = np.inf
        for j in range(max_iterations):
            if j > 0 and not self.reuse_data:
                data = self._collect(self._N, K)
                F, w = self._features(data)
                design = self._design(F, w, "policy evaluation")
            H, c, exc = self._evaluate(data, F, w, design, K)
            try:
                K_new, ratio = est.greedy_gain(H, self.n)
            except est.NotPositiveDefiniteError as err:
                self.stop_reason = "H_uu not positive definite"
                raise est.NotPositiveDefiniteError(
                    f"{err} at iteration {j}: the data do not determine the Q-function of the current gain "
                    "(too few or too noisy samples, or a non-stabilizing gain); collect more samples_per_iteration"
                ) from None
            dK = _rel(K_new, K)
            dH = _rel(H, self.kernel) if self.kernel is not None else 1.0
            self._record(j, "policy_iteration", exc, dH, dK, K_new, ratio, c)
            K = K_new
            self.gain, self.kernel = K, H
            if dK < self.tol:
                self.stop_reason = "converged"
                return
            if j >= 2 and dK >= d_prev:  # no longer contracting: estimation floor reached
                self.stop_reason = "stalled"
                return
            d_prev = dK
        self.stop_reason = "max_iterations"

    # ------------------------------------------------------------------ diagnostics
    def _spectral_radius(self, K: np.ndarray) -> float | None:
        if self._report is None:
            return None
        A, B = self._report.A, self._report.B
        return float(np.max(np.abs(np.linalg.eigvals(A - B @ K))))

    def _record(self, j, phase, exc, dH, dK, K, ratio, c, rho: bool = True) -> None:
        rho = self._spectral_radius(K) if rho else None
        self.history.append(
            {
                "iteration": j,
                "phase": phase,
                "samples_used": self.samples_used,
                "rank": exc.rank,
                "n_unknowns": exc.n_unknowns,
                "cond": exc.cond,
                "delta_H": dH,
                "delta_K": dK,
                "spectral_radius": rho,
                "huu_eig_ratio": ratio,
                "input_signal_ratio": self._input_signal,
                "constant": c,
                "gain": K,
            }
        )


def _rel(new: np.ndarray, old: np.ndarray | None) -> float:
    if old is None:
        return 1.0
    den = np.sqrt(np.vdot(new, new))
    diff = new - old
    num = np.sqrt(np.vdot(diff, diff))
    return float(num / den) if den > 0 else (0.0 if num == 0 else float("inf"))


def _vi_converged(d: list[float], tol: float, window: int = 10) -> bool:
    """VI converges linearly: error ≈ ΔK·r/(1−r) with the contraction rate r estimated
    over the last ``window`` iterations; stop when that bound is below ``tol``, or when
    ΔK has reached round-off."""
    dk = d[-1]
    if dk == 0.0 and len(d) > 1 and any(v > 0 for v in d):
        return True
    if len(d) <= window or d[-1 - window] <= 0 or dk <= 0:
        return False
    r = (dk / d[-1 - window]) ** (1.0 / window)
    if dk < 1e-3 * tol:
        return True
    return r < 1.0 and dk * r / (1.0 - r) < tol


class _NominalModel(NamedTuple):
    """Discrete nominal model in the learner's input coordinates (reporting only)."""

    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray | None
    R: np.ndarray | None
    N: np.ndarray | None


def _reporting_model(env, input_map) -> _NominalModel | None:
    """Discrete (A, B) and stage-cost weights (Q, R, N) of the env's nominal model, in the
    learner's input coordinates ``v`` (actuators ``u = M v``: ``B M``, ``MᵀRM``, ``N M``), for
    the spectral-radius diagnostic and the reference optimum of
    :meth:`QLearningLQR.compare_with_certainty_equivalence` only."""
    model = getattr(env.unwrapped, "model", None)
    try:
        if model is not None and hasattr(model, "A") and getattr(model, "dt_s", None) is not None:
            lin = model
        elif model is not None and hasattr(model, "discrete"):
            lin = model.discrete(input="wheel")
        else:
            return None
        A, B = np.asarray(lin.A, float), np.asarray(lin.B, float)
        Q, R, N = (getattr(lin, key, None) for key in ("Q", "R", "N"))
        M = np.eye(B.shape[1]) if input_map is None else input_map
        R = None if R is None else M.T @ np.asarray(R, float) @ M
        N = None if N is None else np.asarray(N, float) @ M
        return _NominalModel(A, B @ M, None if Q is None else np.asarray(Q, float), R, N)
    except (ValueError, TypeError, AttributeError, np.linalg.LinAlgError):
        return None


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
