"""The MPC baselines of FuelSlosh-v0 (baselines.mpc_slosh) and LinearSystem-v0 (baselines.mpc_linear):
prediction model = env step, short episodes with successful solves, linear MPC = LQR off the bounds."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

pytest.importorskip("casadi")

import gymnasium as gym  # noqa: E402

import attitude_envs  # noqa: E402, F401  (registers the envs)
from baselines import compiled_nlp  # noqa: E402
from baselines.linear_lqr import LinearLQRPolicy  # noqa: E402
from baselines.mpc_linear import LinearMPCPolicy, decision_matrices  # noqa: E402
from baselines.mpc_slosh import SloshMPCPolicy, measured_full_state  # noqa: E402

SLOSH_KW = {"preset": "navabi-fill-i", "episode_duration_s": 100.0, "randomize_initial_state": True}
LINEAR_KW = {"preset": "heravi-2017", "episode_steps": 40000}


def _make(env_id: str, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return gym.make(env_id, **kwargs)


def test_slosh_prediction_model_matches_env_step():
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    _, info = env.reset(seed=3)
    policy = SloshMPCPolicy(env, horizon_steps=2)
    rng = np.random.default_rng(0)
    for _ in range(5):
        y = env.unwrapped.state
        np.testing.assert_array_equal(measured_full_state(info["measured"]), y)
        a = rng.uniform(-0.05, 0.05, 2)  # small: no termination limit crossed (no extra charge)
        _, reward, terminated, _, info = env.step(a.astype(np.float32))
        assert not terminated
        a32 = a.astype(np.float32).astype(float)  # the env receives the float32 action
        y_pred, cost_pred = policy.model_step(y, a32, np.zeros(2))
        y_next = env.unwrapped.state
        scale = np.maximum(1.0, np.abs(y_next))
        assert np.max(np.abs(np.asarray(y_pred).ravel() - y_next) / scale) <= 1e-9
        assert abs(float(cost_pred) + reward) <= 1e-9 * max(1.0, abs(reward))


def test_linear_prediction_model_matches_env_step():
    env = _make("attitude_envs/LinearSystem-v0", **LINEAR_KW)
    obs, _ = env.reset(seed=1)
    policy = LinearMPCPolicy(env, horizon_steps=3)
    scale = env.unwrapped.action_scale
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = env.unwrapped.state.copy()
        a = rng.uniform(-1.0, 1.0, 3).astype(np.float32)
        x_pred, cost_pred = policy.model_step(x, scale * a.astype(float))
        _, reward, _, _, _ = env.step(a)
        np.testing.assert_allclose(np.asarray(x_pred).ravel(), env.unwrapped.state, rtol=0, atol=1e-9)
        assert abs(float(cost_pred) + reward) <= 1e-9 * max(1.0, abs(reward))


@pytest.mark.parametrize("faults, effectiveness", [(False, True), (True, False), (True, True)])
def test_slosh_mpc_short_episode(faults, effectiveness):
    kwargs = dict(SLOSH_KW, episode_duration_s=2.0)
    if faults:  # onset inside the episode: the offset-free estimate must pick up the bias
        kwargs["faults"] = [{"kind": "bias", "target": "actuator", "index": 1, "value": 200.0, "onset_s": 0.5}]
    env = _make("attitude_envs/FuelSlosh-v0", **kwargs)
    policy = SloshMPCPolicy(env, horizon_steps=3, estimate_effectiveness=effectiveness)
    limits = env.unwrapped.actuator_limits
    obs, info = env.reset(seed=2)
    policy.reset(2)
    steps, previous = 0, None
    while True:
        a = policy.act(obs, info)  # updates the estimates from the last step
        assert a.shape == (2,) and np.all(np.abs(a) <= 1.0)
        if previous is not None and steps >= 16:  # window past the onset: the fitted actuator
            a_prev, applied_prev = previous  # model reproduces the last applied input (< 1e-4 of the limits)
            predicted = policy.effectiveness_estimate * a_prev * limits + policy.disturbance_estimate
            assert np.all(np.abs(predicted - applied_prev) <= 1e-4 * limits), (predicted, applied_prev)
        obs, _, terminated, truncated, info = env.step(a)
        previous = (a.astype(float), info["truth"]["applied"])
        steps += 1
        if terminated or truncated:
            break
    assert not terminated and steps == 20
    assert len(policy.solve_times_s) == steps and policy.failures == 0
    if not effectiveness:  # a pure bias is estimated exactly as the input disturbance
        np.testing.assert_allclose(policy.disturbance_estimate, [0.0, 200.0 if faults else 0.0], atol=1e-3)


def test_slosh_actuator_window_keeps_its_data_after_a_loss_of_effectiveness():
    """The estimator's regression window (``applied = θ·command + β`` per actuator) restarts at a
    fault's onset and then fills again, so θ and β converge to the faulty actuator's. Before the
    fix the restart test was the *filtered* estimate's miss, which after a loss of effectiveness
    restarted the window at every step: θ stayed at the one-point ridge fit."""
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    policy = SloshMPCPolicy(env, horizon_steps=2, window_steps=10)
    policy.reset(0)
    rng = np.random.default_rng(0)
    theta, bias = np.array([1.0, 0.5]), np.array([0.0, 0.1])  # thruster 1: 50 % loss and a bias
    lengths = []
    for k in range(30):
        command = rng.uniform(-0.8, 0.8, size=2)  # varied commands: the fit is identifiable
        applied = command if k < 10 else theta * command + bias  # the fault acts from step 10
        policy._update_actuators(command, applied)
        lengths.append(len(policy._history))
    assert lengths[9] == 10  # a full window before the onset
    assert lengths[10] == 1  # the onset's point misses the old fit: the window restarts
    assert lengths[11:19] == list(range(2, 10)) and lengths[19:] == [10] * 11  # and fills again
    np.testing.assert_allclose(policy.effectiveness_estimate, theta, atol=1e-3)
    np.testing.assert_allclose(policy.disturbance_estimate / env.unwrapped.actuator_limits, bias, atol=1e-3)


def test_linear_mpc_short_episode_and_equals_lqr_off_bounds():
    env = _make("attitude_envs/LinearSystem-v0", **dict(LINEAR_KW, episode_steps=30))
    mpc = LinearMPCPolicy(env, horizon_steps=10, unconstrained_shortcut=False)
    lqr = LinearLQRPolicy(env)
    obs, info = env.reset(seed=0)
    mpc.reset(0)
    while True:
        a = mpc.act(obs, info)
        np.testing.assert_allclose(a, lqr.act(obs, info), rtol=0, atol=1e-6)
        obs, _, terminated, truncated, info = env.step(a)
        if terminated or truncated:
            break
    assert mpc.qp_solves == 30 and mpc.failures == 0 and len(mpc.solve_times_s) == 30


def test_linear_mpc_respects_bounds_where_lqr_saturates():
    env = _make("attitude_envs/LinearSystem-v0", **dict(LINEAR_KW, episode_steps=5))
    mpc = LinearMPCPolicy(env, horizon_steps=10)
    env.reset(seed=0)
    x0 = 50.0 * np.ones(6)  # far out: the LQR's input exceeds the bound
    assert np.max(np.abs(mpc.gain @ x0)) > np.max(env.unwrapped.action_scale)
    u = mpc.plan(x0)
    assert mpc.qp_solves == 1 and mpc.failures == 0
    assert np.all(np.abs(u) <= np.asarray(env.unwrapped.action_scale) + 1e-9)


def test_decision_matrices_fallback_is_the_env_model():
    env = _make("attitude_envs/LinearSystem-v0", **LINEAR_KW)
    m = decision_matrices(env)
    base = env.unwrapped
    if getattr(base, "decision_model", None) is None:
        np.testing.assert_array_equal(m.A, base.model.A)
        np.testing.assert_array_equal(m.B, base.model.B)
        np.testing.assert_array_equal(m.Q, base.cost.Q)
        assert not np.any(m.N) and m.dt_s == base.model.dt_s


@pytest.mark.parametrize(
    "kwargs, match",
    [({"horizon_steps": 0}, "horizon_steps"), ({"qp_solver": "nope"}, "qp_solver")],
)
def test_linear_mpc_bad_input(kwargs, match):
    env = _make("attitude_envs/LinearSystem-v0", **LINEAR_KW)
    with pytest.raises(ValueError, match=match):
        LinearMPCPolicy(env, **kwargs)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"horizon_steps": 0}, "horizon_steps"),
        ({"disturbance_gain": 1.5}, "disturbance_gain"),
        ({"solver": "qpoases"}, "solver"),
        ({"initial_guess": "zero"}, "initial_guess"),
        ({"max_iter": 0}, "max_iter"),
        ({"solver_options": {"ipopt.mu_init": 1e-4}}, "solver_options"),
        ({"compiled": "yes"}, "compiled"),
    ],
)
def test_slosh_mpc_bad_input(kwargs, match):
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    with pytest.raises(ValueError, match=match):
        SloshMPCPolicy(env, **kwargs)


def _slosh_problem(policy, seed: int):
    """The NLP arguments of ``policy``'s first decision from FuelSlosh-v0's start on ``seed``,
    started from the LQR's rollout."""
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    env.reset(seed=seed)
    y0 = env.unwrapped.state.copy()
    a_guess, y_guess = policy._initial_guess(y0, np.zeros(2))
    n = policy.horizon_steps
    return {
        "x0": np.r_[a_guess.ravel(order="F"), y_guess.ravel(order="F")],
        "p": np.r_[y0, np.zeros(2)],
        "lbx": np.r_[-np.ones(2 * n), -policy._free],
        "ubx": np.r_[np.ones(2 * n), policy._free],
        "lbg": policy._lbg,
        "ubg": policy._ubg,
    }


