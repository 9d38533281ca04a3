"""Q-learning LQR agent on LinearSystem-v0: exact answers from noise-free data
(to the DARE gain, in the Riccati or Hewer iteration count), API, guards."""

from __future__ import annotations

import numpy as np
import pytest
from qlqr_systems import benchmark_systems, linear_env, random_system, stabilizing_gain

from agents import QLearningLQR
from agents.qlqr.estimators import InsufficientExcitationError
from agents.qlqr.features import n_features, quadratic_features, smat, svec
from agents.qlqr.truth import hewer_iterations, relative_error, riccati_gains, riccati_iterations
from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.evaluation import rollout
from attitude_envs.lqr import dlqr

CASES = dict(benchmark_systems())
CASES["rand6x2-unstable"] = random_system(1, 6, 2, 1.3)
CASES["rand9x3-unstable"] = random_system(2, 9, 3, 1.1)
CASES["rand12x4-stable"] = random_system(3, 12, 4, 0.9)


def first_below(agent, K_star, tol=1e-8, phase=None) -> int | None:
    """1-based count of learning iterations until the gain error is below ``tol``."""
    hist = [h for h in agent.history if phase is None or h["phase"] == phase]
    return next((i + 1 for i, h in enumerate(hist) if relative_error(h["gain"], K_star) < tol), None)


def test_svec_roundtrip_and_quadratic_form():
    rng = np.random.default_rng(0)
    S = rng.normal(size=(5, 5))
    H = S + S.T
    assert np.allclose(smat(svec(H), 5), H)
    assert np.isclose(np.linalg.norm(svec(H)), np.linalg.norm(H))  # isometry
    z = rng.normal(size=(4, 5))
    assert np.allclose(quadratic_features(z) @ svec(H), np.einsum("ki,ij,kj->k", z, H, z))
    assert n_features(9) == 45  # Heravi & Novinzadeh 2017: 45 unknowns for n = 6, m = 3


@pytest.mark.parametrize("name", sorted(CASES))
def test_noise_free_pi_lspi_vi_exact(name):
    A, B, Q, R = CASES[name]
    n, m = B.shape
    p = n_features(n + m)
    K_star, _, _ = dlqr(A, B, Q, R)
    K0 = stabilizing_gain(A, B)
    env = linear_env(A, B, Q, R)

    pi = QLearningLQR(env, method="policy_iteration", seed=0, initial_gain=K0, exploration_std=1.0)
    pi.learn(samples_per_iteration=p)
    assert relative_error(pi.gain, K_star) <= 1e-8
    assert first_below(pi, K_star) <= hewer_iterations(A, B, Q, R, K0)
    assert [h["samples_used"] for h in pi.history[:3]] == [p, 2 * p, 3 * p]
    assert all(h["rank"] == p for h in pi.history)

    lspi = QLearningLQR(env, method="lspi", seed=1, initial_gain=K0, exploration_std=1.0)
    lspi.learn(samples_per_iteration=p)
    assert relative_error(lspi.gain, K_star) <= 1e-8
    assert lspi.history[-1]["samples_used"] == p  # one batch of p samples, reused
    assert first_below(lspi, K_star) <= hewer_iterations(A, B, Q, R, K0)

    vi = QLearningLQR(env, method="value_iteration", seed=2, exploration_std=1.0)
    vi.learn(samples_per_iteration=p)
    assert relative_error(vi.gain, K_star) <= 1e-8
    assert first_below(vi, K_star) <= riccati_iterations(A, B, Q, R)
    assert vi.stop_reason == "converged"
    # the learned kernel is the optimal Q-function's H* = blkdiag(Q, R) + [A B]ᵀP*[A B]
    _, P, _ = dlqr(A, B, Q, R)
    AB = np.hstack([A, B])
    H_star = np.block([[Q, np.zeros((n, m))], [np.zeros((m, n)), R]]) + AB.T @ P @ AB
    assert np.linalg.norm(vi.kernel - H_star) <= 1e-7 * np.linalg.norm(H_star)
    assert vi.history[-1]["spectral_radius"] < 1.0


