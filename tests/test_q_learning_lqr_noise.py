"""Q-learning LQR under process noise: LSTD-Q with the constant feature is consistent, the legacy estimators are
biased, and the matrix-Bellman evaluation reaches certainty equivalence."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from qlqr_systems import benchmark_systems, linear_env

from agents import QLearningLQR
from agents.qlqr.truth import relative_error
from attitude_envs.lqr import dlqr

A, B, Q, R = benchmark_systems()["krauth3x2"]
K_STAR, _, _ = dlqr(A, B, Q, R)
K0 = np.zeros((2, 3))  # krauth3x2 is open-loop stable (ρ(A) = 0.964)


def _errors(sigma_w: float, T: int, seeds: range, estimators: dict[str, dict]) -> dict[str, np.ndarray]:
    """Relative gain errors per estimator, every estimator fitted to the *same* batch per seed
    (one trajectory of T steps under u = η, σ_η = 1, from x₀ = 0; off-policy LSPI / VI)."""
    out: dict[str, list[float]] = {k: [] for k in estimators}
    out["ce"] = []
    for seed in seeds:
        env = linear_env(
            A, B, Q, R, process_noise_std=sigma_w, x0_std=0.0, episode_steps=10**7, divergence_threshold=1e9
        )
        batch = None
        for label, kw in estimators.items():
            kw = dict(kw)
            method = kw.pop("method", "lspi")
            agent = QLearningLQR(
                env,
                method=method,
                seed=seed,
                exploration_std=1.0,
                initial_gain=K0,
                sampling="trajectory",
                tol=1e-9,
                **kw,
            )
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                agent.learn(samples_per_iteration=T, data=batch)
            if batch is None:
                batch = agent.data
                out["ce"].append(relative_error(agent.certainty_equivalence_gain(), K_STAR))
            out[label].append(relative_error(agent.gain, K_STAR))
    return {k: np.array(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def sigma_01():
    est = {
        "lstd+c": {},
        "ols": {"td_estimator": "ols", "constant_feature": False},
        "matrix_bellman": {"td_estimator": "matrix_bellman"},
        "vi+c": {"method": "value_iteration"},
    }
    gls = {"gls": {"td_estimator": "lstd_gls"}}  # feasible GLS at T = 10³ only (keeps the test fast)
    return {T: _errors(0.1, T, range(8), est | (gls if T == 1_000 else {})) for T in (1_000, 10_000)}


def test_lstdq_with_constant_is_consistent(sigma_01):
    small, large = np.median(sigma_01[1_000]["lstd+c"]), np.median(sigma_01[10_000]["lstd+c"])
    assert large <= 0.5 * small  # T^-1/2 would give 0.32 per decade (accepted: ratio ≤ 0.5)
    assert large <= 0.05  # an independent prototype: 0.027 (40 seeds) at T = 1e4, σ_w = 0.1


def test_fitted_q_value_iteration_reaches_the_lspi_fixed_point(sigma_01):
    e = sigma_01[10_000]
    assert np.allclose(e["vi+c"], e["lstd+c"], rtol=1e-6)


def test_ols_bellman_residual_is_biased(sigma_01):
    ols_small, ols_large = np.median(sigma_01[1_000]["ols"]), np.median(sigma_01[10_000]["ols"])
    lstd_large = np.median(sigma_01[10_000]["lstd+c"])
    assert ols_large > 0.15  # a bias floor (an independent prototype: 0.54–0.56 on-policy)
    assert ols_large > 0.6 * ols_small  # does not shrink like T^-1/2
    assert ols_large > 4.0 * lstd_large


def test_matrix_bellman_equals_certainty_equivalence(sigma_01):
    """The CE gap (Q-learner error / CE error at equal data; published 2–7×) is 1 for the
    matrix-Bellman evaluation; plain LSTD-Q keeps the published gap."""
    for T, e in sigma_01.items():
        assert np.allclose(e["matrix_bellman"], e["ce"], rtol=1e-6), T
        gap_lstd = np.median(e["lstd+c"] / e["ce"])
        assert 1.5 < gap_lstd < 5.0, T  # LSTD-Q is less efficient: 3.9 (T = 1e3), 2.2 (T = 1e4); published 2–7×


def test_feasible_gls_lstdq_narrows_the_ce_gap(sigma_01):
    """Weighting each TD equation by its fitted inverse noise variance (feasible GLS) is
    more efficient than plain LSTD-Q on the same data: krauth3x2, σ_w = 0.1, T = 10³, 8
    seeds; measured gap to CE 1.32 vs 2.06, better on 8 of 8 seeds
    (benchmarks/q_learning_ce_gap.py has the full grid)."""
    e = sigma_01[1_000]
    gap_lstd, gap_gls = np.median(e["lstd+c"] / e["ce"]), np.median(e["gls"] / e["ce"])
    assert gap_gls < 0.8 * gap_lstd
    assert np.sum(e["gls"] < e["lstd+c"]) >= 6


def test_missing_constant_feature_leaves_a_bias_floor():
    e = _errors(1.0, 30_000, range(4), {"lstd+c": {}, "lstd": {"constant_feature": False}})
    assert np.median(e["lstd"]) > 0.3  # no-constant LSPI stays > 0.3 at σ_w = 1
    assert np.median(e["lstd+c"]) < 0.5 * np.median(e["lstd"])  # an independent prototype: 0.09 at T = 1e5


def test_on_policy_bradtke_ols_stays_biased_lstd_does_not():
    """Bias detection: on-policy PI with fresh batches (Bradtke style),
    krauth3x2, σ_w = 0.1, N = 1500 per iteration, 6 iterations: OLS residual ≈ 0.56 (must stay
    > 0.3), LSTD-Q + constant ≈ 0.18."""
    errors: dict[str, list[float]] = {"ols": [], "lstd+c": []}
    for seed in range(4):
        for label, kw in (("ols", {"td_estimator": "ols", "constant_feature": False}), ("lstd+c", {})):
            env = linear_env(A, B, Q, R, process_noise_std=0.1, x0_std=0.0, episode_steps=10**7)
            agent = QLearningLQR(
                env,
                method="policy_iteration",
                seed=seed,
                exploration_std=1.0,
                initial_gain=K0,
                sampling="trajectory",
                **kw,
            )
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                agent.learn(samples_per_iteration=1500, max_iterations=6)
            errors[label].append(relative_error(agent.gain, K_STAR))
    assert np.median(errors["ols"]) > 0.3
    assert np.median(errors["lstd+c"]) < 0.5 * np.median(errors["ols"])


def test_reference_reports_the_ce_gap_beside_the_learner():
    """After learn(): ``agent.reference`` holds CE on the same data and, from the env's
    nominal model (reporting only), both relative gain errors and their ratio."""
    env = linear_env(A, B, Q, R, process_noise_std=0.1, x0_std=0.0, episode_steps=10**7)
    agents = {}
    for td in ("lstd", "matrix_bellman"):
        agents[td] = QLearningLQR(
            env, method="lspi", seed=3, exploration_std=1.0, initial_gain=K0, sampling="trajectory", td_estimator=td
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            agents[td].learn(samples_per_iteration=2_000, data=agents["lstd"].data if td != "lstd" else None)
    ref = agents["lstd"].reference
    assert np.allclose(ref["optimal_gain"], K_STAR, rtol=1e-12)
    assert np.array_equal(ref["ce_gain"], agents["lstd"].certainty_equivalence_gain())
    assert ref["error"] == relative_error(agents["lstd"].gain, K_STAR)
    assert ref["ce_error"] == relative_error(ref["ce_gain"], K_STAR)
    assert ref["gap"] == ref["error"] / ref["ce_error"] and ref["gap"] > 1.0
    assert abs(agents["matrix_bellman"].reference["gap"] - 1.0) < 1e-6  # CE as a Q-function equation
    given = agents["lstd"].compare_with_certainty_equivalence(optimal_gain=2 * K_STAR)
    assert given["error"] == relative_error(agents["lstd"].gain, 2 * K_STAR)
    with pytest.raises(ValueError, match="optimal_gain"):
        agents["lstd"].compare_with_certainty_equivalence(optimal_gain=np.zeros((3, 2)))
