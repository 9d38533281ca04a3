"""A trained model acting on an estimator's output (``params: {estimator: mekf}``): the same
actions as the bare model fed the estimator's rebuilt observation, memory through a sensor
outage, clear errors where no estimator applies, and a campaign row that plays another
agent's models on the flight cells only (``models_of`` on some of its envs)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from test_estimators_flight import _angle  # the angle between two attitudes, rad

import attitude_envs  # noqa: F401
from attitude_envs.estimation.estimators import GyrostatMEKF
from baselines.estimated import Estimated
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.spec import load_campaign
from experiments.policies import build_policy

AB1 = "attitude_envs/AirBearing-v1"
OUTAGE = [
    {"kind": "dropout", "target": "sensor", "sensor": "star_tracker", "index": "all", "mode": "hold", "onset_s": 2.0}
]


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    """An untrained PPO of AirBearing-v1's spaces (its weights are random; the wiring is tested)."""
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make(AB1)
    path = tmp_path_factory.mktemp("ppo") / "model.zip"
    sb3.PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=0, device="cpu").save(path)
    env.close()
    return str(path)


def test_the_model_acts_on_the_estimate_and_holds_through_an_outage(model_path):
    env = gym.make(AB1, conditions="flight", faults=OUTAGE)
    policy = build_policy({"policy": "sb3", "model": model_path, "params": {"estimator": "mekf"}}, env, name="ppo+mekf")
    assert isinstance(policy, Estimated) and policy.name == "ppo+mekf"
    bare = build_policy({"policy": "sb3", "model": model_path}, env)
    twin = GyrostatMEKF(env)  # an independent estimator fed the same readings
    obs, info = env.reset(seed=3)
    policy.reset(3)
    obs_e, _ = twin.reset(obs, info)
    held, estimated = [], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = policy.act(obs, info)
        np.testing.assert_array_equal(action, bare.act(obs_e, info))
        obs, _, terminated, truncated, info = env.step(action)
        obs_e, view = twin.update(obs, info)
        truth = info["truth"]["state"]["attitude"]
        if info["time_s"] > 4.0:  # two seconds into the outage: the reading is held, the estimate coasts on the gyro
            held.append(_angle(truth, info["sensors"]["star_tracker"]))
            estimated.append(_angle(truth, view["estimate"]["attitude"]))
    assert len(held) > 10
    assert np.median(estimated) < 0.2 * np.median(held), (np.median(estimated), np.median(held))


def test_an_estimator_needs_sensors_and_a_name_that_fits(model_path):
    lab = gym.make(AB1)
    with pytest.raises(ValueError, match="needs sensors on"):
        build_policy({"policy": "sb3", "model": model_path, "params": {"estimator": "mekf"}}, lab)
    flight = gym.make(AB1, conditions="flight")
    with pytest.raises(ValueError, match="estimator 'kf' does not apply to AirBearing"):
        build_policy({"policy": "sb3", "model": model_path, "params": {"estimator": "kf"}}, flight)
    with pytest.raises(ValueError, match="estimator_params needs params.estimator"):
        build_policy({"policy": "sb3", "model": model_path, "params": {"estimator_params": {"x": 1}}}, flight)


def _campaign(behind_envs: list[str] | None) -> dict:
    behind = {"name": "ppo+mekf", "policy": "sb3", "env_id": AB1, "models_of": "ppo", "params": {"estimator": "mekf"}}
    if behind_envs is not None:
        behind["envs"] = behind_envs
    return {
        "name": "behind-estimator",
        "seeds": 2,
        "envs": [
            {"name": "lab", "id": "attitude_envs/AirBearing-v0", "faults": {"none": []}},
            {"name": "flight", "id": "attitude_envs/AirBearing-v0", "kwargs": {"conditions": "flight"}},
        ],
        "agents": [
            {"name": "ppo", "policy": "sb3", "env_id": AB1, "train": {"algo": "ppo", "seeds": [0], "env": "lab"}},
            behind,
        ],
    }


def test_a_row_behind_the_estimator_plays_the_lab_models_on_the_flight_cells_only(tmp_path):
    campaign = load_campaign(_campaign(["flight"]))
    played = [j for j in episode_jobs(campaign, tmp_path) if j["key"]["agent"] == "ppo+mekf"]
    assert {j["key"]["env"] for j in played} == {"flight"} and len(played) == 2
    for j in played:
        assert "/models/lab/ppo/seed0/" in j["policy"]["model"]
        assert j["policy"]["params"] == {"estimator": "mekf"}
    with pytest.raises(ValueError, match="plays the models of ppo: .*its envs or some of them"):
        load_campaign(
            {
                **_campaign(["flight"]),
                "agents": [{**_campaign(None)["agents"][0], "envs": ["lab"]}, _campaign(["flight"])["agents"][1]],
            }
        )
