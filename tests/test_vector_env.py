"""The natively batched ReactionWheel-v0 follows the single env exactly."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from attitude_envs.plants import gyrostat

RW = "attitude_envs/ReactionWheel-v0"
KWARGS = {
    "episode_duration_s": 2.0,
    "inertia_uncertainty": {"kind": "random", "moment_scale": 0.2},
    "initial_rate_max_rad_s": 0.05,
}


def make_vec(n, **kwargs):
    return gym.make_vec(RW, num_envs=n, vectorization_mode="vector_entry_point", **{**KWARGS, **kwargs})


def test_make_vec_uses_the_native_batched_env():
    env = make_vec(3)
    assert type(env).__name__ == "ReactionWheelVectorEnv"
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.observation_space.shape == (3, 6) and env.action_space.shape == (3, 4)


@pytest.mark.parametrize(
    "faults",
    [None, [{"kind": "loss_of_effectiveness", "index": "random", "value": {"uniform": [0.2, 0.9]}, "onset_s": 0.5}]],
)
def test_sub_envs_match_single_envs_bitwise_across_autoreset(faults):
    n, seed = 3, 100
    vec = make_vec(n, faults=faults)
    singles = [gym.make(RW, **KWARGS, faults=faults).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=seed)
    single_obs = [s.reset(seed=seed + i)[0] for i, s in enumerate(singles)]
    assert np.array_equal(obs, np.stack(single_obs))
    rng = np.random.default_rng(0)
    for _ in range(20):  # exactly one 2 s episode of 0.1 s steps
        actions = rng.uniform(-1, 1, (n, 4))
        obs, rewards, term, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            o, r, te, tr, info = s.step(actions[i])
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
            assert np.array_equal(infos["applied"][i], info["applied"])
    assert trunc.all()
    # next-step autoreset: the following step resets, ignores the action, reward 0
    obs, rewards, term, trunc, _ = vec.step(np.ones((n, 4)))
    assert not (term.any() or trunc.any()) and np.all(rewards == 0.0)
    assert np.allclose(vec.states[:, 7:], 0.0)  # wheels back at rest after the reset


def test_same_step_autoreset_reports_final_observation():
    vec = make_vec(2, autoreset_mode="same_step")
    vec.reset(seed=0)
    for _ in range(19):
        vec.step(np.zeros((2, 4)))
    obs, _, _, trunc, infos = vec.step(np.zeros((2, 4)))
    assert trunc.all() and infos["_final_obs"].all()
    assert not np.array_equal(infos["final_obs"][0], obs[0])  # obs is already the new episode's


def test_batched_path_conserves_momentum():
    vec = make_vec(
        4,
        inertia_uncertainty=None,
        initial_rate_max_rad_s=0.05,
        episode_duration_s=1e3,
        max_wheel_speed_rad_s=np.inf,
        integrator_dt_s=0.02,
    )
    vec.reset(seed=0)
    params = vec.unwrapped.model.params

    def inertial_momentum():
        from attitude_envs import quaternion

        return np.array(
            [quaternion.to_matrix(s[:4]) @ gyrostat.body_momentum(params, s[4:7], s[7:]) for s in vec.states]
        )

    h0 = inertial_momentum()
    rng = np.random.default_rng(1)
    for _ in range(200):
        vec.step(rng.uniform(-1, 1, (4, 4)))
    assert np.allclose(inertial_momentum(), h0, rtol=1e-9, atol=1e-12)


def test_bad_batched_actions_are_rejected():
    vec = make_vec(2)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must have shape \(2, 4\)"):
        vec.step(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="actions must be finite"):
        vec.step(np.full((2, 4), np.nan))
    with pytest.raises(ValueError, match="num_envs must be >= 1"):
        gym.make_vec(RW, num_envs=0, vectorization_mode="vector_entry_point")


def test_sb3_trains_directly_on_the_batched_env():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env  # noqa: F401  (import works)
    from stable_baselines3.common.vec_env import DummyVecEnv

    from attitude_envs.envs.sb3_vec_env import SB3VecEnv

    venv = SB3VecEnv(RW, num_envs=4, episode_duration_s=1.0)
    venv.seed(3)
    obs = venv.reset()
    reference = DummyVecEnv([lambda: gym.make(RW, episode_duration_s=1.0) for _ in range(4)])
    reference.seed(3)
    assert np.array_equal(obs, reference.reset())  # same seeding convention as SB3's own VecEnvs
    actions = np.zeros((4, 4), dtype=np.float32)
    for _ in range(10):
        obs, rewards, dones, infos = venv.step(actions)
        ref_obs, ref_rewards, ref_dones, ref_infos = reference.step(actions)
        assert np.allclose(obs, ref_obs) and np.allclose(rewards, ref_rewards) and np.array_equal(dones, ref_dones)
    assert dones.all() and infos[0]["TimeLimit.truncated"]
    assert np.allclose(infos[0]["terminal_observation"], ref_infos[0]["terminal_observation"])
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_linear_system_batch_matches_single_envs_bitwise(noise):
    kwargs = {"x0_std": 0.1, "process_noise_std": noise, "episode_steps": 15}
    n = 3
    vec = gym.make_vec("attitude_envs/LinearSystem-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make("attitude_envs/LinearSystem-v0", **kwargs).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=9)
    assert np.array_equal(obs, np.stack([s.reset(seed=9 + i)[0] for i, s in enumerate(singles)]))
    rng = np.random.default_rng(2)
    for _ in range(15):
        actions = rng.uniform(-1, 1, (n, 3))
        obs, rewards, _, trunc, _ = vec.step(actions)
        for i, s in enumerate(singles):
            o, r, _, tr, _ = s.step(actions[i])
            assert np.array_equal(obs[i], o) and rewards[i] == r and tr == trunc[i]
    assert trunc.all()


def test_lqr_policy_acts_on_a_batch():
    from baselines.lqr import LQRPolicy

    env = gym.make(RW)
    policy = LQRPolicy(env)
    obs = np.random.default_rng(0).normal(scale=0.1, size=(5, 6)).astype(np.float32)
    batch = policy.act(obs, {})
    assert batch.shape == (5, 4)
    assert np.allclose(batch, np.stack([policy.act(o, {}) for o in obs]), atol=1e-7)


def test_batched_env_refuses_what_it_does_not_model():
    with pytest.raises(ValueError, match="sensors and fault_hint are not supported by the batched env"):
        make_vec(2, fault_hint=True)


def test_air_bearing_batch_matches_single_envs_including_the_tilt_stop():
    ab = "attitude_envs/AirBearing-v0"
    n, kwargs = 3, {"episode_duration_s": 3.0}
    vec = gym.make_vec(ab, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(ab, **kwargs).unwrapped for _ in range(n)]
    options = {"euler_321_deg": [38.0, 0.0, 0.0], "rate_rad_s": [0.3, 0.0, 0.0]}  # tips over the 40° stop
    vec.reset(seed=1)
    vec.unwrapped._reset_one(0, 1, options)
    singles[0].reset(seed=1, options=options)
    for i in range(1, n):
        singles[i].reset(seed=1 + i)
    stopped = False
    for _ in range(30):
        actions = np.zeros((n, 3))
        obs, rewards, term, trunc, _ = vec.step(actions)
        for i, s in enumerate(singles):
            o, r, te, tr, _ = s.step(actions[i])
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
        if term[0]:
            stopped = True
            break
    assert stopped and not term[1:].any()
