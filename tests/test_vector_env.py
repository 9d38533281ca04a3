"""The natively batched ReactionWheel-v0 follows the single env exactly."""

import gymnasium as gym
import numpy as np
import pytest
from batched_reference import step_matches_singles
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
        _, trunc, _, _ = step_matches_singles(vec, singles, rng.uniform(-1, 1, (n, 4)))
    assert trunc.all()
    # next-step autoreset: the following step resets, ignores the action, reward 0
    obs, rewards, term, trunc, _ = vec.step(np.ones((n, 4)))
    assert not (term.any() or trunc.any()) and np.all(rewards == 0.0)
    assert np.allclose(vec.states[:, 7:], 0.0)  # wheels back at rest after the reset


def _step_singles_with_autoreset(singles, actions, done_before):
    """Single envs stepped as gymnasium's next-step autoreset does: a sub-env that ended
    last step resets (no seed: its own generator goes on) and reports reward 0."""
    out = []
    for i, s in enumerate(singles):
        if done_before[i]:
            o, _ = s.reset()
            out.append((o, 0.0, False, False, None))
        else:
            out.append(s.step(actions[i]))
    return out


@pytest.mark.parametrize(
    "kwargs",
    [
        {  # two blocks of lanes, the second partial; sub-steps, disturbance, wheel-speed limit, faults
            "integrator_dt_s": 0.05,
            "max_wheel_speed_rad_s": 30.0,
            "disturbance": {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-3, "initial_nm": [1e-3, 0.0, -1e-3]},
            "faults": [{"kind": "loss_of_effectiveness", "index": "random", "value": 0.5, "onset_s": 0.3}],
            "max_rate_rad_s": 0.1,  # some sub-envs tumble and terminate
            "initial_rate_max_rad_s": 0.08,
        },
        {"observe_wheel_speeds": True, "wheel_momentum_weight": 10.0, "cost_input": "wheel", "R": np.eye(4)},
        {"action_frame": "body", "faults": [{"kind": "stuck", "index": 1, "value": 0.2, "onset_s": 0.5}]},
    ],
    ids=["partial-block-disturbance-faults-limits", "wheel-cost-and-momentum", "body-frame-actions"],
)
def test_sub_envs_match_single_envs_bitwise_in_every_kernel_path(kwargs):
    n, seed = 67 if "disturbance" in kwargs else 3, 7
    vec = make_vec(n, **kwargs)
    singles = [gym.make(RW, **{**KWARGS, **kwargs}).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=seed)
    assert np.array_equal(obs, np.stack([s.reset(seed=seed + i)[0] for i, s in enumerate(singles)]))
    rng = np.random.default_rng(1)
    done = np.zeros(n, dtype=bool)
    ended = 0
    for _ in range(45):  # past the 2 s episodes: next-step autoreset of every sub-env
        actions = rng.uniform(-1.2, 1.2, (n, *vec.single_action_space.shape))
        obs, rewards, term, trunc, infos = vec.step(actions)
        for i, (o, r, te, tr, info) in enumerate(_step_singles_with_autoreset(singles, actions, done)):
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i], i
            assert infos["_cost"][i] == infos["_truth"][i] == infos["truth"]["_applied"][i] == (info is not None)
            if info is not None:
                truth = infos["truth"]
                assert (
                    np.array_equal(truth["applied"][i], info["truth"]["applied"]) and infos["cost"][i] == info["cost"]
                )
                assert truth["error_angle_deg"][i] == info["truth"]["error_angle_deg"]
                assert infos["time_s"][i] == info["time_s"]
        done = term | trunc
        ended += done.sum()
    assert ended >= n