def test_vi_follows_riccati_recursion_iteration_by_iteration():
    A, B, Q, R = CASES["krauth3x2"]
    agent = QLearningLQR(linear_env(A, B, Q, R), seed=0, exploration_std=1.0).learn(samples_per_iteration=15)
    ref = riccati_gains(A, B, Q, R, len(agent.history))
    errs = [
        np.linalg.norm(h["gain"] - ref[j]) / max(np.linalg.norm(ref[j]), 1e-300)
        for j, h in enumerate(agent.history[1:], 1)
    ]
    assert max(errs) < 1e-9
    assert np.linalg.norm(agent.history[0]["gain"]) < 1e-12  # H₁ = blkdiag(Q, R) ⇒ K₁ = 0


@pytest.mark.parametrize("method", ["policy_iteration", "lspi"])
def test_unstable_plant_without_initial_gain_value_iteration_first(method):
    A, B, Q, R = CASES["rand6x2-unstable"]
    assert np.max(np.abs(np.linalg.eigvals(A))) > 1.0
    K_star, _, _ = dlqr(A, B, Q, R)
    p = n_features(8)
    agent = QLearningLQR(
        linear_env(A, B, Q, R), method=method, seed=4, exploration_std=1.0, stabilize="value_iteration"
    )
    agent.learn(samples_per_iteration=p)
    warm = [h for h in agent.history if h["phase"] == "vi_warmup"]
    assert warm and warm[-1]["spectral_radius"] < 1.0  # the data Lyapunov gate accepted a stabilizing gain
    K0 = warm[-1]["gain"]
    assert relative_error(agent.gain, K_star) <= 1e-8
    assert first_below(agent, K_star, phase="policy_iteration") <= hewer_iterations(A, B, Q, R, K0)


@pytest.mark.parametrize("name", ["kiumarsi2x1", "rand9x3-unstable"])
def test_discount_annealing_finds_a_stabilizing_gain(name):
    A, B, Q, R = CASES[name]
    n, m = B.shape
    K_star, _, _ = dlqr(A, B, Q, R)
    agent = QLearningLQR(
        linear_env(A, B, Q, R), method="lspi", seed=0, exploration_std=1.0, stabilize="discount_annealing"
    )
    agent.learn(samples_per_iteration=n_features(n + m))
    annealing = [h for h in agent.history if h["phase"] == "annealing"]
    discounts = [h["discount"] for h in annealing]
    assert discounts[0] == 1e-3 and discounts[-1] == 1.0 and discounts == sorted(discounts)
    assert annealing[-1]["spectral_radius"] < 1.0
    assert relative_error(agent.gain, K_star) <= 1e-8


def test_rls_exact_initialization_matches_batch_and_ridge_init_is_biased():
    A, B, Q, R = CASES["krauth3x2"]
    K_star, _, _ = dlqr(A, B, Q, R)
    K0 = stabilizing_gain(A, B)
    env = linear_env(A, B, Q, R)
    exact = QLearningLQR(env, method="policy_iteration", estimator="rls", seed=0, initial_gain=K0, exploration_std=1.0)
    exact.learn(samples_per_iteration=60)
    assert relative_error(exact.gain, K_star) <= 1e-8
    vi = QLearningLQR(env, estimator="rls", seed=0, exploration_std=1.0).learn(samples_per_iteration=30)
    assert relative_error(vi.gain, K_star) <= 1e-8
    # P₀ = 10·I is ridge regression with penalty 0.1 (an independent prototype: 0.3 at β = 10): biased
    ridge = QLearningLQR(
        env,
        method="policy_iteration",
        estimator="rls",
        seed=0,
        initial_gain=K0,
        exploration_std=1.0,
        rls_initial_covariance=10.0,
        row_normalize=False,
    )
    ridge.learn(samples_per_iteration=150, max_iterations=8)
    assert relative_error(ridge.gain, K_star) > 1e-3