def test_slosh_sqp_and_interior_point_reach_the_same_optimum():
    """From the LQR's rollout, SQP (the default) and IPOPT solve the first decision's NLP of seed
    0's start to the same objective and action. The NLP is nonconvex: from larger starts the two
    can end in different local minima (seed 3's first decision: SQP's objective 1.8 % above
    IPOPT's), which is why the campaign's J is compared per solver on its 40 episodes."""
    seed = 0
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    sqp = SloshMPCPolicy(env, horizon_steps=5)
    ipopt = SloshMPCPolicy(env, horizon_steps=5, solver="ipopt")
    args = _slosh_problem(sqp, seed)
    sol_sqp, ok_sqp = sqp._solve(**args)
    sol_ipopt, ok_ipopt = ipopt._solve(**args)
    assert ok_sqp and ok_ipopt and sqp.fallbacks == 0
    f_sqp, f_ipopt = float(sol_sqp["f"]), float(sol_ipopt["f"])
    assert abs(f_sqp - f_ipopt) <= 1e-6 * abs(f_ipopt), (f_sqp, f_ipopt)
    np.testing.assert_allclose(np.asarray(sol_sqp["x"])[:2], np.asarray(sol_ipopt["x"])[:2], atol=1e-5)


@pytest.mark.parametrize("initial_guess", ["lqr", "shifted"])
def test_slosh_mpc_decisions_start_where_asked(initial_guess):
    """Through ``act``: the second decision's solve starts from the LQR's rollout from its state
    (``"lqr"``) or from the first solution shifted by one step (``"shifted"``)."""
    env = _make("attitude_envs/FuelSlosh-v0", **dict(SLOSH_KW, episode_duration_s=1.0))
    policy = SloshMPCPolicy(env, horizon_steps=3, initial_guess=initial_guess)
    calls = []
    solve = policy._solve

    def recording_solve(**args):
        sol, solved = solve(**args)
        calls.append((args, np.asarray(sol["x"]).ravel()))
        return sol, solved

    policy._solve = recording_solve
    obs, info = env.reset(seed=3)
    policy.reset(3)
    for _ in range(2):
        obs, _, _, _, info = env.step(policy.act(obs, info))
    (_, w_first), (args, _) = calls
    n_a, n_y = 2 * policy.horizon_steps, 10
    y0, d = args["p"][:n_y], args["p"][n_y:]
    if initial_guess == "lqr":
        policy.initial_guess = "lqr"
        a_start, y_start = policy._initial_guess(y0, d)
    else:
        a_first = w_first[:n_a].reshape(2, -1, order="F")
        y_start = w_first[n_a:].reshape(n_y, -1, order="F")
        a_start = np.column_stack([a_first[:, 1:], a_first[:, -1:]])
        y_start = np.column_stack([y_start[:, 1:], y_start[:, -1:]])
        y_start[:, 0] = y0
    a_start = np.clip(a_start.ravel(order="F"), args["lbx"][:n_a], args["ubx"][:n_a])
    np.testing.assert_allclose(args["x0"], np.r_[a_start, y_start.ravel(order="F")], rtol=0, atol=1e-12)


