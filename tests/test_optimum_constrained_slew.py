"""J* of ConstrainedSlew-v0 (:mod:`attitude_envs.symbolic.constrained_slew`): a short 60° slew
whose eigenaxis path crosses a keep-out cone, warm-started from the CBF-filtered slew."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("casadi")
pytest.importorskip("clarabel")

import gymnasium as gym  # noqa: E402

import attitude_envs  # noqa: E402, F401
from attitude_envs import quaternion  # noqa: E402
from attitude_envs.info import policy_view  # noqa: E402
from attitude_envs.symbolic import BUILDERS, FLIGHT_BUILDERS, problem_for  # noqa: E402
from attitude_envs.symbolic import constrained_slew as cs  # noqa: E402
from attitude_envs.symbolic.gyrostat import build_reaction_wheel  # noqa: E402
from baselines.cbf import CBFSafetyFilterPolicy, EigenaxisSlewPolicy  # noqa: E402
from experiments import optimum  # noqa: E402

ENV = "ConstrainedSlew-v0"
KWARGS = {"episode_duration_s": 20.0}
X = np.array([1.0, 0.0, 0.0])


def _options(cones: bool = True) -> dict:
    """Identity to 60° about x: the star tracker (+z) sweeps the y-z plane; a 15° Sun cone
    centred 8° off that plane at the path's midpoint."""
    mid = np.array([0.0, -math.sin(math.radians(30.0)), math.cos(math.radians(30.0))])
    d = math.cos(math.radians(8.0)) * mid + math.sin(math.radians(8.0)) * X
    return {
        "attitude": np.array([0.0, 0.0, 0.0, 1.0]),
        "target_attitude": quaternion.from_axis_angle(X, math.radians(60.0)),
        "keep_out_cones": [{"inertial_direction": list(d / np.linalg.norm(d)), "half_angle_deg": 15.0}]
        if cones
        else [],
    }


def _rollout(env, policy, n_steps):
    obs, info = env.reset(seed=0, options=_options())
    actions = np.zeros((n_steps, env.action_space.shape[0]))
    for k in range(n_steps):
        actions[k] = policy.act(obs, policy_view(info))
        obs, _, terminated, truncated, info = env.step(actions[k])
        if terminated or truncated:
            break
    return actions, info


def _replay(env, actions, options):
    """The last info and the least cone margin (deg) of ``actions`` replayed from ``reset(seed=0)``."""
    _, info = env.reset(seed=0, options=options)
    margins = []
    for a in actions:
        _, _, _, _, info = env.step(a)
        margins.append(min(info["constraint_margins_deg"].values(), default=np.inf))
    return info, min(margins)


@pytest.fixture(scope="module")
def env():
    e = gym.make(f"attitude_envs/{ENV}", **KWARGS)
    yield e
    e.close()


@pytest.fixture(scope="module")
def solved(env):
    problem = problem_for(env, seed=0, options=_options())
    _, eig = _rollout(env, EigenaxisSlewPolicy(env), problem.n_steps)
    warm, cbf = _rollout(env, CBFSafetyFilterPolicy(env), problem.n_steps)
    constrained = optimum.solve_episode(ENV, KWARGS, 0, options=_options(), warm_start=warm, cache=False)
    free = optimum.solve_episode(ENV, KWARGS, 0, options=_options(cones=False), warm_start=warm, cache=False)
    # the plain ReactionWheel-v0 problem of the same episode: no cone, rate or wheel-speed limit
    env.reset(seed=0, options=_options())
    plain = build_reaction_wheel(env.unwrapped)
    a_plain, _, status, _, _ = optimum.solve_problem(plain, warm)
    a_plain = np.clip(a_plain, plain.a_lb, plain.a_ub)
    j_plain = optimum.replay(env, a_plain, 0, _options())[0] if status in optimum.SOLVED else np.nan
    return {
        "problem": problem,
        "eigenaxis": eig,
        "cbf": cbf,
        "constrained": constrained,
        "free": free,
        "plain": j_plain,
    }