def test_spacecraft_plant_lstd_pi_and_vi():
    """Heravi & Novinzadeh 2017's plant (Euler, Δt = 0.01 s, J ≈ 10³ kg·m²). An independent prototype measured
    LSTD-Q PI failing here (cond ≈ 1e13); with per-coordinate feature scaling it is exact."""
    env = LinearSystemEnv(preset="heravi-2017")
    A, B, Q, R = env.model.A, env.model.B, env.model.Q, env.model.R
    K_star, _, _ = dlqr(A, B, Q, R)
    K0 = np.hstack([0.1 * np.eye(3), 10.0 * np.eye(3)])  # a stabilizing initial gain for this plant
    std = [1.0, 1.0, 1.0, 0.05, 0.05, 0.05]
    pi = QLearningLQR(env, method="lspi", seed=0, initial_gain=K0, state_std=std, exploration_std=1.0)
    pi.learn(samples_per_iteration=90)
    assert relative_error(pi.gain, K_star) <= 1e-8
    assert first_below(pi, K_star) <= hewer_iterations(A, B, Q, R, K0)
    assert max(h["cond"] for h in pi.history) < 1e5
    # on-policy PI with no initial gain, through the preset's ±2 N·m actuator: the agent finds
    # a stabilizing gain by value iteration and samples states where −Kx does not saturate
    onp = QLearningLQR(env, method="policy_iteration", seed=0, state_std=std, exploration_std=1.0)
    onp.learn(samples_per_iteration=90)
    assert relative_error(onp.gain, K_star) <= 1e-8
    assert any(h["phase"] == "annealing" for h in onp.history)
    assert max(h["cond"] for h in onp.history if h["phase"] == "policy_iteration") < 1e4


def test_excitation_guard_raises_instead_of_wrong_gain():
    A, B, Q, R = CASES["krauth3x2"]
    env = linear_env(A, B, Q, R)
    with pytest.raises(InsufficientExcitationError, match="rank"):
        QLearningLQR(env, seed=0, exploration_std=1.0).learn(samples_per_iteration=14)  # p = 15
    with pytest.raises(InsufficientExcitationError, match="round-off"):
        QLearningLQR(env, seed=0, exploration_std=1e-9).learn(samples_per_iteration=60)
    # feature scaling keeps the regressors well conditioned, so the guard is on the data's
    # information: the probe's effect on x⁺ relative to ‖x⁺‖ (here ≈ 1e-9 · 0.1)
    with pytest.raises(InsufficientExcitationError, match="condition number"):
        QLearningLQR(env, seed=0, exploration_std=1.0, cond_limit=1.5).learn(samples_per_iteration=60)


def test_api_policy_interface_and_predict():
    A, B, Q, R = CASES["kiumarsi2x1"]
    env = linear_env(A, B, Q, R, action_scale=50.0, x0_std=1.0, episode_steps=50)
    agent = QLearningLQR(env, method="value_iteration", estimator="batch", seed=7, exploration_std=1.0)
    agent.learn(max_iterations=200, samples_per_iteration=12)
    K_star, _, _ = dlqr(A, B, Q, R)
    assert relative_error(agent.gain, K_star) <= 1e-8
    assert agent.kernel.shape == (3, 3)
    keys = {"iteration", "samples_used", "rank", "cond", "delta_H", "delta_K", "spectral_radius"}
    assert keys <= set(agent.history[-1])
    obs = np.array([0.3, -0.2], dtype=np.float32)
    action, state = agent.predict(obs)
    assert state is None and action.shape == (1,)
    assert np.allclose(action * 50.0, -K_star @ obs, rtol=1e-6)
    batch, _ = agent.predict(np.stack([obs, -obs]))
    assert batch.shape == (2, 1) and np.allclose(batch[0], -batch[1])
    result = rollout(env, agent, seed=3)
    assert result["steps"] == 50 and not result["terminated"]


