"""The natively batched Magnetorquer-v0 follows the single env exactly."""

import gymnasium as gym
import numpy as np
import pytest
from batched_reference import step_matches_singles
from gymnasium.vector import AutoresetMode

from attitude_envs import presets
from attitude_envs.plants import magnetorquer as mt

MT = "attitude_envs/Magnetorquer-v0"
PAPER_FAULTS = presets.get(MT, "sadigh-2022-faults").params()["faults"]  # Sadigh et al. 2022, eq. (40)
KWARGS = {
    "episode_duration_s": 2.0,
    "task": "regulation",
    "inertia_uncertainty": {"kind": "random", "moment_scale": 0.1, "axis_angle_deg": 10},
}


def make_vec(n, **kwargs):
    return gym.make_vec(MT, num_envs=n, vectorization_mode="vector_entry_point", **{**KWARGS, **kwargs})


def test_make_vec_uses_the_native_batched_env():
    env = make_vec(3, observe_field=True)
    assert type(env).__name__ == "MagnetorquerVectorEnv"
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.observation_space.shape == (3, 10) and env.action_space.shape == (3, 4)


@pytest.mark.parametrize(
    "extra",
    [
        {
            "faults": [
                {"kind": "loss_of_effectiveness", "index": "random", "value": {"uniform": [0.2, 0.9]}, "onset_s": 0.5}
            ]
        },
        {
            "task": "tracking",
            "faults": PAPER_FAULTS,
            "observe_field": True,
            "gravity_gradient": True,
            "disturbance": {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-5},
            "integrator_dt_s": 0.05,
        },
    ],
)
def test_sub_envs_match_single_envs_bitwise_across_autoreset(extra):
    n, seed = 3, 100
    vec = make_vec(n, **extra)
    singles = [gym.make(MT, **{**KWARGS, **extra}).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=seed)
    assert np.array_equal(obs, np.stack([s.reset(seed=seed + i)[0] for i, s in enumerate(singles)]))
    rng = np.random.default_rng(0)
    for _ in range(20):  # exactly one 2 s episode of 0.1 s steps
        _, trunc, infos, single_infos = step_matches_singles(vec, singles, rng.uniform(-1, 1, (n, 4)))
        for i, info in enumerate(single_infos):
            truth = info["truth"]
            assert infos["truth"]["error_angle_deg"][i] == truth["error_angle_deg"]
            assert infos["time_s"][i] == info["time_s"]
            assert np.array_equal(
                vec.states[i],
                truth["state"]["attitude"].tolist()
                + truth["state"]["rate_rad_s"].tolist()
                + truth["state"]["wheel_speed_rad_s"].tolist(),
            )
    assert trunc.all()
    # next-step autoreset: the following step resets, ignores the action, reward 0; the
    # new episodes are the single envs' next episodes (same RNG streams)
    obs, rewards, term, trunc, infos = vec.step(np.ones((n, 4)))
    assert not (term.any() or trunc.any()) and np.all(rewards == 0.0)
    assert not infos["_truth"].any() and not infos["truth"]["_applied"].any()  # the reset rows are masked out
    assert np.array_equal(obs, np.stack([s.reset()[0] for s in singles]))
    assert np.allclose(vec.states[:, 7], 0.0)  # wheels back at rest after the reset


def test_batched_path_conserves_inertial_momentum_with_the_wheel_working():
    """No field torque (zero dipoles), no disturbance, constant inertia: the wheel only
    exchanges momentum, so each sub-env's total angular momentum in ECI stays put."""
    vec = make_vec(
        3,
        disturbance=None,
        time_varying_inertia=None,
        initial_rate_max_rad_s=0.05,
        episode_duration_s=100.0,
        integrator_dt_s=0.05,
    )
    vec.reset(seed=4)
    base = vec.unwrapped
    p = base.model.params

    def momentum(t_s):
        out = []
        for env, y in zip(base.envs, vec.states, strict=True):
            frame = env.orbit.state_at(t_s).eci_from_orbital
            w_bi = mt.inertial_rate(y[:4], y[4:7], env.orbit.state_at(t_s).rate_rad_s)
            inertia = env.true_inertia_at(t_s)  # constant here: no ΔJ(t)
            out.append(mt.angular_momentum_inertial(y[:4], w_bi, y[7], inertia, p.wheel_inertia_kg_m2, frame))
        return np.array(out)

    h0 = momentum(0.0)
    wheel0 = vec.states[:, 7].copy()
    for k in range(200):
        actions = np.zeros((3, 4))
        actions[:, 3] = [1.0, -0.5, 0.3] if k < 100 else [-0.5, 1.0, 0.0]
        vec.step(actions)
    assert np.all(np.abs(vec.states[:, 7] - wheel0) > 10.0)  # the wheels did work
    assert np.allclose(momentum(20.0), h0, rtol=0, atol=1e-10 * np.linalg.norm(h0, axis=1).max())


def test_batched_igrf_matches_single_envs():
    pytest.importorskip("ppigrf")
    kwargs = {"field_model": "igrf", "episode_duration_s": 1.0, "observe_field": True}
    vec = make_vec(2, **kwargs)
    singles = [gym.make(MT, **{**KWARGS, **kwargs}).unwrapped for _ in range(2)]
    obs, _ = vec.reset(seed=7)
    assert np.array_equal(obs, np.stack([s.reset(seed=7 + i)[0] for i, s in enumerate(singles)]))
    for _ in range(10):
        obs, rewards, *_ = vec.step(np.full((2, 4), 0.5))
        for i, s in enumerate(singles):
            o, r, *_ = s.step(np.full(4, 0.5))
            assert np.array_equal(obs[i], o) and rewards[i] == r


def test_sb3_adapter_matches_dummy_vec_env():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from experiments.training.sb3_vec_env import SB3VecEnv

    kwargs = {"episode_duration_s": 1.0}
    venv = SB3VecEnv(MT, num_envs=3, **kwargs)
    venv.seed(5)
    reference = DummyVecEnv([lambda: gym.make(MT, **kwargs) for _ in range(3)])
    reference.seed(5)
    assert np.array_equal(venv.reset(), reference.reset())
    actions = np.random.default_rng(1).uniform(-1, 1, (3, 4)).astype(np.float32)
    for _ in range(10):
        obs, rewards, dones, infos = venv.step(actions)
        ref_obs, ref_rewards, ref_dones, ref_infos = reference.step(actions)
        assert np.array_equal(obs, ref_obs) and np.allclose(rewards, ref_rewards) and np.array_equal(dones, ref_dones)
    assert dones.all() and infos[0]["TimeLimit.truncated"]
    assert np.array_equal(infos[2]["terminal_observation"], ref_infos[2]["terminal_observation"])


def test_batched_path_is_fourth_order_in_the_integrator_step():
    """Halving the RK4 sub-step divides the state error after 20 s by ~16 (the paper's
    disturbance, ΔJ(t), the field and the orbit all vary within each step)."""

    def final_states(h):
        vec = make_vec(2, control_dt_s=1.0, integrator_dt_s=h, episode_duration_s=20.0, initial_rate_max_rad_s=0.02)
        vec.reset(seed=3)
        actions = np.array([[0.5, -0.8, 0.3, 1.0], [-0.2, 0.9, -0.7, -1.0]])
        for _ in range(20):
            vec.step(actions)
        return vec.states[:, :7].copy()

    fine = final_states(1.0 / 64)
    errors = [np.abs(final_states(h) - fine).max() for h in (0.5, 0.25, 0.125)]
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert errors[2] > 1e-13  # above rounding: the ratios measure truncation error
    assert all(12.0 < r < 20.0 for r in ratios), ratios
