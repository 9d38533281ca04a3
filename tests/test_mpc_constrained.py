"""ConstrainedSlew-v0's constrained MPC (:mod:`baselines.mpc_constrained`), the registry names
of the env's baselines, and the resume of ``benchmarks/constrained_slew_optimum.py``."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("casadi")
pytest.importorskip("clarabel")

import gymnasium as gym  # noqa: E402

import attitude_envs  # noqa: E402, F401
from attitude_envs.info import policy_view  # noqa: E402
from attitude_envs.symbolic import constrained_slew as cs  # noqa: E402
from baselines.cbf import CBFSafetyFilterPolicy, EigenaxisSlewPolicy  # noqa: E402
from baselines.mpc_constrained import ConstrainedSlewMPCPolicy  # noqa: E402
from benchmarks import constrained_slew_optimum as bench  # noqa: E402
from experiments.policies import build_policy, check_policy_env, policies_for  # noqa: E402

ENV = "attitude_envs/ConstrainedSlew-v0"
#: seed 18's eigenaxis slew enters the Moon cone within its first 12 s (10 steps, measured)
SEED = 18
SHORT = {"episode_duration_s": 12.0}


@pytest.fixture(scope="module")
def env():
    e = gym.make(ENV, **SHORT)
    yield e
    e.close()


@pytest.fixture(scope="module")
def mpc(env):
    return build_policy({"policy": "mpc-constrained"}, env)


def test_the_registry_names_resolve(env, mpc):
    assert {"eigenaxis", "eigenaxis+cbf", "mpc-constrained"} <= set(policies_for(ENV))
    assert type(build_policy({"policy": "eigenaxis"}, env)) is EigenaxisSlewPolicy
    cbf = build_policy({"policy": "eigenaxis+cbf", "params": {"buffer_deg": 3.0}}, env)
    assert isinstance(cbf, CBFSafetyFilterPolicy) and cbf.name == "eigenaxis+cbf"
    assert isinstance(mpc, ConstrainedSlewMPCPolicy) and mpc.name == "mpc-constrained"
    with pytest.raises(ValueError, match="does not apply to attitude_envs/ReactionWheel-v0"):
        check_policy_env("mpc-constrained", "attitude_envs/ReactionWheel-v0")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"backoff": -1e-6}, r"backoff must be in \[0, inf\)"),
        ({"constr_viol_tol": 0.0}, r"constr_viol_tol must be in \(0, inf\)"),
        ({"replan_steps": 0}, "replan_steps must be an integer >= 1"),
    ],
)
def test_bad_settings_are_refused_by_name(env, kwargs, message):
    with pytest.raises(ValueError, match=message):
        ConstrainedSlewMPCPolicy(env, **kwargs)


def test_the_cone_parameters_and_rows_are_the_episodes(env, mpc):
    """The observation's cones, turned inertial by the measured attitude, are the env's; the
    MPC's rows with them are J*'s rows (the same back-off)."""
    obs, info = env.reset(seed=SEED)
    base = env.unwrapped
    p = mpc.cone_parameters(obs, policy_view(info))
    for i, cone in enumerate(base.cones):
        np.testing.assert_allclose(p[4 * i : 4 * i + 3], cone.inertial_direction, atol=1e-6)
        assert p[4 * i + 3] == pytest.approx(cone.cos_half_angle, abs=1e-7)
    for i in range(len(base.cones), 3):
        np.testing.assert_array_equal(p[4 * i : 4 * i + 4], [0.0, 0.0, 0.0, 1.0])
    assert mpc.backoff == cs.backoff(base) == cs.BACKOFF
    x = np.r_[base.state_row[:4], 0.01, -0.02, 0.03, 100.0, -200.0, 300.0, -400.0]
    exact = np.asarray(cs.path_constraint(base)(x)).ravel()
    for i, cone in enumerate(base.cones):
        row = cs.cone_row(x, cone.body_axis, p[4 * i : 4 * i + 3], p[4 * i + 3], mpc.backoff)
        assert float(row) == pytest.approx(exact[i] + cs.BACKOFF, abs=1e-6)
    limits = cs.limit_rows(x, mpc.rate_limit_rad_s, mpc.wheel_speed_limit_rad_s, 4, 0.0)
    assert max(limits[:6]) * mpc.rate_limit_rad_s == pytest.approx(exact[-1], abs=1e-12)
    assert max(limits[6:]) * mpc.wheel_speed_limit_rad_s == pytest.approx(exact[-2], abs=1e-9)


def test_the_mpc_keeps_the_constraints_where_the_eigenaxis_slew_violates(env, mpc):
    eigenaxis = bench.rollout(env, build_policy({"policy": "eigenaxis"}, env), SEED)
    assert eigenaxis["violations_by_constraint"]["keep_out_moon_star_tracker"] > 0
    assert eigenaxis["min_cone_margin_deg"] < 0.0
    r = bench.rollout(env, mpc, SEED)
    assert r["violations"] == 0 and not r["terminated"]
    assert r["min_cone_margin_deg"] >= 0.0
    assert mpc.failures == 0 and mpc.held_steps == 0
    assert len(mpc.solve_times_s) == len(r["actions"])  # a solve every step (replan_steps=1)


def test_replan_steps_plays_the_plan_between_solves(env):
    policy = ConstrainedSlewMPCPolicy(env, horizon_steps=8, replan_steps=3)
    obs, info = env.reset(seed=SEED)
    policy.reset(SEED)
    for _ in range(7):
        obs, *_, info = env.step(policy.act(obs, policy_view(info)))
    assert len(policy.solve_times_s) == 3  # steps 0, 3 and 6
    with pytest.raises(ValueError, match="replan_steps"):
        ConstrainedSlewMPCPolicy(env, horizon_steps=2, replan_steps=0)


def _fake_optimum(seed: int) -> dict:
    return {
        "seed": seed,
        "solved": True,
        "J_star": 10.0 + seed,
        "violations": 0,
        "solve_s": 1.0,
        "total_s": 2.0,
        "unconstrained": {"solved": True, "J_star_unc": 9.0 + seed},
    }


def _fake_baseline(name: str, seed: int) -> dict:
    return {"seed": seed, "J": 2.0 * (10.0 + seed), "violations": seed % 2, "min_cone_margin_deg": -1.0, "wall_s": 0.1}


def test_the_script_resumes_skipping_the_seeds_it_holds(tmp_path):
    out = tmp_path / "optimum.json"
    calls: list = []

    def solve(seed):
        calls.append(seed)
        return _fake_optimum(seed)

    def evaluate(name, seed):
        calls.append((name, seed))
        return _fake_baseline(name, seed)

    quiet = {"argv": [], "solve": solve, "evaluate": evaluate, "log": lambda _: None}
    bench.run("optimum", [0, 1], out, **quiet)
    bench.run("optimum", [0, 1, 2], out, **quiet)
    assert calls == [0, 1, 2]
    calls.clear()
    bench.run("baselines", [0, 1], out, policies=["eigenaxis"], **quiet)
    bench.run("baselines", [0, 1, 2], out, policies=["eigenaxis", "mpc-constrained"], **quiet)
    assert calls == [("eigenaxis", 0), ("eigenaxis", 1), ("eigenaxis", 2)] + [("mpc-constrained", s) for s in range(3)]
    data = json.loads(out.read_text())
    assert sorted(data["optimum"]) == ["0", "1", "2"]
    s = data["summary"]
    assert s["optimum"]["solved"] == 3 and s["optimum"]["sum_J_star"] == 33.0
    assert s["eigenaxis"]["sum_J_over_sum_J_star"] == pytest.approx(2.0)
    assert s["eigenaxis"]["violating_episodes"] == 1 and s["eigenaxis"]["violation_steps"] == 1
    assert bench.build_parser().parse_args(["--part", "optimum", "--seeds", "0-3,7"]).seeds == [0, 1, 2, 3, 7]
    assert bench.build_parser().parse_args(["--part", "optimum"]).seeds == list(range(20))
    with pytest.raises(SystemExit):
        bench.build_parser().parse_args(["--part", "optimum", "--seeds", ""])