def test_registered():
    assert ENV in BUILDERS and ENV in FLIGHT_BUILDERS


def test_start_node_matches_the_env_constraints(env):
    problem = problem_for(env, seed=0, options=_options())
    base = env.unwrapped
    _, info = env.reset(seed=0, options=_options())
    exact = np.asarray(cs.path_constraint(base, problem.n_x)(problem.x0)).ravel()
    names = cs.constraint_names(base)
    assert names == list(info["constraints"])
    for name, value in zip(names, exact, strict=True):
        assert value == pytest.approx(info["constraints"][name], abs=1e-9)
    # the problem's own rows at x_0: the cone row and the max of the rate and wheel rows
    rows = np.asarray(problem.g(problem.x0)).ravel()
    n_w = base.model.params.wheel_axes.shape[1]
    assert cs.backoff(base) == cs.BACKOFF  # the lab
    appended = rows[-(len(base.cones) + 6 + 2 * n_w) :] - cs.BACKOFF
    cone = appended[0]
    rate = appended[1:7].max() * base.body_rate_limit.limit_rad_s
    wheel = appended[7:].max() * base.wheel_speed_limit.limit_rad_s
    assert cone == pytest.approx(info["constraints"]["keep_out_sun_star_tracker"], abs=1e-9)
    assert rate == pytest.approx(info["constraints"]["body_rate"], abs=1e-9)
    assert wheel == pytest.approx(info["constraints"]["wheel_speed"], abs=1e-9)
    assert info["constraints"]["keep_out_sun_star_tracker"] < 0.0  # the start is outside the cone


def test_the_episode_needs_the_cone(solved):
    # the eigenaxis slew enters the cone, the CBF-filtered one (the warm start) does not
    assert solved["eigenaxis"]["violations_by_constraint"]["keep_out_sun_star_tracker"] > 0
    assert solved["cbf"]["violations"] == 0


def test_j_star_is_feasible_and_costs_at_least_the_cone_free_optimum(env, solved):
    r, free = solved["constrained"], solved["free"]
    assert r.solved and free.solved
    info, margin = _replay(env, r.actions, _options())
    assert info["violations"] == 0
    assert margin > -1e-9  # on or outside the cone at every decision time
    assert r.j_star == pytest.approx(r.j_nlp, rel=1e-6)
    assert r.j_star < r.j_warm
    assert r.j_star >= free.j_star
    # the cone-free optimum enters the cone: the cone is active
    free_info, free_margin = _replay(env, free.actions, _options())
    assert free_info["violations_by_constraint"]["keep_out_sun_star_tracker"] > 0 and free_margin < 0.0
    # and at least the optimum of the plain ReactionWheel-v0 problem (no limits at all)
    assert free.j_star >= solved["plain"] * (1.0 - 1e-9)


def test_flight_conditions_carry_the_gyrostat_chain_and_stay_feasible():
    """Through the flight actuator chain (delay, quantized commands, Coulomb friction signs
    fixed after a relaxed first solve) with the larger back-off: the replay has no violation."""
    kwargs = {**KWARGS, "conditions": {"parameters": 1, "actuators": True, "delay_steps": 1}}
    env = gym.make(f"attitude_envs/{ENV}", **kwargs)
    try:
        problem = problem_for(env, seed=0, options=_options())
        assert problem.n_x > 11 and cs.backoff(env.unwrapped) == cs.FLIGHT_BACKOFF
        warm, _ = _rollout(env, CBFSafetyFilterPolicy(env), problem.n_steps)
        r = optimum.solve_episode(ENV, kwargs, 0, options=_options(), warm_start=warm, cache=False)
        assert r.solved and r.j_star < r.j_warm
        info, _ = _replay(env, r.actions, _options())
        assert info["violations"] == 0
    finally:
        env.close()
