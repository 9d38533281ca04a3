"""Every observation of every id lies in its declared space, at every step, limit crossings
included: Gymnasium's passive env checker stays silent (warnings as errors) over
random-action episodes on the ten registered ids, with and without faults, and the step that
crosses a limit observes its measurement clipped to the box
(:meth:`attitude_envs.envs.base.AttitudeEnv.clip_observation`), the single and the batched
envs alike."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.passive_env_checker import env_reset_passive_checker, env_step_passive_checker

import attitude_envs  # noqa: F401  (registers the ids)
from attitude_envs.registration import ENV_IDS, LEARNING_TASKS, OUT_OF_DATE
from attitude_envs.scenarios import load_scenario

ALL_IDS = sorted([*ENV_IDS, *LEARNING_TASKS])
EPISODES = 12
MAX_STEPS = 150  # the -v0 episodes are long; random actions cross the limits early where they do

#: keywords whose limits a random action overshoots in one decision, past twice the limit
#: (the observation bound): 84–100 of the 100 bang-bang episodes of each row end at a bound
OVERSHOOT = [
    ("attitude_envs/FuelSlosh-v1", {}),  # the pitch rate, on about a third of random episodes
    ("attitude_envs/FuelSlosh-v0", {"max_pitch_rate_rad_s": 0.05}),
    ("attitude_envs/AirBearing-v1", {"max_rate_rad_s": 0.02}),
    ("attitude_envs/Magnetorquer-v1", {"max_rate_rad_s": 0.001}),
]


def _make(env_id: str, **kwargs) -> gym.Env:
    """``gym.make`` with the passive checker on; only Gymnasium's out-of-date note on the
    ``-v0`` ids (kept on purpose) is let through."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=OUT_OF_DATE, category=DeprecationWarning)
        env = gym.make(env_id, **kwargs)
    assert env.spec is not None and not env.spec.disable_env_checker
    return env


def _episodes(env: gym.Env, seeds, bang: bool) -> tuple[int, int]:
    """Random-action episodes through the passive checker's reset and step checks, every
    observation tested against the space. Returns (terminated episodes, terminal
    observations at a bound)."""
    space = env.observation_space
    terminated_eps = at_bound = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any checker warning fails the test
        for seed in seeds:
            obs, _ = env_reset_passive_checker(env, seed=seed)
            assert space.contains(obs), (seed, "reset", obs)
            rng = np.random.default_rng(seed)
            for _ in range(MAX_STEPS):
                n = env.action_space.shape
                action = (rng.choice([-1.0, 1.0], n) if bang else rng.uniform(-1.0, 1.0, n)).astype(np.float32)
                obs, _, terminated, truncated, _ = env_step_passive_checker(env, action)
                assert space.contains(obs), (seed, obs, space)
                if terminated:
                    terminated_eps += 1
                    at_bound += bool(np.any((obs == space.high) | (obs == space.low)))
                if terminated or truncated:
                    break
    return terminated_eps, at_bound


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_passive_checker_is_silent_over_random_episodes(env_id):
    env = _make(env_id)
    _episodes(env, range(EPISODES), bang=False)
    _episodes(env, range(100, 100 + EPISODES // 2), bang=True)


@pytest.mark.parametrize(
    ("env_id", "scenario"),
    [
        ("attitude_envs/ReactionWheel-v1", "two-wheel-failure"),
        ("attitude_envs/ReactionWheel-v0", "sensor-bias"),  # noisy, biased sensors
        ("attitude_envs/AirBearing-v1", "air-bearing-outage"),
        ("attitude_envs/FuelSlosh-v1", "slosh-actuator-faults"),
        ("attitude_envs/Magnetorquer-v1", "sadigh-2022-faults"),
    ],
)
def test_passive_checker_is_silent_with_faults_and_sensors(env_id, scenario):
    """The packaged fault and sensor scenarios, with the fault flags observed."""
    sc = load_scenario(scenario)
    env = _make(env_id, **sc["env_kwargs"], faults=sc["faults"], fault_hint=True)
    _episodes(env, range(EPISODES // 2), bang=True)
    _episodes(env, range(EPISODES // 2), bang=False)


@pytest.mark.parametrize(("env_id", "kwargs"), OVERSHOOT)
def test_a_limit_crossing_observes_the_clipped_measurement(env_id, kwargs):
    """The cases that left the box: the terminal observation is at a bound (the clip acted:
    the test exercises it), in the box, and is the true state's observation clipped."""
    env = _make(env_id, **kwargs)
    terminated, at_bound = _episodes(env, range(100), bang=True)
    assert terminated >= 90 and at_bound >= 50, (terminated, at_bound)
    if "FuelSlosh" in env_id:  # observed exactly: the observation is the state's entries
        raw = env.unwrapped
        space = env.observation_space
        for seed in range(20):
            raw.reset(seed=seed)
            rng = np.random.default_rng(seed)
            while True:
                obs, _, terminated, truncated, info = raw.step(rng.choice([-1.0, 1.0], 2))
                measured = info["truth"]["full_state"][raw.observation_index].astype(np.float32)
                expected = np.clip(measured, space.low, space.high) if terminated else measured
                np.testing.assert_array_equal(obs, expected)
                if terminated or truncated:
                    break


def test_a_start_beyond_the_limits_is_observed_clipped():
    """The paper's ±30° slosh start under a 2° slosh limit (bound 4°): the reset observation
    is at the bound, in the space, and the first step ends the episode."""
    env = _make("attitude_envs/FuelSlosh-v0", max_slosh_angle_deg=2.0)
    space = env.observation_space
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs, _ = env_reset_passive_checker(env, seed=0)
        assert space.contains(obs)
        slosh = [3, 5]  # ψ1, ψ2 in [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2, v_x]
        np.testing.assert_array_equal(np.abs(obs[slosh]), space.high[slosh])
        obs, _, terminated, _, _ = env_step_passive_checker(env, np.zeros(2, np.float32))
        assert terminated and space.contains(obs)


def test_the_batched_env_clips_as_the_single_env():
    """FuelSlosh-v1's batched env: every observation and final observation in the space,
    equal to the single envs' (same-step autoreset)."""
    n = 4
    vec = gym.make_vec(
        "attitude_envs/FuelSlosh-v1", num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode="same_step"
    )
    singles = [_make("attitude_envs/FuelSlosh-v1").unwrapped for _ in range(n)]
    space = vec.single_observation_space
    vec.reset(seed=3)
    for i, s in enumerate(singles):
        s.reset(seed=3 + i)
    rng = np.random.default_rng(0)
    clipped = 0
    for _ in range(60):
        actions = rng.choice([-1.0, 1.0], vec.action_space.shape)
        obs, _, term, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            o, _, te, tr, _ = s.step(actions[i])
            assert (te, tr) == (term[i], trunc[i])
            if te or tr:
                final = infos["final_obs"][i]
                assert space.contains(final) and np.array_equal(final, o)
                clipped += bool(np.any(final == space.high) | np.any(final == space.low))
                o = s.reset()[0]
            assert space.contains(obs[i]) and np.array_equal(obs[i], o)
    assert clipped >= 3, clipped
