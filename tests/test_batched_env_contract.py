"""The contract every native batched env shares (``vector_base.BatchedEnv``): same-step
autoreset reports the single env's final observation, and bad input is refused by name.
Per-env physics (bitwise equality across next-step autoreset, conservation, RK4 order) lives
in each env's own test module."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs.registration import VECTOR_ENTRY_POINTS

# Short episodes (a few steps) so that the same-step autoresets come quickly.
SHORT = {
    "attitude_envs/ReactionWheel-v0": {"episode_duration_s": 2.0, "initial_rate_max_rad_s": 0.05},
    "attitude_envs/AirBearing-v0": {"episode_duration_s": 0.2},  # control period 0.01 s
    "attitude_envs/LinearSystem-v0": {"x0_std": 0.1, "process_noise_std": 0.01, "episode_steps": 5},
    "attitude_envs/FuelSlosh-v0": {"episode_duration_s": 2.0, "randomize_initial_state": True},
    "attitude_envs/Magnetorquer-v0": {"episode_duration_s": 2.0, "task": "regulation"},
}


def test_every_batched_env_is_covered():
    assert set(SHORT) == set(VECTOR_ENTRY_POINTS)


def make_vec(env_id: str, n: int, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **{**SHORT[env_id], **kwargs})


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_same_step_autoreset_reports_the_single_envs_final_observation(env_id):
    n = 2
    vec = make_vec(env_id, n, autoreset_mode="same_step")
    singles = [gym.make(env_id, **SHORT[env_id]).unwrapped for _ in range(n)]
    vec.reset(seed=7)
    for i, s in enumerate(singles):
        s.reset(seed=7 + i)
    rng = np.random.default_rng(1)
    seen_final = 0
    for _ in range(45):
        actions = rng.uniform(-0.3, 0.3, vec.action_space.shape)
        obs, rewards, term, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            o, r, te, tr, _ = s.step(actions[i])
            assert rewards[i] == r and te == term[i] and tr == trunc[i]
            if te or tr:
                assert infos["_final_obs"][i] and np.array_equal(infos["final_obs"][i], o)
                o = s.reset()[0]  # the returned obs is already the new episode's
                seen_final += 1
            assert np.array_equal(obs[i], o)
    assert seen_final >= 2 * n


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_bad_batched_input_is_rejected_by_name(env_id):
    vec = make_vec(env_id, 2)
    vec.reset(seed=0)
    m = vec.single_action_space.shape[0]
    with pytest.raises(ValueError, match=rf"actions must have shape \(2, {m}\)"):
        vec.step(np.zeros((3, m)))
    with pytest.raises(ValueError, match="actions must be finite"):
        bad = np.zeros((2, m))
        bad[1, -1] = np.nan
        vec.step(bad)
    with pytest.raises(ValueError, match="num_envs must be >= 1"):
        gym.make_vec(env_id, num_envs=0, vectorization_mode="vector_entry_point")


@pytest.mark.parametrize("env_id", sorted(VECTOR_ENTRY_POINTS))
def test_step_before_reset_raises_reset_needed(env_id):
    vec = make_vec(env_id, 3)
    actions = np.zeros(vec.action_space.shape)
    with pytest.raises(gym.error.ResetNeeded, match=r"sub-envs \[0, 1, 2\] .* never been reset; call reset\(\) first"):
        vec.step(actions)
    vec.reset(seed=0, options={"reset_mask": np.array([True, False, True])})
    with pytest.raises(gym.error.ResetNeeded, match=r"sub-envs \[1\] "):
        vec.step(actions)
    vec.reset(seed=0, options={"reset_mask": np.array([False, True, False])})
    vec.step(actions)  # every sub-env has been reset once: steps (and autoresets) from here on


UNMODELLED = [
    (env_id, kwargs)
    for env_id in sorted(set(VECTOR_ENTRY_POINTS) - {"attitude_envs/LinearSystem-v0"})
    for kwargs in ({"fault_hint": True}, {"sensors": {"gyro": {"noise_std": 1e-4}}})
    if not (env_id == "attitude_envs/FuelSlosh-v0" and "sensors" in kwargs)  # its sensors are a string choice
]


@pytest.mark.parametrize(("env_id", "kwargs"), UNMODELLED)
def test_batched_env_refuses_what_it_does_not_model(env_id, kwargs):
    with pytest.raises(ValueError, match="sensors and fault_hint are not supported by the batched env"):
        make_vec(env_id, 2, **kwargs)
