"""Training under flight conditions: ``env_kwargs={"conditions": "flight"}`` trains on single
flight envs (the batched env runs the lab only), each sub-env drawing its own plant per
episode; the run saves and its model plays a flight episode. Lab kwargs keep the batched env."""

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import attitude_envs  # noqa: F401,E402
from attitude_envs.evaluation.rollout import rollout  # noqa: E402
from experiments.training import training  # noqa: E402
from experiments.training.policy import SB3Policy  # noqa: E402
from experiments.training.vec_envs import batched_supported  # noqa: E402

AB1 = "attitude_envs/AirBearing-v1"


@pytest.mark.parametrize(
    "conditions, batched",
    [(None, True), ("lab", True), ("flight", False), ({"actuators": True}, False), ({"delay_steps": 1}, False)],
)
def test_only_lab_conditions_take_the_batched_env(conditions, batched):
    env = gym.make(AB1) if conditions is None else gym.make(AB1, conditions=conditions)
    assert batched_supported(AB1, env) is batched


def test_ppo_trains_and_saves_under_flight_conditions(tmp_path, monkeypatch):
    built = []
    make = training.make_training_env

    def spy(*args, **kwargs):
        built.append(make(*args, **kwargs))
        return built[-1]

    monkeypatch.setattr(training, "make_training_env", spy)
    out = tmp_path / "run"
    result = training.train(
        "ppo",
        AB1,
        out,
        env_kwargs={"conditions": "flight"},
        seed=1000,
        backend="sb3",  # the recipe's shapes on PyTorch: no JAX compilation in a short test
        overrides={"n_epochs": 1},
        total_timesteps=320,  # one rollout: 8 envs × 40 steps
        eval_freq=320,
        checkpoint_freq=320,
        eval_episodes=1,
        evaluate_initial=False,
    )
    assert result.timesteps == 320 and result.model_path.is_file()
    assert json.loads((out / "config.json").read_text())["env_kwargs"] == {"conditions": "flight"}

    # the training env really was the flight env: single envs, each with its own drawn plant
    (venv,) = built
    envs = [e.unwrapped for e in venv.envs]
    assert len(envs) == 8
    assert all(e.conditions.name == "flight" for e in envs)
    inertias = [e.drawn_parameters()["inertia_kg_m2"] for e in envs]
    assert len({np.asarray(i).tobytes() for i in inertias}) == 8  # drawn per sub-env

    # the saved model plays a flight episode
    env = gym.make(AB1, conditions="flight")
    ep = rollout(env, SB3Policy(training.load_trained(result.model_path, env)), seed=0)
    assert ep["steps"] == 40 and np.isfinite(ep["J"])