def test_bad_arguments_raise_value_error():
    env = linear_env(*CASES["kiumarsi2x1"])
    with pytest.raises(ValueError, match="method"):
        QLearningLQR(env, method="sarsa")
    with pytest.raises(ValueError, match="estimator"):
        QLearningLQR(env, estimator="gd")
    with pytest.raises(ValueError, match="discount"):
        QLearningLQR(env, discount=1.5)
    with pytest.raises(ValueError, match="initial_gain"):
        QLearningLQR(env, initial_gain=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="exploration_std"):
        QLearningLQR(env, exploration_std=-1.0)
    with pytest.raises(ValueError, match="samples_per_iteration"):
        QLearningLQR(env).learn(samples_per_iteration=0)


def test_feasible_gls_lstdq_is_exact_on_noise_free_data():
    """``td_estimator="lstd_gls"`` keeps the first pass on exact data (no noise to weight)."""
    A, B, Q, R = CASES["krauth3x2"]
    K_star, _, _ = dlqr(A, B, Q, R)
    for n_samples in (15, 60):  # exactly p, and enough for the constant feature and a variance fit
        agent = QLearningLQR(
            linear_env(A, B, Q, R),
            method="lspi",
            seed=0,
            exploration_std=1.0,
            initial_gain=np.zeros((2, 3)),
            td_estimator="lstd_gls",
        )
        agent.learn(samples_per_iteration=n_samples)
        assert relative_error(agent.gain, K_star) <= 1e-8
        assert agent.reference["ce_error"] <= 1e-10


def test_discounted_gain_matches_scaled_dare():
    A, B, Q, R = CASES["kiumarsi2x1"]
    gamma = 0.1  # √γ ρ(A) = 0.9 < 1: K = 0 is stabilizing for the discounted problem
    K_star, _, _ = dlqr(A, B, Q, R, discount=gamma)
    for method in ("lspi", "value_iteration"):
        agent = QLearningLQR(
            linear_env(A, B, Q, R),
            method=method,
            seed=0,
            discount=gamma,
            exploration_std=1.0,
            initial_gain=np.zeros((1, 2)) if method == "lspi" else None,
        )
        agent.learn(samples_per_iteration=6)
        assert relative_error(agent.gain, K_star) <= 1e-8


def test_value_iteration_with_fresh_batches_like_the_paper():
    """``reuse_data=False``: a fresh batch of N ≥ p samples per iteration (the paper's
    eqs. 29/31); same iterates as the reused batch, N× the samples."""
    A, B, Q, R = CASES["kiumarsi2x1"]
    K_star, _, _ = dlqr(A, B, Q, R)
    agent = QLearningLQR(linear_env(A, B, Q, R), seed=0, exploration_std=1.0, reuse_data=False)
    agent.learn(samples_per_iteration=6)
    assert relative_error(agent.gain, K_star) <= 1e-8
    assert first_below(agent, K_star) <= riccati_iterations(A, B, Q, R)
    assert [h["samples_used"] for h in agent.history[:3]] == [6, 12, 18]


def test_row_normalization_on_unstable_trajectory_data():
    """One trajectory of an unstable plant under u = η spans ~10²⁶ in ‖z‖²; raw least
    squares is swamped by the last rows, equations divided by ‖z_k‖² stay exact."""
    A, B, Q, R = CASES["kiumarsi2x1"]  # ρ(A) = 2.84
    K_star, _, _ = dlqr(A, B, Q, R)
    env = linear_env(A, B, Q, R, x0_std=1.0, episode_steps=10_000, divergence_threshold=1e30)
    errors = {}
    for normalize in (None, True, False):
        agent = QLearningLQR(env, seed=0, exploration_std=1.0, sampling="trajectory", row_normalize=normalize)
        try:
            agent.learn(samples_per_iteration=30)
            errors[normalize] = relative_error(agent.gain, K_star)
        except ValueError:  # refused (guard) instead of a wrong gain is acceptable for raw LS
            errors[normalize] = np.inf
    assert max(np.linalg.norm(agent.data.Xn, axis=1)) > 1e10
    assert errors[True] <= 1e-8 and errors[None] <= 1e-8  # the default detects the dynamic range
    assert errors[False] > 1e-3