@pytest.mark.parametrize("control_dt_s", [None, 0.03], ids=["k1", "k3"])
def test_linear_system_batch_matches_single_envs_across_autoreset_with_noise(control_dt_s):
    kwargs = {"x0_std": 0.1, "process_noise_std": 0.01, "episode_steps": 5}
    if control_dt_s is not None:  # 3 plant steps of 0.01 s per decision (LinearSystem's decision period)
        kwargs |= {"dt_s": 0.01, "control_dt_s": control_dt_s, "episode_steps": 15}
    n = 3
    vec = gym.make_vec("attitude_envs/LinearSystem-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make("attitude_envs/LinearSystem-v0", **kwargs).unwrapped for _ in range(n)]
    vec.reset(seed=4)
    for i, s in enumerate(singles):
        s.reset(seed=4 + i)
    rng = np.random.default_rng(3)
    done = np.zeros(n, dtype=bool)
    for _ in range(13):  # two autoresets: the reset step draws no process noise
        actions = rng.uniform(-1, 1, (n, 3))
        obs, rewards, term, trunc, _ = vec.step(actions)
        for i, (o, r, te, tr, _) in enumerate(_step_singles_with_autoreset(singles, actions, done)):
            assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
        done = term | trunc


def test_batched_rk4_global_error_is_fourth_order():
    from scipy.integrate import solve_ivp

    u_cmd = np.array([0.3, -0.2, 0.1, 0.4])
    options = {"rate_rad_s": [0.4, -0.3, 0.5], "wheel_speed_rad_s": [50.0, -40.0, 20.0, 0.0]}
    kwargs = {"max_wheel_speed_rad_s": np.inf, "episode_duration_s": 1e6, "max_rate_rad_s": 100.0}
    kwargs |= {"inertia_uncertainty": None, "control_dt_s": 0.2}
    params = make_vec(1, **kwargs).unwrapped.model.params
    u = u_cmd * params.max_wheel_torque_nm
    errors = []
    for h in (0.2, 0.1, 0.05):
        vec = make_vec(2, integrator_dt_s=h, **kwargs)
        vec.reset(seed=0, options=options)
        y0 = vec.states[0].copy()
        for _ in range(50):
            vec.step(np.tile(u_cmd, (2, 1)))
        if not errors:
            sol = solve_ivp(
                lambda t, y: gyrostat.derivative(params, y, u, np.zeros(3)),
                (0.0, 10.0),
                y0,
                method="DOP853",
                rtol=1e-13,
                atol=1e-14,
            )
            ref = sol.y[:, -1]
        assert np.array_equal(vec.states[0], vec.states[1])
        errors.append(np.linalg.norm(vec.states[0][:7] - ref[:7]))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert errors[-1] < 1e-6
    for r in ratios:
        assert 12.0 < r < 20.0, (errors, ratios)


def test_returned_arrays_are_not_reused_by_the_env():
    vec = make_vec(2)
    vec.reset(seed=0)
    first = vec.step(np.ones((2, 4)))
    infos = {**first[4], **{"truth." + k: v for k, v in first[4]["truth"].items()}}
    del infos["truth"]
    kept = [np.copy(a) for a in first[:4]] + [{k: np.copy(v) for k, v in infos.items()}]
    for _ in range(3):
        vec.step(-np.ones((2, 4)))
    for a, b in zip(first[:4], kept[:4], strict=True):
        assert np.array_equal(a, b)
    for k, v in kept[4].items():
        assert np.array_equal(infos[k], v)


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


def test_sb3_trains_directly_on_the_batched_env():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env  # noqa: F401  (import works)
    from stable_baselines3.common.vec_env import DummyVecEnv

    from experiments.training.sb3_vec_env import SB3VecEnv

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
    from experiments.training.training import log_without_folder

    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    log_without_folder(model)  # else learn() makes a $TMPDIR/SB3-* folder
    model.learn(256)
    assert model.num_timesteps >= 256


@pytest.mark.parametrize("control_dt_s", [None, 5.0], ids=["k1", "k500"])
@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_linear_system_batch_matches_single_envs_bitwise(noise, control_dt_s):
    kwargs = {"x0_std": 0.1, "process_noise_std": noise, "episode_steps": 15}
    if control_dt_s is not None:  # heravi-2017 (dt_s 0.01 s) deciding every 5 s: 500 plant steps
        kwargs |= {"control_dt_s": control_dt_s, "episode_steps": 7500}
    n = 3
    vec = gym.make_vec("attitude_envs/LinearSystem-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make("attitude_envs/LinearSystem-v0", **kwargs).unwrapped for _ in range(n)]
    obs, _ = vec.reset(seed=9)
    assert np.array_equal(obs, np.stack([s.reset(seed=9 + i)[0] for i, s in enumerate(singles)]))
    rng = np.random.default_rng(2)
    for _ in range(15):
        actions = rng.uniform(-1, 1, (n, 3))
        obs, rewards, _, trunc, infos = vec.step(actions)
        for i, s in enumerate(singles):
            o, r, _, tr, info = s.step(actions[i])
            assert np.array_equal(obs[i], o) and rewards[i] == r and tr == trunc[i]
            assert np.array_equal(infos["truth"]["applied"][i], info["truth"]["applied"])
            assert np.array_equal(infos["commanded"][i], info["commanded"]) and infos["time_s"][i] == info["time_s"]
    assert trunc.all()


def test_lqr_policy_acts_on_a_batch():
    from baselines.lqr import LQRPolicy

    env = gym.make(RW)
    policy = LQRPolicy(env)
    obs = np.random.default_rng(0).normal(scale=0.1, size=(5, 6)).astype(np.float32)
    batch = policy.act(obs, {})
    assert batch.shape == (5, 4)
    assert np.allclose(batch, np.stack([policy.act(o, {}) for o in obs]), atol=1e-7)


def test_air_bearing_batch_matches_single_envs_including_the_tilt_stop():
    ab = "attitude_envs/AirBearing-v0"
    n, kwargs = 3, {"episode_duration_s": 3.0}
    vec = gym.make_vec(ab, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(ab, **kwargs).unwrapped for _ in range(n)]
    options = {"euler_321_deg": [38.0, 0.0, 0.0], "rate_rad_s": [0.3, 0.0, 0.0]}  # tips over the 40° stop
    vec.reset(seed=1)
    vec.reset(seed=1, options={**options, "reset_mask": np.array([True, False, False])})
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
