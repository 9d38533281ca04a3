"""LinearSystem-v0's decision period ``control_dt_s = k · dt_s``: the input held over k plant
steps, discretized exactly (state and summed stage cost), so J is the same quantity at any k."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.linearization import LinearModel
from attitude_envs.lqr import dlqr
from attitude_envs.plants.linear_hold import hold_model
from baselines.linear_lqr import LinearLQRPolicy

LS = "attitude_envs/LinearSystem-v0"


def _brute_force(model: LinearModel, k: int):
    """Aᵏ, Σ_{i<k}AⁱB and the summed cost weights, one plant step at a time."""
    n, m = model.n, model.m
    N = np.zeros((n, m)) if model.N is None else model.N
    Ax, Bu = np.eye(n), np.zeros((n, m))  # x_j = Ax x + Bu u
    Qk, Nk, Rk = np.zeros((n, n)), np.zeros((n, m)), np.zeros((m, m))
    for _ in range(k):
        Qk += Ax.T @ model.Q @ Ax
        Nk += Ax.T @ model.Q @ Bu + Ax.T @ N
        Rk += Bu.T @ model.Q @ Bu + Bu.T @ N + N.T @ Bu + model.R
        Ax, Bu = model.A @ Ax, model.A @ Bu + model.B
    return Ax, Bu, Qk, Nk, Rk


def _rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b))))


@pytest.mark.parametrize("k", [2, 3, 7, 64, 500])
def test_hold_model_is_the_sum_of_k_plant_steps(k):
    rng = np.random.default_rng(k)
    n, m = 4, 2
    A = rng.normal(size=(n, n))
    A *= 0.98 / np.max(np.abs(np.linalg.eigvals(A)))
    G = rng.normal(size=(n, n))
    model = LinearModel(A, rng.normal(size=(n, m)), G @ G.T, np.eye(m) * 0.5, 0.1 * rng.normal(size=(n, m)), 0.2)
    held = hold_model(model, k)
    Ak, Bk, Qk, Nk, Rk = _brute_force(model, k)
    for got, want in ((held.A, Ak), (held.B, Bk), (held.Q, Qk), (held.N, Nk), (held.R, Rk)):
        assert _rel(got, want) <= 1e-12
    assert held.dt_s == k * 0.2
    assert np.array_equal(held.Q, held.Q.T) and np.array_equal(held.R, held.R.T)


def test_hold_model_of_an_integrator_matches_the_closed_form():
    """A = I: x_j = x + jBu, so A_k = I, B_k = kB, Q_k = kQ, N_k = k(k−1)/2 QB and
    R_k = kR + (k−1)k(2k−1)/6 BᵀQB (sums of j and j²)."""
    k = 500
    B = np.array([[0.5, 0.0], [0.1, 2.0], [0.0, 1.0]])
    Q, R = np.diag([1.0, 2.0, 3.0]), np.array([[2.0, 0.3], [0.3, 1.0]])
    held = hold_model(LinearModel(np.eye(3), B, Q, R, np.zeros((3, 2)), 0.01), k)
    assert np.array_equal(held.A, np.eye(3))
    assert _rel(held.B, k * B) <= 1e-13
    assert _rel(held.Q, k * Q) <= 1e-13
    assert _rel(held.N, k * (k - 1) / 2 * Q @ B) <= 1e-13
    assert _rel(held.R, k * R + (k - 1) * k * (2 * k - 1) / 6 * B.T @ Q @ B) <= 1e-13


def test_default_is_the_plant_step_and_k_1_is_the_model_itself():
    env = LinearSystemEnv()
    assert env.control_dt_s == env.model.dt_s == 0.01 and env.decision_steps == 1
    assert env.decision_model is env.model
    explicit = LinearSystemEnv(control_dt_s=0.01)
    assert explicit.decision_model is explicit.model and explicit.decision_steps == 1


def _episode(env, actions, seed=0):
    env.reset(seed=seed)
    J, times, done = 0.0, [], False
    for a in actions:
        assert not done
        _, r, te, tr, info = env.step(a)
        J += info["cost"]
        assert -r == info["cost"]
        times.append(info["time_s"])
        done = te or tr
    return J, env.state, times, done


def test_k500_env_matches_the_plant_step_env_fed_the_held_actions():
    """heravi-2017, 5 s decisions: J and the final state equal the dt_s env's (≤ 1e-9)."""
    steps, k = 4000, 500
    coarse = LinearSystemEnv(preset="heravi-2017", episode_steps=steps, control_dt_s=5.0)
    fine = LinearSystemEnv(preset="heravi-2017", episode_steps=steps)
    assert coarse.decision_steps == k
    actions = np.random.default_rng(0).uniform(-1, 1, (steps // k, 3)).astype(np.float32)
    J_coarse, x_coarse, times, done = _episode(coarse, actions)
    assert done and times == pytest.approx([5.0 * (i + 1) for i in range(steps // k)], rel=1e-12)
    J_fine, x_fine, _, done_fine = _episode(fine, np.repeat(actions, k, axis=0))
    assert done_fine
    assert abs(J_coarse - J_fine) <= 1e-9 * J_fine
    assert np.max(np.abs(x_coarse - x_fine)) <= 1e-9 * np.max(np.abs(x_fine))


def test_with_process_noise_the_k_env_is_bitwise_the_plant_step_env():
    kwargs = {"preset": "heravi-2017", "episode_steps": 60, "process_noise_std": 1e-3, "x0_std": 0.1}
    coarse = LinearSystemEnv(**kwargs, control_dt_s=0.2)
    fine = LinearSystemEnv(**kwargs)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, 3)).astype(np.float32)
    coarse.reset(seed=5)
    fine.reset(seed=5)
    for a in actions:
        _, _, _, _, info = coarse.step(a)
        costs = [fine.step(a)[4]["cost"] for _ in range(20)]
        assert np.array_equal(coarse.state, fine.state)  # the same draws, the same arithmetic
        assert info["cost"] == pytest.approx(sum(costs), rel=1e-13)  # the same terms, summed in another order


def test_time_limit_and_fault_onset_are_in_plant_steps_and_seconds():
    fault = [{"kind": "stuck", "index": 0, "value": 0.0, "onset_s": 12.0}]
    env = LinearSystemEnv(preset="heravi-2017", episode_steps=2000, control_dt_s=5.0, faults=fault)
    env.reset(seed=0)
    applied, truncated = [], []
    for _ in range(4):
        _, _, _, tr, info = env.step(np.ones(3, np.float32))
        applied.append(info["truth"]["applied"][0])
        truncated.append(tr)
    # the decisions at 0, 5 and 10 s precede the 12 s onset; the one at 15 s is faulty
    assert applied == [2.0, 2.0, 2.0, 0.0]
    assert truncated == [False, False, False, True] and info["time_s"] == pytest.approx(20.0)


@pytest.mark.parametrize("mode", ["hold", "none"])
def test_divergence_is_checked_per_decision_and_charged_in_plant_steps(mode):
    env = LinearSystemEnv(
        preset="heravi-2017",
        episode_steps=4000,
        control_dt_s=5.0,
        divergence_threshold=0.9,
        termination_cost=mode,
    )
    env.reset(seed=0)
    d = env.decision_model
    elapsed = 0
    for _ in range(8):
        elapsed += 500
        x = env.state
        u = np.array([2.0, 2.0, 2.0])
        _, _, terminated, _, info = env.step(np.ones(3, np.float32))
        x_next = env.state
        held = float(x @ d.Q @ x + 2 * x @ d.N @ u + u @ d.R @ u)
        if terminated:
            break
        assert info["cost"] == pytest.approx(held, rel=1e-12)
    assert terminated and np.abs(x_next).max() > 0.9
    assert elapsed < 4000
    charge = (4000 - elapsed) * float(x_next @ env.model.Q @ x_next) if mode == "hold" else 0.0
    assert info["cost"] == pytest.approx(held + charge, rel=1e-12)


def test_observation_bound_covers_a_decision_period():
    env = LinearSystemEnv(preset="heravi-2017", control_dt_s=5.0, process_noise_std=1e-3, divergence_threshold=10.0)
    d = env.decision_model
    reach = 10.0 * np.linalg.norm(d.A, np.inf) + np.linalg.norm(d.B, np.inf) * 2.0
    assert np.all(env.observation_space.high > reach) and np.all(env.observation_space.low < -reach)


@pytest.mark.parametrize("control_dt_s", [0.01, 0.05, 5.0])
def test_lqr_baseline_designs_for_the_decision_period(control_dt_s):
    """Unsaturated LQR on the decision-period model: the episode's J plus the end state's
    cost-to-go x_Tᵀ S x_T is x₀ᵀ S x₀ (dynamic programming), so the env charges the model's
    cost and the gain is its optimum."""
    env = LinearSystemEnv(preset="heravi-2017", episode_steps=4000, control_dt_s=control_dt_s)
    policy = LinearLQRPolicy(env)
    d = env.decision_model
    K, S, _ = dlqr(d.A, d.B, d.Q, d.R, d.N)
    assert np.array_equal(policy.gain, K)
    if control_dt_s == 0.01:  # one plant step per decision: the plant's dlqr, bit for bit
        assert np.array_equal(policy.gain, dlqr(env.model.A, env.model.B, env.model.Q, env.model.R)[0])
    obs, info = env.reset(seed=0)
    x0, J, done = env.state, 0.0, False
    while not done:
        action = policy.act(obs, info)
        assert np.max(np.abs(action)) < 1.0  # no saturation
        obs, _, te, tr, info = env.step(action)
        J += info["cost"]
        done = te or tr
    xT = env.state
    assert J + xT @ S @ xT == pytest.approx(x0 @ S @ x0, rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"control_dt_s": 0.015}, r"^control_dt_s must be a whole multiple k >= 1 of dt_s=0\.01 .*got 0\.015$"),
        ({"control_dt_s": 0.004}, r"^control_dt_s must be a whole multiple k >= 1 of dt_s=0\.01 .*got 0\.004$"),
        ({"control_dt_s": 0.0}, r"^control_dt_s must be in \(0, inf\), got 0\.0$"),
        ({"control_dt_s": -5.0}, r"^control_dt_s must be in \(0, inf\), got -5\.0$"),
        ({"control_dt_s": np.inf}, r"^control_dt_s must be in \(0, inf\), got inf$"),
        ({"control_dt_s": "0.1"}, r"^control_dt_s must be a number in \(0, inf\), got '0.1' .*pass control_dt_s=0.1"),
        ({"control_dt_s": "fast"}, r"^control_dt_s must be a number in \(0, inf\), got 'fast'"),
        ({"control_dt_s": True}, r"^control_dt_s must be a number in \(0, inf\), got True"),
        ({"control_dt_s": 0.05, "episode_steps": 1001}, r"^episode_steps must be a multiple of .* = 5, got .*1001$"),
        ({"dt_s": 0.5, "control_dt_s": 1.2}, r"^control_dt_s must be a whole multiple k >= 1 of dt_s=0\.5 "),
    ],
)
def test_bad_decision_periods_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(LS, **kwargs)