def test_slosh_mpc_decisions_go_through_the_fallback():
    """``act`` solves through the fallback: with SQP capped at one iteration every decision that
    SQP cannot finish is redone by IPOPT (counted in ``fallbacks``), none fails, and each
    decision's time includes both solves."""
    env = _make("attitude_envs/FuelSlosh-v0", **dict(SLOSH_KW, episode_duration_s=0.5))
    policy = SloshMPCPolicy(env, horizon_steps=3, max_iter=1)
    fallback, fallback_s = policy._fallback, []

    def timed_fallback(**args):
        t0 = time.perf_counter()
        sol = fallback(**args)
        fallback_s.append(time.perf_counter() - t0)
        return sol

    timed_fallback.stats = fallback.stats
    policy._fallback = timed_fallback
    obs, info = env.reset(seed=3)
    policy.reset(3)
    times = []
    for _ in range(5):
        before = len(fallback_s)
        obs, _, _, _, info = env.step(policy.act(obs, info))
        times.append((policy.solve_times_s[-1], sum(fallback_s[before:])))
    assert policy.fallbacks == len(fallback_s) >= 1 and policy.failures == 0
    assert all(decision >= redo for decision, redo in times)


def test_slosh_sqp_failure_falls_back_to_ipopt():
    """An SQP solve that fails (here: capped at one iteration from a guess far from the optimum)
    is solved again by IPOPT from the same guess, and counted."""
    env = _make("attitude_envs/FuelSlosh-v0", **SLOSH_KW)
    capped = SloshMPCPolicy(env, horizon_steps=5, max_iter=1)
    ipopt = SloshMPCPolicy(env, horizon_steps=5, solver="ipopt")
    args = _slosh_problem(capped, 3)
    args["x0"] = np.zeros_like(args["x0"])
    starts = []
    fallback = capped._fallback
    capped._fallback = lambda **a: (starts.append(a["x0"].copy()), fallback(**a))[1]
    capped._fallback.stats = fallback.stats
    sol, ok = capped._solve(**args)
    assert ok and capped.fallbacks == 1
    np.testing.assert_array_equal(starts[0], args["x0"])  # IPOPT starts from SQP's guess
    reference, _ = ipopt._solve(**args)
    assert abs(float(sol["f"]) - float(reference["f"])) <= 1e-9 * abs(float(reference["f"]))


