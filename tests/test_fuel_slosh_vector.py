"""The natively batched FuelSlosh-v0 follows the single env exactly (bitwise), across
terminations and both autoreset modes, and keeps the plant's conservation laws."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from attitude_envs.plants import slosh

SLOSH = "attitude_envs/FuelSlosh-v0"
KWARGS = {"episode_duration_s": 2.0, "randomize_initial_state": True}
FAULTS = [
    {"kind": "loss_of_effectiveness", "index": "random", "value": {"uniform": [0.2, 0.9]}, "onset_s": 0.5},
    {"kind": "intermittent", "index": 1, "onset_s": {"uniform": [0.0, 1.0]}, "mean_on_s": 0.3, "mean_off_s": 0.2},
]


def make_vec(n, **kwargs):
    return gym.make_vec(SLOSH, num_envs=n, vectorization_mode="vector_entry_point", **{**KWARGS, **kwargs})


def test_make_vec_uses_the_native_batched_env():
    env = make_vec(3, observe_slosh=False)
    assert type(env).__name__ == "FuelSloshVectorEnv"
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.observation_space.shape == (3, 4) and env.action_space.shape == (3, 2)


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.uniform(-0.3, 0.3, (n, 2))
    a[0] = [0.0, 1.0]  # full pitch moment: sub-env 0 terminates (pitch rate) every few steps
    return a


@pytest.mark.parametrize("faults", [None, FAULTS])
def test_sub_envs_match_single_envs_bitwise_across_next_step_autoreset(faults):
    n, seed = 3, 100
    vec = make_vec(n, faults=faults)
    singles = [gym.make(SLOSH, **KWARGS, faults=faults).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=seed)
    assert np.array_equal(obs, np.stack([s.reset(seed=seed + i)[0] for i, s in enumerate(singles)]))
    rng = np.random.default_rng(0)
    done = np.zeros(n, dtype=bool)
    ends = 0
    for _ in range(45):  # two 2 s episodes of sub-envs 1, 2 and many of sub-env 0
        actions = _actions(rng, n)
        obs, rewards, term, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            if done[i]:  # gymnasium's next-step autoreset: reset, action ignored, reward 0
                o, r, te, tr = s.reset()[0], 0.0, False, False
            else:
                o, r, te, tr, info = s.step(actions[i])
                assert np.array_equal(infos["truth"]["applied"][i], info["truth"]["applied"])
                assert np.array_equal(infos["commanded"][i], info["commanded"])
                assert np.array_equal(infos["truth"]["new_inputs"][i], info["truth"]["new_inputs"])
                assert infos["cost"][i] == info["cost"] and infos["time_s"][i] == info["time_s"]
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
        done = term | trunc
        ends += int(done.sum())
    assert ends >= 8 and not np.array_equal(vec.states[1], vec.states[2])


def test_batched_path_conserves_energy_and_momentum():
    """No thrust, no damping, no moment: every sub-env keeps T, P and H (the paper's
    Lagrangian, eq. 5, has no potential) through
    the batched compiled step, to the RK4 error of 0.01 s sub-steps."""
    params = slosh.SloshParams(thrust_n=0.0, damping_kg_m2_s=(0.0, 0.0))
    limits = {"max_pitch_rate_rad_s": 10.0, "max_pitch_angle_deg": 1e4, "max_slosh_angle_deg": 1e4}
    vec = make_vec(4, params=params, integrator_dt_s=0.01, episode_duration_s=1e3, **limits)
    vec.reset(seed=0)
    for i in range(4):  # spinning, sloshing starts: [v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]
        y = [30.0 * (i + 1), -5.0, 0.1, 0.05 * (i - 1.5), 0.5, 0.3, -0.4, -0.6]
        vec.unwrapped._reset_one(i, None, {"state": y})
    y0 = vec.states.copy()
    for _ in range(200):  # 20 s, ≈ 4 slosh periods
        vec.step(np.zeros((4, 2)))
    for a, b in zip(y0, vec.states, strict=True):
        P0, H0 = slosh.momenta(params, a)
        P, H = slosh.momenta(params, b)
        E0 = slosh.kinetic_energy(params, a)
        assert abs(slosh.kinetic_energy(params, b) - E0) <= 1e-8 * E0
        assert np.linalg.norm(P - P0) <= 1e-8 * np.linalg.norm(P0)
        assert abs(H - H0) <= 1e-8 * abs(H0)
        assert abs(b[slosh.IPSI1] - a[slosh.IPSI1]) > 0.01  # the pendulums really moved


def test_sb3_adapter_matches_dummy_vec_env():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from experiments.training.sb3_vec_env import SB3VecEnv

    venv = SB3VecEnv(SLOSH, num_envs=3, **KWARGS)
    reference = DummyVecEnv([lambda: gym.make(SLOSH, **KWARGS) for _ in range(3)])
    venv.seed(3)
    reference.seed(3)
    assert np.array_equal(venv.reset(), reference.reset())
    rng = np.random.default_rng(2)
    for _ in range(22):
        actions = _actions(rng, 3).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        ref_obs, ref_rewards, ref_dones, ref_infos = reference.step(actions)
        assert np.array_equal(obs, ref_obs) and np.array_equal(rewards, ref_rewards)
        assert np.array_equal(dones, ref_dones)
        for i in np.flatnonzero(dones):
            assert np.array_equal(infos[i]["terminal_observation"], ref_infos[i]["terminal_observation"])
            assert infos[i]["TimeLimit.truncated"] == ref_infos[i]["TimeLimit.truncated"]
