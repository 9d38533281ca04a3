"""Symbolic (CasADi) discrete models of FuelSlosh-v0 and Magnetorquer-v0: the step agrees with
the env's compiled step to round-off (states and step cost), with and without faults, and a
short J* solve beats the env's baselines and replays through the env."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

import attitude_envs  # noqa: E402,F401  (registers the envs)
from attitude_envs.info import policy_view  # noqa: E402
from attitude_envs.symbolic import BUILDERS, problem_for  # noqa: E402
from experiments.policies import build_policy  # noqa: E402

RTOL = 1e-9
SLOSH_FAULTS = [
    {"kind": "loss_of_effectiveness", "index": 1, "value": 0.3, "onset_s": 0.5},
    {"kind": "effectiveness", "index": 0, "schedule": [[0.0, 1.0], [1.0, 0.6], [2.0, 0.9]]},
    {"kind": "bias", "index": 1, "value": 5.0, "onset_s": 1.0, "duration_s": 0.6},
]
MAGNETORQUER_FAULTS = [  # the paper's eq. (40) effectiveness, earlier, and a wheel bias
    {"kind": "loss_of_effectiveness", "index": i, "value": v, "onset_s": 0.5} for i, v in enumerate((0.1, 0.3, 0.4))
] + [{"kind": "bias", "index": 3, "value": 1e-5, "onset_s": 1.0}]


def _actions(n: int, n_u: int, scale: float) -> np.ndarray:
    """A fixed, smooth, non-saturating action sequence."""
    k = np.arange(n)[:, None]
    return scale * np.sin(0.07 * k * (1 + np.arange(n_u)) + np.arange(n_u))


def _compare(env, problem, actions, state) -> None:
    """Step the env and the symbolic step from the same states; both agree to ``RTOL``."""
    inputs = problem.step_inputs()
    x = problem.x0
    np.testing.assert_array_equal(x, state())
    for k, a in enumerate(actions):
        _, reward, terminated, _, _ = env.step(a)
        assert not terminated
        x_next, cost = problem.step(x, a, inputs[:, k])
        y = state()
        np.testing.assert_allclose(np.asarray(x_next).ravel(), y, rtol=RTOL, atol=RTOL * 1e-3 * np.max(np.abs(y)))
        assert float(cost) == pytest.approx(-reward, rel=RTOL)
        x = y


def test_both_builders_are_registered():
    assert {"FuelSlosh-v0", "Magnetorquer-v0"} <= set(BUILDERS)


@pytest.mark.parametrize("faults", [None, SLOSH_FAULTS], ids=["healthy", "faults"])
def test_fuel_slosh_step_matches_the_env(faults):
    env = gym.make("attitude_envs/FuelSlosh-v0", episode_duration_s=3.0, faults=faults)
    problem = problem_for(env, seed=0)
    base = env.unwrapped
    assert (problem.n_x, problem.n_u, problem.n_steps) == (10, 2, 30)
    assert problem.params is None
    _compare(env, problem, _actions(problem.n_steps, 2, 0.02), lambda: base.state)
    g = np.asarray(problem.g(problem.x0)).ravel()
    assert g.shape == (8,) and np.all(g < 0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"gravity_gradient": True, "integrator_dt_s": 0.05, "disturbance_second_harmonic": True},
        # a full (non-diagonal) Q and R: the kernel's general cost path
        {"Q": np.diag([1.0] * 3 + [1e3] * 3) + 0.1, "R": 1e4 * np.eye(3) + 10.0},
    ],
    ids=["paper", "gravity-gradient-substeps", "full-weights"],
)
@pytest.mark.parametrize("faults", [None, MAGNETORQUER_FAULTS], ids=["healthy", "faults"])
def test_magnetorquer_step_matches_the_env(kwargs, faults):
    env = gym.make("attitude_envs/Magnetorquer-v0", episode_duration_s=3.0, **kwargs)
    options = None if faults is None else {"faults": faults}
    problem = problem_for(env, seed=2, options=options)
    base = env.unwrapped
    assert (problem.n_x, problem.n_u, problem.n_steps) == (8, 4, 30)
    assert problem.params.shape[0] == 30
    _compare(env, problem, _actions(problem.n_steps, 4, 0.5), lambda: np.array(base.state_row))


def test_magnetorquer_igrf_field_matches_the_env():
    pytest.importorskip("ppigrf")
    env = gym.make("attitude_envs/Magnetorquer-v0", episode_duration_s=2.0, field_model="igrf")
    problem = problem_for(env, seed=1)
    _compare(env, problem, _actions(problem.n_steps, 4, 0.5), lambda: np.array(env.unwrapped.state_row))


def test_unsupported_settings_raise():
    walk = {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-7}
    env = gym.make("attitude_envs/Magnetorquer-v0", episode_duration_s=2.0, disturbance=walk)
    with pytest.raises(ValueError, match="random_walk"):
        problem_for(env, seed=0)
    env = gym.make("attitude_envs/FuelSlosh-v0", episode_duration_s=2.0)
    with pytest.raises(ValueError, match="intermittent"):
        problem_for(env, seed=0, options={"faults": [{"kind": "intermittent", "index": 0}]})


def _baseline_cost(env_id: str, env_kwargs: dict, name: str, seed: int) -> float:
    env = gym.make(f"attitude_envs/{env_id}", **env_kwargs)
    policy = build_policy({"policy": name}, env)
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    total, done = 0.0, False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += info["cost"]
        done = terminated or truncated
    return total


@pytest.mark.parametrize(
    ("env_id", "env_kwargs", "baselines"),
    [
        ("FuelSlosh-v0", {"episode_duration_s": 3.0}, ["slosh-lqr", "slosh-pd", "slosh-fuzzy"]),
        ("Magnetorquer-v0", {"episode_duration_s": 20.0}, ["amnftsmc", "bdot"]),
    ],
    ids=["fuel-slosh", "magnetorquer"],
)
def test_short_optimum_beats_the_baselines_and_replays(env_id, env_kwargs, baselines):
    optimum = pytest.importorskip("experiments.optimum")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the fuzzy baseline's skfuzzy notices
        costs = {name: _baseline_cost(env_id, env_kwargs, name, seed=0) for name in baselines}
        env = gym.make(f"attitude_envs/{env_id}", **env_kwargs)
        problem = problem_for(env, seed=0)
        actions0, _ = optimum.baseline_rollout(env, optimum.BASELINES[env_id][0], 0, None, problem.n_steps)
        actions, j_nlp, status, _, _ = optimum.solve_problem(
            problem, actions0, max_iter=300, tol=1e-8, ipopt_options={"expand": False}
        )
    assert status in optimum.SOLVED
    j_star, terminated = optimum.replay(env, np.clip(actions, -1.0, 1.0), 0, None)
    assert not terminated
    assert j_star == pytest.approx(j_nlp, rel=1e-6)
    assert j_star <= min(costs.values()) * (1 + 1e-9)