def test_whole_multiples_within_the_tolerance_are_accepted():
    env = LinearSystemEnv(preset="heravi-2017", control_dt_s=0.07 * (1 + 1e-12), episode_steps=700)
    assert env.decision_steps == 7


def test_q_learning_lqr_learns_the_decision_period_gain():
    """The model-free Q-learning LQR learns from the env's transitions: at 1 s decisions
    (k = 100) its gain is dlqr of the decision-period model, cross term included."""
    from agents.qlqr import QLearningLQR

    env = LinearSystemEnv(preset="heravi-2017", control_dt_s=1.0)
    d = env.decision_model
    K_star = dlqr(d.A, d.B, d.Q, d.R, d.N)[0]
    agent = QLearningLQR(
        env, method="policy_iteration", seed=0, state_std=[1.0, 1.0, 1.0, 0.05, 0.05, 0.05], exploration_std=1.0
    )
    agent.learn(samples_per_iteration=90)
    assert np.linalg.norm(agent.gain - K_star) <= 1e-8 * np.linalg.norm(K_star)
    rho = np.max(np.abs(np.linalg.eigvals(d.A - d.B @ K_star)))
    assert agent.history[-1]["spectral_radius"] == pytest.approx(rho, rel=1e-9)


@pytest.mark.parametrize("autoreset_mode", ["next_step", "same_step"])
def test_batched_env_matches_single_envs_through_divergence_and_autoreset(autoreset_mode):
    """5 s decisions with a limit some sub-envs cross: rewards (termination charge included),
    flags, times and observations bitwise the single envs' (seed s + i)."""
    kwargs = {"x0_std": 0.2, "episode_steps": 2000, "control_dt_s": 5.0, "divergence_threshold": 0.8}
    n = 4
    vec = gym.make_vec(LS, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=autoreset_mode, **kwargs)
    singles = [gym.make(LS, **kwargs).unwrapped for _ in range(n)]
    vec.reset(seed=3)
    for i, s in enumerate(singles):
        s.reset(seed=3 + i)
    rng = np.random.default_rng(4)
    done = np.zeros(n, dtype=bool)
    ended = terminated = 0
    for _ in range(12):
        actions = rng.uniform(-1, 1, (n, 3))
        obs, rewards, term, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            if autoreset_mode == "next_step" and done[i]:
                o, r, te, tr = s.reset()[0], 0.0, False, False
            else:
                o, r, te, tr, info = s.step(actions[i])
                assert infos["time_s"][i] == info["time_s"]
                if (te or tr) and autoreset_mode == "same_step":
                    assert np.array_equal(infos["final_obs"][i], o)
                    o = s.reset()[0]
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
        done = term | trunc
        ended += int(done.sum())
        terminated += int(term.sum())
    assert terminated >= 1 and ended > terminated
