"""The magnetorquer MPC (baselines/mpc_magnetorquer.py) and the nominal symbolic step it predicts with."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("casadi")

import attitude_envs  # noqa: E402,F401  (registers the envs)
from attitude_envs.symbolic import magnetorquer as sym  # noqa: E402
from baselines.mpc_magnetorquer import MagnetorquerMPCPolicy  # noqa: E402

ENV_ID = "attitude_envs/Magnetorquer-v0"
CAMPAIGN = {"preset": "sadigh-2022", "episode_duration_s": 300.0, "integrator_dt_s": 0.5}


def _nominal_env(control_dt_s: float):
    """The plant the MPC's model describes: nominal inertia, no ΔJ(t), no disturbance, healthy."""
    return gym.make(
        ENV_ID, **CAMPAIGN, control_dt_s=control_dt_s, disturbance=None, time_varying_inertia=None
    ).unwrapped


@pytest.mark.parametrize("control_dt_s", [1.0, 2.0])
def test_nominal_model_matches_env_step(control_dt_s: float) -> None:
    env = _nominal_env(control_dt_s)
    policy_model = sym.nominal_step_function(env)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    worst_state, worst_cost = 0.0, 0.0
    for _ in range(15):
        a = rng.uniform(-1.2, 1.2, 4).astype(np.float32)  # beyond ±1: the step clips like the env
        y = np.array(env.state_row)
        p = sym.nominal_step_parameters(env, [env._t])[0]
        y_next, cost = policy_model(y, a.astype(float), p)
        _, reward, terminated, _, _ = env.step(a)
        assert not terminated
        worst_state = max(worst_state, float(np.max(np.abs(np.asarray(y_next).ravel() - env.state_row))))
        worst_cost = max(worst_cost, abs(float(cost) + reward))
    assert worst_state <= 1e-9
    assert worst_cost <= 1e-9


def test_nominal_parameters_hold_nominal_inertia_and_no_disturbance() -> None:
    env = gym.make(ENV_ID, **CAMPAIGN, control_dt_s=1.0).unwrapped  # the paper's ΔJ(t) and eq. 39 disturbance on
    env.reset(seed=1)
    p = sym.nominal_step_parameters(env, [10.0, 11.0], 1.0, 1.0)
    assert p.shape == (2, 1 + 3 * sym.N_FIELDS)
    np.testing.assert_array_equal(p[:, 0], [10.0, 11.0])
    assert np.all(p[:, sym.disturbance_columns(1)] == 0.0)
    inertia = p[0, 1 + sym._I : 1 + sym._I + 9].reshape(3, 3)
    np.testing.assert_array_equal(inertia, env.model.params.inertia_kg_m2)
    # the existing J* step still reads the episode's truth (ΔJ(t), disturbance)
    truth = sym.step_parameters(env, 1)
    assert np.any(truth[0, sym.disturbance_columns(env._substeps)] != 0.0)


def test_nominal_substeps_rejects_a_period_that_is_not_a_multiple() -> None:
    env = _nominal_env(1.0)
    with pytest.raises(ValueError, match="integrator_dt_s"):
        sym.nominal_substeps(env, 1.0, 0.3)
    with pytest.raises(ValueError, match="integrator_dt_s"):
        sym.nominal_substeps(env, 1.0, 2.0)


def test_policy_rejects_bad_parameters() -> None:
    env = gym.make(ENV_ID, **CAMPAIGN, control_dt_s=2.0)
    with pytest.raises(ValueError, match="disturbance_gain"):
        MagnetorquerMPCPolicy(env, disturbance_gain=0.0)
    with pytest.raises(ValueError, match="horizon_s"):
        MagnetorquerMPCPolicy(env, horizon_s=1.0)


def test_short_episode_solves_and_estimates_the_disturbance() -> None:
    env = gym.make(ENV_ID, **{**CAMPAIGN, "episode_duration_s": 20.0}, control_dt_s=2.0)
    policy = MagnetorquerMPCPolicy(env, horizon_s=10.0, model_integrator_dt_s=1.0)
    obs, info = env.reset(seed=0)
    policy.reset(0)
    done, total = False, 0.0
    truth = []
    while not done:
        action = policy.act(obs, {"measured": info["measured"], "time_s": info["time_s"]})
        assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
        obs, _, terminated, truncated, info = env.step(action)
        total += info["cost"]
        truth.append(np.asarray(info["truth"]["disturbance_torque_nm"], dtype=float))
        done = terminated or truncated
    assert not terminated
    assert len(policy.solve_times_s) == 10
    assert policy.failures == 0
    assert np.isfinite(total) and total > 0.0
    # the observer's estimate (lumping ΔJ(t)) is of the eq. 39 disturbance's size and sign
    estimate = policy.disturbance_nm
    assert np.all(np.sign(estimate) == np.sign(truth[-1]))


def test_episode_cost_is_the_same_quantity_at_any_control_period() -> None:
    """J = ∫ (xᵀQx + uᵀRu) dt over the episode does not depend on the decision period: the zero
    policy's J at 1 s and 5 s periods (same 0.5 s RK4 sub-steps) agree, so an MPC deciding every
    few seconds is scored against the cell's J* (solved at 1 s)."""
    totals = []
    for control_dt_s in (1.0, 5.0):
        env = gym.make(ENV_ID, **{**CAMPAIGN, "episode_duration_s": 100.0}, control_dt_s=control_dt_s)
        env.reset(seed=2)
        done, total = False, 0.0
        while not done:
            _, _, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
            total += info["cost"]
            done = terminated or truncated
        totals.append(total)
    assert totals[0] > 0.0
    assert totals[1] == pytest.approx(totals[0], rel=1e-12)