def test_linear_mpc_at_a_longer_decision_period():
    """With ``control_dt_s`` = k·dt_s the MPC predicts with the env's decision model (k-step
    matrices, cost with cross term) and equals that model's discrete LQR off the bounds."""
    try:
        env = _make("attitude_envs/LinearSystem-v0", **dict(LINEAR_KW, episode_steps=50), control_dt_s=0.05)
    except TypeError:
        pytest.skip("LinearSystem-v0 has no control_dt_s")
    obs, info = env.reset(seed=0)
    mpc = LinearMPCPolicy(env, horizon_steps=5, unconstrained_shortcut=False)
    d = env.unwrapped.decision_model
    np.testing.assert_array_equal(mpc.matrices.A, d.A)
    np.testing.assert_array_equal(mpc.matrices.N, d.N)
    scale = env.unwrapped.action_scale
    for _ in range(3):
        x = env.unwrapped.state.copy()
        a = mpc.act(obs, info)
        k_gain = mpc.gain
        np.testing.assert_allclose(a, np.clip(-k_gain @ x / scale, -1, 1), rtol=0, atol=1e-6)
        x_pred, cost_pred = mpc.model_step(x, scale * a.astype(float))
        obs, reward, _, _, info = env.step(a)
        np.testing.assert_allclose(np.asarray(x_pred).ravel(), env.unwrapped.state, rtol=0, atol=1e-9)
        assert abs(float(cost_pred) + reward) <= 1e-9 * max(1.0, abs(reward))


@pytest.mark.skipif(compiled_nlp.c_compiler() is None, reason="no C compiler on PATH")
def test_slosh_mpc_compiled_decides_as_interpreted(tmp_path, monkeypatch):
    """``compiled=True`` (the slosh campaign's setting: the NLP's functions compiled to C) makes
    the same decisions as the interpreted solver over a short episode with a disturbance (compiled
    with -O0 on a 1-step horizon here to keep the test short; the campaign's -O1 builds once per
    machine)."""
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path))
    monkeypatch.setattr(compiled_nlp, "DEFAULT_FLAGS", ("-O0",))
    env = _make("attitude_envs/FuelSlosh-v0", **dict(SLOSH_KW, episode_duration_s=1.0))
    policies = [SloshMPCPolicy(env, horizon_steps=1, compiled=c) for c in (False, True)]
    obs, info = env.reset(seed=3)
    for policy in policies:
        policy.reset(3)
    for _ in range(10):
        actions = [policy.act(obs, info) for policy in policies]
        np.testing.assert_allclose(actions[1], actions[0], rtol=0, atol=1e-10)
        obs, _, _, _, info = env.step(actions[0])
    assert [p.failures for p in policies] == [0, 0]
    assert len(list(tmp_path.glob("casadi/mpc_slosh_sqp-*.casadi"))) == 1
