"""J* under flight conditions on LinearSystem-v0, FuelSlosh-v0 and Magnetorquer-v0: the oracle
knows the episode's draws (B's gain error; the slosh masses and lengths; the inertia) and
acts through the env's own actuator chain, and J* is still the env's replay of its commands.

* the symbolic step is the env's step under the conditions (sensors off: the oracle acts on
  the true state) to 1e-10;
* under the one-period delay the first period delivers zero whatever the command;
* J* is >= 0 and no worse than the plant's analytic baseline on the same seed where that
  baseline survives (FuelSlosh's paper LQR and PD do not under the flight gimbal rate
  limit: they cross the slosh or pitch limits within a few seconds; the zero policy does
  survive, and J* beats it).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

from attitude_envs import symbolic  # noqa: E402
from attitude_envs.symbolic import problem_for  # noqa: E402
from experiments import optimum  # noqa: E402

#: flight conditions with the sensors off (they do not change the plant; noise off)
FLIGHT = {"base": "flight", "sensors": 0}
#: a fast double integrator (the default preset is a 1000 kg·m² satellite: 30 steps barely move it)
LINEAR = {
    "preset": None,
    "A": [[1.0, 0.1], [0.0, 1.0]],
    "B": [[0.005], [0.1]],
    "x0_mean": [1.0, 0.0],
    "x0_std": 0.2,
    "episode_steps": 30,
}
SLOSH = {"episode_duration_s": 3.0}
MAGNETORQUER = {"episode_duration_s": 3.0}


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))


def _env(env_id, kwargs, conditions):
    return gym.make(f"attitude_envs/{env_id}", **kwargs, conditions=conditions)


def _assert_steps_as_the_env(env, problem, actions, seed, n_plant):
    states, costs = problem.rollout(actions)
    env.reset(seed=seed)
    base = env.unwrapped
    for k, a in enumerate(actions):
        _, _, terminated, _, info = env.step(a)
        assert not terminated
        true = np.asarray(base.state_row if hasattr(base, "state_row") else base.state, dtype=float)
        np.testing.assert_allclose(true, states[k + 1, :n_plant], rtol=0, atol=1e-10)
        assert info["cost"] == pytest.approx(costs[k], rel=1e-10, abs=1e-14)


def _assert_first_delivered_is_zero(env_id, kwargs, seed, n_plant):
    env = _env(env_id, kwargs, FLIGHT)
    problem = problem_for(env, seed=seed)
    p0 = problem.step_inputs(0, 1)[:, 0]
    x_a, c_a = problem.step(problem.x0, np.ones(problem.n_u), p0)
    x_b, c_b = problem.step(problem.x0, -np.ones(problem.n_u), p0)
    np.testing.assert_array_equal(np.asarray(x_a)[:n_plant], np.asarray(x_b)[:n_plant])
    assert float(c_a) == float(c_b)
    env.reset(seed=seed)
    _, _, _, _, info = env.step(np.ones(problem.n_u))
    np.testing.assert_array_equal(info["truth"]["applied"], 0.0)  # the env agrees: nothing delivered


def test_the_three_plants_have_flight_builders():
    assert {"LinearSystem-v0", "FuelSlosh-v0", "Magnetorquer-v0"} <= symbolic.FLIGHT_BUILDERS


# ----------------------------------------------------------------------------- LinearSystem
def test_linear_flight_step_is_the_envs():
    env = _env("LinearSystem-v0", LINEAR, FLIGHT)
    problem = problem_for(env, seed=4)
    gain = env.unwrapped.drawn_parameters()["actuator_gain"]
    assert gain != pytest.approx(1.0)
    assert problem.n_x == 2 + 1  # the plant, then the one-period delay line
    actions = np.random.default_rng(0).uniform(-1.3, 1.3, (problem.n_steps, 1))  # the env clips past ±1
    _assert_steps_as_the_env(env, problem, actions, 4, 2)
    _assert_first_delivered_is_zero("LinearSystem-v0", LINEAR, 4, 2)


@pytest.mark.parametrize("seed", [0, 1])
def test_linear_flight_optimum(seed):
    r = optimum.solve_episode("LinearSystem-v0", {**LINEAR, "conditions": "flight"}, seed, cache=False)
    assert r.solved and not r.terminated
    assert "delay of 1 period(s) exact" in r.notes
    assert r.j_star == pytest.approx(r.j_nlp, rel=1e-9)  # an exact model: the NLP is the env
    env = _env("LinearSystem-v0", LINEAR, "flight")
    _, j_lqr = optimum.baseline_rollout(env, optimum.BASELINES["LinearSystem-v0"][0], seed, None, len(r.actions))
    assert 0.0 <= r.j_star <= j_lqr
    lab = optimum.solve_episode("LinearSystem-v0", LINEAR, seed, cache=False)
    assert lab.j_star != r.j_star  # the flight oracle's own problem


# ----------------------------------------------------------------------------- FuelSlosh
def test_slosh_flight_step_is_the_envs():
    env = _env("FuelSlosh-v0", SLOSH, FLIGHT)
    problem = problem_for(env, seed=2)
    drawn = env.unwrapped.drawn_parameters()
    assert {"slosh_mass_kg", "length_m", "actuator_gain"} <= set(drawn)
    assert "rate limit exact" in problem.notes and "path constraint" in problem.notes
    # within the gimbal's rate (the problem holds the command there by a path constraint)
    rate = env.unwrapped._actuator_chain.model.rate_limit[0] * env.unwrapped.control_dt_s
    swing = 0.9 * rate / env.unwrapped.actuator_limits[0] / 0.3  # largest change per step: 0.9 of the rate
    k = np.arange(problem.n_steps)
    actions = np.column_stack([swing * np.sin(0.3 * k), 0.2 * np.cos(0.7 * k)])
    _assert_steps_as_the_env(env, problem, actions, 2, 10)
    states, _ = problem.rollout(actions)
    assert np.all(np.asarray(problem.g.map(problem.n_steps)(states[1:].T)) <= 1e-12)
    _assert_first_delivered_is_zero("FuelSlosh-v0", SLOSH, 2, 10)


def test_slosh_step_keeps_the_rate_clip_without_a_delay():
    conditions = {"actuators": True, "parameters": 1}
    env = _env("FuelSlosh-v0", SLOSH, conditions)
    problem = problem_for(env, seed=3)
    assert "the env's clip" in problem.notes
    actions = np.random.default_rng(2).uniform(-0.3, 0.3, (problem.n_steps, 2))  # often past the rate
    _assert_steps_as_the_env(env, problem, actions, 3, 10)


def test_slosh_flight_optimum_beats_the_zero_policy_where_the_paper_lqr_fails():
    kwargs = {**SLOSH, "conditions": "flight"}
    r = optimum.solve_episode("FuelSlosh-v0", kwargs, 0, warm_start=None, cache=False)
    assert r.solved and not r.terminated
    assert r.j_star == pytest.approx(r.j_nlp, rel=1e-9)  # exact: no relaxation in this chain
    assert 0.0 <= r.j_star <= r.j_warm  # the zero policy's J on this episode
    env = _env("FuelSlosh-v0", SLOSH, "flight")
    for spec in optimum.BASELINES["FuelSlosh-v0"]:
        actions, j = optimum.baseline_rollout(env, spec, 0, None, len(r.actions))
        if not optimum.replay(env, actions, 0, None)[1]:  # where the baseline survives
            assert r.j_star <= j


# ----------------------------------------------------------------------------- Magnetorquer
def test_magnetorquer_flight_step_is_the_envs():
    env = _env("Magnetorquer-v0", MAGNETORQUER, FLIGHT)
    base = env.unwrapped
    problem = problem_for(env, seed=1)
    drawn = base.drawn_parameters()
    assert {"inertia_kg_m2", "actuator_gain"} <= set(drawn)
    model = base._actuator_chain.model
    np.testing.assert_array_equal(model.duty, [0.8, 0.8, 0.8, 1.0])
    # commands on the env's resolution grid (the oracle's is continuous), the Coulomb signs the env's
    quantum = model.resolution / model.limits
    actions = np.random.default_rng(0).uniform(-1, 1, (problem.n_steps, 4))
    actions = np.round(actions / quantum) * quantum
    env.reset(seed=1)
    rows = [base.state_row.copy()]
    for a in actions[:-1]:
        env.step(a)
        rows.append(base.state_row.copy())
    signs = np.sign(symbolic.friction_speeds(env, np.array(rows)))
    np.testing.assert_array_equal(signs[:, :3], 0.0)
    env.reset(seed=1)
    fixed = symbolic.with_friction_signs(env, signs)
    assert "Coulomb sign(Omega) fixed per step" in fixed.notes
    _assert_steps_as_the_env(env, fixed, actions, 1, 8)
    _assert_first_delivered_is_zero("Magnetorquer-v0", MAGNETORQUER, 1, 8)


def test_magnetorquer_friction_sign_margin_levels():
    env = _env("Magnetorquer-v0", MAGNETORQUER, FLIGHT)
    n = problem_for(env, seed=0).n_steps
    signs = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    everywhere = symbolic.with_friction_signs(env, signs)
    nowhere = symbolic.with_friction_signs(env, signs, False)
    where = np.zeros((n, 4), dtype=bool)
    where[5:, 3] = True
    some = symbolic.with_friction_signs(env, signs, where)
    x = everywhere.x0
    p = everywhere.params[0]
    assert everywhere.g(x, p).shape[0] == nowhere.g(x, p).shape[0] + 4
    assert some.params.shape[1] == everywhere.params.shape[1] + 4
    # the wheel at rest violates the margin where it is held, not where it is not
    assert float(everywhere.g(x, p)[-1]) > 0
    assert float(some.g(x, some.params[0])[-1]) == 0.0 and float(some.g(x, some.params[5])[-1]) > 0
    # the step is the same function of (x, a) in all three
    a = np.full(4, 0.3)
    np.testing.assert_array_equal(some.step(x, a, some.params[3])[0], everywhere.step(x, a, everywhere.params[3])[0])


def test_magnetorquer_flight_optimum():
    kwargs = {**MAGNETORQUER, "conditions": "flight"}
    r = optimum.solve_episode("Magnetorquer-v0", kwargs, 0, cache=False)
    assert r.solved and not r.terminated
    assert "resolution relaxed" in r.notes
    env = _env("Magnetorquer-v0", MAGNETORQUER, "flight")
    assert optimum.replay(env, r.actions, 0, None)[0] == r.j_star  # J* is the env's replay
    # the relaxed resolution (the wheel's quantum is 1.5 % of its limit) leaves a small gap
    assert r.j_star == pytest.approx(r.j_nlp, rel=0.05)
    _, j_base = optimum.baseline_rollout(env, optimum.BASELINES["Magnetorquer-v0"][0], 0, None, len(r.actions))
    assert 0.0 <= r.j_star <= j_base
