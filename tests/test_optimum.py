"""The optimal-control yardstick J*: symbolic models agree with the envs, J* matches the
finite-horizon Riccati value on an LTI plant, beats every baseline, replays exactly, and the
CLI writes its table."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

import attitude_envs  # noqa: E402,F401  (registers the env ids)
from attitude_envs.evaluation import rollout  # noqa: E402
from attitude_envs.symbolic import problem_for  # noqa: E402
from experiments import optimum  # noqa: E402
from experiments.cli import main  # noqa: E402
from experiments.policies import build_policy  # noqa: E402

LOE = [{"kind": "loss_of_effectiveness", "index": 1, "value": 0.4, "onset_s": 0.5}]
RW_SHORT = {"episode_duration_s": 4.0, "control_dt_s": 0.1}


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))


def _true_state(env) -> np.ndarray:
    base = env.unwrapped
    return np.array(base.state_row if hasattr(base, "state_row") else base.state)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "scale"),
    [
        ("LinearSystem-v0", {"faults": LOE}, 0.5),
        ("ReactionWheel-v0", {**RW_SHORT, "faults": LOE}, 0.5),
        ("ReactionWheel-v0", {**RW_SHORT, "action_frame": "body", "integrator_dt_s": 0.05, "faults": LOE}, 0.5),
        (
            "ReactionWheel-v0",
            {
                **RW_SHORT,
                "cost_input": "wheel",
                "R": np.eye(4),
                "wheel_momentum_weight": 5.0,
                "inertia_uncertainty": {"kind": "random"},
                "disturbance": {"kind": "sinusoidal", "amplitude_nm": [0.01, 0.02, 0.0], "phase_rad": "random"},
                "faults": [*LOE, {"kind": "bias", "index": 2, "value": 0.01}],
            },
            0.3,
        ),
        (
            "AirBearing-v0",
            {"episode_duration_s": 1.0, "disturbance": {"kind": "constant", "torque_nm": [0.01] * 3}, "faults": LOE},
            1.0,
        ),
    ],
)
def test_builder_matches_env_step(env_id, kwargs, scale):
    env = gym.make(optimum.full_id(env_id), **kwargs)
    problem = problem_for(env, seed=3)
    x = problem.x0.copy()
    np.testing.assert_array_equal(x, _true_state(env))
    actions = scale * np.random.default_rng(0).uniform(-1.0, 1.0, (min(problem.n_steps, 40), problem.n_u))
    for k, a in enumerate(actions):
        _, _, terminated, _, info = env.step(a)
        x_next, cost = problem.step(x, a, float(k))
        x = np.asarray(x_next).ravel()
        truth = _true_state(env)
        assert np.max(np.abs(x - truth)) <= 1e-9 * max(1.0, np.max(np.abs(truth)))
        assert abs(float(cost) - info["cost"]) <= 1e-9 * abs(info["cost"])
        assert not terminated


def test_unsupported_faults_and_disturbances_are_named():
    env = gym.make("attitude_envs/ReactionWheel-v0", faults=[{"kind": "intermittent", "index": 0}], **RW_SHORT)
    with pytest.raises(ValueError, match="intermittent"):
        problem_for(env, seed=0)
    env = gym.make(
        "attitude_envs/ReactionWheel-v0", disturbance={"kind": "random_walk", "std_nm_per_sqrt_s": 1e-3}, **RW_SHORT
    )
    with pytest.raises(ValueError, match="random_walk"):
        problem_for(env, seed=0)


def _riccati_cost(A, B, Q, R, x0, n_steps) -> float:
    """min Σ_{k<N} (xᵀQx + uᵀRu) with no terminal cost: x0ᵀP_0x0, P_N = 0."""
    P = np.zeros_like(Q)
    for _ in range(n_steps):
        gain = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ A - A.T @ P @ B @ gain
    return float(x0 @ P @ x0)


def test_lti_optimum_is_the_riccati_value():
    A = np.array([[1.0, 0.1], [-0.05, 0.98]])
    B = np.array([[0.005], [0.1]])
    Q, R = np.diag([2.0, 0.5]), np.array([[0.3]])
    x0 = np.array([1.0, -0.5])
    kwargs = {"A": A, "B": B, "Q": Q, "R": R, "episode_steps": 20, "action_scale": 1e3}
    result = optimum.solve_episode("LinearSystem-v0", kwargs, seed=0, options={"state": x0})
    expected = _riccati_cost(A, B, Q, R, x0, 20)
    assert result.solved and result.oracle
    assert abs(result.j_star - expected) <= 1e-6 * expected
    assert np.max(np.abs(result.actions)) < 1.0  # no action clipping active
    assert abs(result.j_star - result.j_nlp) <= 1e-6 * result.j_nlp


def test_fixed_prefix_optimum_is_the_riccati_value_of_the_rest():
    """``solve_problem(fixed_steps=m)`` holds the first m actions and optimizes the rest: on an
    LTI plant its objective is the prefix's cost plus the Riccati value of the remaining N − m
    steps from the state the prefix reaches."""
    A = np.array([[1.0, 0.1], [-0.05, 0.98]])
    B = np.array([[0.005], [0.1]])
    Q, R = np.diag([2.0, 0.5]), np.array([[0.3]])
    kwargs = {"A": A, "B": B, "Q": Q, "R": R, "episode_steps": 20, "action_scale": 1e3}
    env = gym.make(optimum.full_id("LinearSystem-v0"), **kwargs)
    problem = problem_for(env, seed=0, options={"state": np.array([1.0, -0.5])})
    prefix = np.full((problem.n_steps, problem.n_u), 0.2e-3)  # 0.2 N·m, far from the optimum's
    actions, objective, status, _, _ = optimum.solve_problem(problem, prefix, fixed_steps=5)
    assert status == "Solve_Succeeded"
    np.testing.assert_array_equal(actions[:5], prefix[:5])  # held exactly (IPOPT's fixed variables)
    states, costs = problem.rollout(actions)
    expected = costs[:5].sum() + _riccati_cost(A, B, Q, R, states[5], 15)
    assert abs(objective - expected) <= 1e-6 * expected
    free = optimum.solve_problem(problem, prefix)[1]
    assert free < objective  # the prefix is not the optimum's, so holding it costs J
    for bad in (21, -1, 2.5, None, True):
        with pytest.raises(ValueError, match="fixed_steps"):
            optimum.solve_problem(problem, prefix, fixed_steps=bad)


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("LinearSystem-v0", {"episode_steps": 60}),
        ("ReactionWheel-v0", RW_SHORT),
        ("ReactionWheel-v0", {**RW_SHORT, "faults": LOE}),
        ("AirBearing-v0", {"episode_duration_s": 1.0}),
    ],
)
def test_optimum_beats_every_baseline_and_replays(env_id, kwargs):
    seed = 1
    result = optimum.solve_episode(env_id, kwargs, seed=seed)
    assert result.solved, result.status
    assert not result.terminated
    assert abs(result.j_star - result.j_nlp) <= 1e-6 * result.j_nlp  # replay through the real env
    env = gym.make(optimum.full_id(env_id), **kwargs)
    for name, params in optimum.BASELINES[env_id]:
        j = rollout(env, build_policy({"policy": name, "params": params}, env), seed=seed)["J"]
        assert result.j_star <= j * (1 + 1e-9), (name, params, result.j_star, j)
    again = optimum.solve_episode(env_id, kwargs, seed=seed)  # from the on-disk cache
    assert again.cached and again.j_star == result.j_star
    np.testing.assert_array_equal(again.actions, result.actions)


def test_cli_writes_optimum_json(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["optimum", "--env", "LinearSystem-v0", "--env-kwargs", "{episode_steps: 15}", "--seeds", "0,2"]
    assert main([*argv, "--faults", "[{kind: outage, index: 0, onset_s: 0.05}]", "--out", str(out)]) == 0
    rows = json.loads((out / "optimum.json").read_text())
    assert [r["seed"] for r in rows] == [0, 2]
    for row in rows:
        assert {"seed", "j_star", "j_nlp", "solve_s", "status", "oracle", "env_id", "env_kwargs"} <= set(row)
        assert row["oracle"] is True and row["env_id"] == "LinearSystem-v0"
        assert row["env_kwargs"]["faults"][0]["kind"] == "outage"
    assert (out / "optimum.md").is_file()
    assert "seed 2" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:  # a usage error: argparse's one line, exit status 2
        main([*argv, "--out", str(tmp_path / "x"), "--seeds", "a"])
    assert exc.value.code == 2 and "argument --seeds: must be a count N" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    assert main(["optimum", "--env", "LinearSystem-v0", "--out", str(tmp_path / "file")]) == 2


def test_an_actions_warm_start_is_cached_by_its_content():
    kwargs = {"episode_steps": 15}
    first = optimum.solve_episode("LinearSystem-v0", kwargs, seed=0)
    warm = first.actions.copy()
    result = optimum.solve_episode("LinearSystem-v0", kwargs, seed=0, warm_start=warm)
    assert not result.cached and result.warm_start == "actions"
    again = optimum.solve_episode("LinearSystem-v0", kwargs, seed=0, warm_start=warm.copy())
    assert again.cached and again.j_star == result.j_star
    warm[0, 0] += 1e-3  # another warm start: another entry
    assert not optimum.solve_episode("LinearSystem-v0", kwargs, seed=0, warm_start=warm).cached
