"""Adding a plant takes three files: the plant (example_plant.py), its env (example_env.py)
and its registration (here). Everything shared — presets, faults, sensors, fault_hint, the
truth/measured info contract, the evaluator — works for it without touching the suite."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from example_env import SingleAxisEnv
from gymnasium.utils.env_checker import check_env

from attitude_envs import presets
from attitude_envs.evaluation import rollout
from attitude_envs.info import policy_view

ENV_ID = "attitude_envs_examples/SingleAxis-v0"
if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point=SingleAxisEnv)


class PD:
    """A PD law on the measured state: the policy interface of the suite."""

    name = "pd"

    def reset(self, seed=None):
        pass

    def act(self, obs, info):
        assert "truth" not in info  # the evaluator hides the truth from policies
        m = info["measured"]
        return np.array([np.clip(2.0 * (m["angle_rad"] - 0.5) + 4.0 * m["rate_rad_s"], -1, 1)], dtype=np.float32)


def test_check_env_and_preset():
    env = gym.make(ENV_ID)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.target_rad == 0.5
    assert presets.get("SingleAxis-v0").source("inertia_kg_m2").startswith("assumed")
    env2 = gym.make(ENV_ID, target_rad=0.2)  # an explicit keyword overrides one preset value
    assert env2.unwrapped.target_rad == 0.2 and env2.unwrapped.model.inertia_kg_m2 == 10.0


def test_evaluator_and_momentum_conservation():
    env = gym.make(ENV_ID)
    result = rollout(env, PD(), seed=0)
    assert result["steps"] == 200 and np.isfinite(result["J"])
    _, info = env.reset(seed=1)
    m = env.unwrapped.model
    h0 = m.inertia_kg_m2 * info["truth"]["state"]["rate_rad_s"]
    for _ in range(20):
        _, _, _, _, info = env.step(np.array([0.7], dtype=np.float32))
    wheel = env.unwrapped._y[2]  # noqa: SLF001 (test reads the plant state directly)
    h = m.inertia_kg_m2 * info["truth"]["state"]["rate_rad_s"] + m.wheel_inertia_kg_m2 * wheel
    assert h == pytest.approx(h0, abs=1e-12)


def test_faults_sensors_and_hint_come_from_the_base():
    outage = [{"kind": "outage", "index": 0, "onset_s": 0.0}]
    env = gym.make(ENV_ID, faults=outage, fault_hint=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (2 + 1 + 2,) and obs[2] == 1.0
    _, _, _, _, info = env.step(np.array([1.0], dtype=np.float32))
    assert info["truth"]["applied"][0] == 0.0 and info["commanded"][0] == pytest.approx(0.1)
    assert info["truth"]["faults"][0]["active"]

    clean = gym.make(ENV_ID)
    _, info = clean.reset(seed=0)
    assert info["measured"] == info["truth"]["state"]  # sensors off: measured is the truth
    noisy = gym.make(ENV_ID, sensors={"gyro": {"noise_std": 1e-3}})
    _, info = noisy.reset(seed=0)
    assert info["measured"]["rate_rad_s"] != info["truth"]["state"]["rate_rad_s"]
    assert "sensor_bias" in info["truth"] and "truth" not in policy_view(info)


def test_unknown_keyword_and_preset_get_clear_errors():
    with pytest.raises(ValueError, match="did you mean 'demo'"):
        SingleAxisEnv(preset="dem")


def test_the_example_plant_declares_how_campaigns_judge_it():
    from example_env import SingleAxisEnv

    env = SingleAxisEnv()
    _, first = env.reset(seed=0)
    metric = env.success_metric
    assert metric.name == "final_state_fraction"
    assert metric.value(first, first) == 1.0  # the start judged against itself


def test_the_plant_defined_once_runs_on_every_executor():
    """The example's equations (example_plant.define) compile under numba bit for bit with
    numpy, and CasADi's Jacobian of the same source is the model's linearization."""
    from example_plant import define

    from attitude_envs.plants.ops import NUMBA, NUMPY

    m = gym.make(ENV_ID).unwrapped.model
    args = (m.inertia_kg_m2, m.wheel_inertia_kg_m2, 0.5, m.cost.Q, m.cost.R)
    rng = np.random.default_rng(0)
    for _ in range(50):
        y, u = rng.normal(size=4), float(rng.normal())
        compiled = define(NUMBA).derivative(y, u, *args)
        plain = define(NUMPY).derivative(y, u, *args)
        assert np.array_equal(np.array(compiled), np.array(plain, dtype=float))
    casadi = pytest.importorskip("casadi")
    from attitude_envs.symbolic.ops import CASADI

    y, u = casadi.SX.sym("y", 4), casadi.SX.sym("u")
    dy = casadi.vertcat(*define(CASADI).derivative(y, u, *args[:3], casadi.DM(m.cost.Q), casadi.DM(m.cost.R)))
    # the error state is [θ − θ_T, ω]: its Jacobian is the state's in those two entries
    jac = casadi.Function("linearization", [y, u], [casadi.jacobian(dy[:2], y[:2]), casadi.jacobian(dy[:2], u)])
    a, b = (np.asarray(v) for v in jac(np.array([0.7, -0.2, 3.0, 0.0]), 0.3))
    a_model, b_model = m.linearize()
    np.testing.assert_array_equal(a, a_model)
    np.testing.assert_array_equal(b, b_model)
