"""Gymnasium conventions of every registered env: check_env, seeding, pickling, options."""

import pickle
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import attitude_envs

CONFIGS = [
    ("attitude_envs/ReactionWheel-v0", {}),
    ("attitude_envs/ReactionWheel-v0", {"preset": "heravi-2017", "control_dt_s": 0.1}),
    (
        "attitude_envs/ReactionWheel-v0",
        {
            "observe_wheel_speeds": True,
            "wheel_momentum_weight": 10.0,
            "cost_input": "wheel",
            "R": 1.0,
            "inertia_uncertainty": {"kind": "random", "moment_scale": 0.2, "axis_angle_deg": 20},
            "disturbance": {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-4},
        },
    ),
    ("attitude_envs/ReactionWheel-v0", {"action_frame": "body", "fault_hint": True}),
    ("attitude_envs/LinearSystem-v0", {}),
    ("attitude_envs/AirBearing-v0", {"disturbance": {"kind": "constant", "torque_nm": [0.01, 0.01, 0.01]}}),
    ("attitude_envs/Magnetorquer-v0", {"episode_duration_s": 20.0, "observe_field": True}),
    (
        "attitude_envs/LinearSystem-v0",
        {"preset": None, "A": [[1.1, 0.1], [0, 0.9]], "B": [[0], [1]], "process_noise_std": 0.01},
    ),
    ("attitude_envs/FuelSlosh-v0", {}),
    ("attitude_envs/FuelSlosh-v0", {"randomize_initial_state": True, "observe_slosh": False}),
]
# configurations that start from a paper's fixed initial condition (no draw)
FIXED_START = {
    ("attitude_envs/ReactionWheel-v0", "heravi-2017"),
    ("attitude_envs/LinearSystem-v0", "heravi-2017"),
    ("attitude_envs/FuelSlosh-v0", "default"),
}


def starts_fixed(env_id: str, kwargs: dict) -> bool:
    if env_id.endswith("FuelSlosh-v0"):
        return (env_id, "default" if not kwargs.get("randomize_initial_state") else "random") in FIXED_START
    preset = kwargs.get("preset", "heravi-2017" if env_id.endswith("LinearSystem-v0") else "pyramid-4wheel")
    return (env_id, preset) in FIXED_START


def test_every_registered_id_is_covered():
    assert {c[0] for c in CONFIGS} == set(attitude_envs.ENV_IDS)


@pytest.mark.parametrize("env_id,kwargs", CONFIGS)
def test_check_env_is_clean(env_id, kwargs):
    env = gym.make(env_id, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)


def trajectory(env, seed, n=40):
    obs, _ = env.reset(seed=seed)
    action_rng = np.random.default_rng(7)
    out = [obs]
    for _ in range(n):
        obs, reward, terminated, truncated, _ = env.step(
            action_rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        out.append(np.append(obs, reward))
        if terminated or truncated:  # the next episode from the seeded generator's state
            obs, _ = env.reset()
            out.append(obs)
    return np.concatenate([np.ravel(o) for o in out])


@pytest.mark.parametrize("index", range(len(CONFIGS)))
def test_seeding_is_deterministic(index):
    env_id, kwargs = CONFIGS[index]
    a = trajectory(gym.make(env_id, **kwargs), seed=5)
    b = trajectory(gym.make(env_id, **kwargs), seed=5)
    c = trajectory(gym.make(env_id, **kwargs), seed=6)
    assert np.array_equal(a, b)
    assert np.array_equal(a, c) == starts_fixed(env_id, kwargs)


@pytest.mark.parametrize("env_id,kwargs", CONFIGS)
def test_pickled_env_continues_identically(env_id, kwargs):
    env = gym.make(env_id, **kwargs).unwrapped
    env.reset(seed=3)
    if any(env.step(env.action_space.sample())[2:4]):
        env.reset()
    clone = pickle.loads(pickle.dumps(env))
    action = np.full(env.action_space.shape, 0.3, dtype=np.float32)
    for _ in range(5):
        a = env.step(action)
        b = clone.step(action)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]
        if a[2] or a[3]:  # both go on with the next episode of their (equal) generators
            assert np.array_equal(env.reset()[0], clone.reset()[0])


def test_reset_options_pin_the_state():
    env = gym.make("attitude_envs/ReactionWheel-v0").unwrapped
    target = [0.0, 0.0, np.sin(0.25), np.cos(0.25)]
    obs, info = env.reset(
        seed=0,
        options={
            "attitude": [0, 0, 0, 1.0],
            "rate_rad_s": [0.01, 0.02, 0.03],
            "wheel_speed_rad_s": [1, 2, 3, 4.0],
            "target_attitude": target,
        },
    )
    assert np.allclose(info["truth"]["state"]["target_attitude"], target)
    assert np.allclose(info["truth"]["state"]["wheel_speed_rad_s"], [1, 2, 3, 4])
    assert np.allclose(obs, [0, 0, -np.sin(0.25), 0.01, 0.02, 0.03], atol=1e-7)
    assert info["truth"]["error_angle_deg"] == pytest.approx(np.degrees(0.5))
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(options={"atitude": [0, 0, 0, 1]})


def test_reaction_wheel_info_contract():
    """truth / measured / top level (attitude_envs.info): without sensors the measured state
    has the truth's values; the policy view holds no truth."""
    from attitude_envs.info import policy_view

    env = gym.make("attitude_envs/ReactionWheel-v0").unwrapped
    _, info = env.reset(seed=0)
    _, _, _, _, info = env.step(np.full(4, 0.2))
    assert set(info) == {"truth", "measured", "cost", "time_s", "commanded"}
    truth = info["truth"]
    assert set(truth) == {
        "state",
        "applied",
        "faults",
        "error_angle_deg",
        "disturbance_torque_nm",
        "true_inertia_kg_m2",
    }
    assert set(truth["state"]) == {"attitude", "rate_rad_s", "wheel_speed_rad_s", "target_attitude"}
    assert set(info["measured"]) == set(truth["state"])
    for key, value in truth["state"].items():
        assert np.array_equal(info["measured"][key], value)
    np.testing.assert_array_equal(info["commanded"], np.full(4, 0.1))
    assert "truth" not in policy_view(info)


@pytest.mark.parametrize("preset", ["spec-000", "pyramid-4wheel", "spec-001", "heravi-2017"])
def test_old_preset_names_are_aliases(preset):
    env = gym.make("attitude_envs/ReactionWheel-v0", preset=preset).unwrapped
    new = {"spec-000": "pyramid-4wheel", "spec-001": "heravi-2017"}.get(preset, preset)
    ref = gym.make("attitude_envs/ReactionWheel-v0", preset=new).unwrapped
    np.testing.assert_array_equal(env.kernel_constants, ref.kernel_constants)
    assert env.preset == preset


def test_unknown_keyword_is_a_one_line_error_with_a_suggestion():
    from attitude_envs.make import make_checked

    with pytest.raises(
        ValueError, match=r"'attitude_envs/ReactionWheel-v0'.*'control_dt'; did you mean 'control_dt_s'"
    ) as e:
        make_checked("attitude_envs/ReactionWheel-v0", control_dt=0.1)
    assert "\n" not in str(e.value) and "__init__" not in str(e.value)
    with pytest.raises(ValueError, match="did you mean 'initial_euler_max_deg'"):
        make_checked("attitude_envs/AirBearing-v0", initial_euler_max=[1.0, 1.0, 1.0])


def test_random_targets_respect_the_configured_angle():
    env = gym.make("attitude_envs/ReactionWheel-v0", target_angle_deg=20.0).unwrapped
    angles = [env.reset(seed=s)[1]["truth"]["error_angle_deg"] for s in range(50)]
    assert max(angles) <= 20.0 + 1e-9 and min(angles) < 10.0 < max(angles)


def test_inertia_uncertainty_keeps_nominal_model_and_draws_valid_tensors():
    env = gym.make(
        "attitude_envs/ReactionWheel-v0", inertia_uncertainty={"kind": "random", "moment_scale": 0.3}
    ).unwrapped
    nominal = env.model.params.inertia_kg_m2.copy()
    drawn = []
    for seed in range(30):
        _, info = env.reset(seed=seed)
        inertia = info["truth"]["true_inertia_kg_m2"]
        moments = np.sort(np.linalg.eigvalsh(inertia))
        assert moments[0] > 0 and moments[0] + moments[1] >= moments[2]
        assert np.allclose(inertia, inertia.T)
        drawn.append(inertia)
    assert np.array_equal(env.model.params.inertia_kg_m2, nominal)
    assert not np.allclose(drawn[0], nominal) and not np.allclose(drawn[0], drawn[1])
    _, info = env.reset(seed=0)
    assert np.array_equal(info["truth"]["true_inertia_kg_m2"], drawn[0])
    fixed = np.diag([5.0, 4.0, 3.0])
    env = gym.make("attitude_envs/ReactionWheel-v0", inertia_uncertainty={"kind": "fixed", "inertia_kg_m2": fixed})
    assert np.array_equal(env.reset(seed=0)[1]["truth"]["true_inertia_kg_m2"], fixed)


def test_episode_cost_does_not_depend_on_control_period():
    costs = []
    for dt in (0.1, 0.05):
        env = gym.make("attitude_envs/ReactionWheel-v0", control_dt_s=dt, integrator_dt_s=0.05).unwrapped
        env.reset(seed=0, options={"rate_rad_s": [0.01, -0.02, 0.015], "target_attitude": [0.1, 0, 0, np.sqrt(0.99)]})
        total, done = 0.0, False
        while not done:
            _, reward, term, trunc, info = env.step(np.zeros(4))
            total -= reward
            done = term or trunc
        assert info["time_s"] == pytest.approx(60.0)
        costs.append(total)
    assert costs[0] == pytest.approx(costs[1], rel=1e-12)


def test_truncation_on_time_and_termination_on_tumbling():
    env = gym.make("attitude_envs/ReactionWheel-v0", episode_duration_s=1.0).unwrapped
    env.reset(seed=0)
    flags = [env.step(np.zeros(4))[2:4] for _ in range(10)]
    assert flags[-1] == (False, True) and all(f == (False, False) for f in flags[:-1])
    env = gym.make("attitude_envs/ReactionWheel-v0", max_rate_rad_s=0.1).unwrapped
    env.reset(seed=0, options={"rate_rad_s": [0.0, 0.0, 0.0]})
    terminated = False
    for _ in range(200):
        _, _, terminated, truncated, _ = env.step(np.ones(4))
        if terminated:
            break
    assert terminated and not truncated


def test_linear_system_step_is_exactly_the_model():
    env = gym.make("attitude_envs/LinearSystem-v0").unwrapped
    A, B = env.model.A, env.model.B
    # Heravi & Novinzadeh 2017, eqs. 59, 61–62, 71: forward Euler, Δt = 0.01 s, J = diag(1000, 1000, 800)
    assert A[0, 3] == pytest.approx(0.005) and B[5, 2] == pytest.approx(1.25e-5) and B[3, 0] == pytest.approx(1e-5)
    obs, info = env.reset(seed=0)
    assert np.allclose(obs, [0.372897, -0.433710, 0.665744, 0.01, -0.02, 0.01], atol=1e-6)
    x = info["truth"]["state"]
    _, reward, _, _, info = env.step(np.array([0.25, -0.5, 0.1]))
    u = np.array([0.5, -1.0, 0.2])
    assert np.allclose(info["truth"]["applied"], u) and np.array_equal(info["commanded"], info["truth"]["applied"])
    assert np.array_equal(info["truth"]["previous_state"], x)  # the state the step started from
    assert np.allclose(info["truth"]["state"], A @ x + B @ u, rtol=1e-15)
    assert reward == pytest.approx(-(x @ x + u @ u))
    # the DARE gain of the preset (the reference K* of our Heravi & Novinzadeh 2017 reproduction)
    K = env.model.lqr_gain()
    assert np.allclose(np.diag(K[:, :3]), [0.999842, 0.999842, 0.999823], atol=1e-6)
    assert np.allclose(np.diag(K[:, 3:]), [31.638579, 31.638579, 28.301937], atol=1e-5)


def test_linear_system_terminates_on_divergence():
    env = gym.make(
        "attitude_envs/LinearSystem-v0",
        preset=None,
        A=[[2.0]],
        B=[[1.0]],
        x0_std=0.0,
        x0_mean=[1.0],
        divergence_threshold=100.0,
    )
    env.reset(seed=0)
    steps = 0
    terminated = False
    while not terminated:
        _, _, terminated, truncated, _ = env.step(np.zeros(1))
        steps += 1
    assert steps == 7 and not truncated  # 2**7 = 128 > 100


# ---------------------------------------------------------------- episode order
ENV_IDS = sorted(attitude_envs.ENV_IDS)
# episodes truncated (by the env itself: no TimeLimit wrapper) on the third step
TRUNCATE_AT_3 = {
    "attitude_envs/ReactionWheel-v0": {"episode_duration_s": 0.3},  # control period 0.1 s
    "attitude_envs/AirBearing-v0": {"episode_duration_s": 0.03},  # 0.01 s
    "attitude_envs/LinearSystem-v0": {"episode_steps": 3},
    "attitude_envs/FuelSlosh-v0": {"episode_duration_s": 0.3},  # 0.1 s
    "attitude_envs/Magnetorquer-v0": {"episode_duration_s": 0.3},  # 0.1 s
}
# a limit crossed on the first step: (keywords, reset options)
TERMINATE_AT_1 = {
    "attitude_envs/ReactionWheel-v0": ({"max_rate_rad_s": 1e-3}, {"rate_rad_s": [0.01, 0.0, 0.0]}),
    "attitude_envs/AirBearing-v0": ({"max_rate_rad_s": 1e-3}, {"rate_rad_s": [0.01, 0.0, 0.0]}),
    "attitude_envs/LinearSystem-v0": ({"divergence_threshold": 1e-6}, None),
    "attitude_envs/FuelSlosh-v0": ({"max_pitch_rate_rad_s": 1e-6}, None),
    "attitude_envs/Magnetorquer-v0": ({"max_rate_rad_s": 1e-3}, {"rate_rad_s": [0.01, 0.0, 0.0]}),
}
AFTER_DONE = "You are calling 'step()' even though this environment has already returned {} = True"


def test_every_env_id_has_an_episode_order_case():
    assert set(TRUNCATE_AT_3) == set(TERMINATE_AT_1) == set(ENV_IDS)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_step_before_reset_raises_reset_needed(env_id):
    wrapped = gym.make(env_id)
    env = wrapped.unwrapped  # the raw class, without gymnasium's OrderEnforcing wrapper
    action = np.zeros(env.action_space.shape, np.float32)
    for stepper in (env, wrapped):
        with pytest.raises(gym.error.ResetNeeded, match=r"Cannot call env\.step\(\) before calling env\.reset\(\)"):
            stepper.step(action)
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(seed=0, options={"no_such_option": 1})
    with pytest.raises(gym.error.ResetNeeded, match="call reset"):  # a reset that failed started nothing
        env.step(action)
    env.reset(seed=0)
    env.step(action)


def _after_done_warnings(env, action, steps: int) -> list[str]:
    """The after-done warnings of ``steps`` steps (every one recorded, none filtered)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(steps):
            env.step(action)
    return [str(w.message) for w in caught if "even though this environment has already returned" in str(w.message)]


def _run_to_end(env, action, options=None, max_steps: int = 10) -> tuple[bool, bool]:
    """Reset and step until the episode ends; no after-done warning on the way."""
    env.reset(seed=0, options=options)
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*even though this environment has already returned")
        for _ in range(max_steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                return terminated, truncated
    raise AssertionError(f"the episode did not end within {max_steps} steps")


# the limits crossed on purpose put the observation beyond its bounds (gymnasium's checker says so)
@pytest.mark.filterwarnings("ignore:.*not within the observation space")
@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("end", ["terminated", "truncated"])
def test_stepping_after_the_end_warns_once_per_episode(env_id, end):
    if end == "truncated":
        kwargs, options = TRUNCATE_AT_3[env_id], None
    else:
        kwargs, options = TERMINATE_AT_1[env_id]
    env = gym.make(env_id, **kwargs).unwrapped
    action = np.full(env.action_space.shape, 0.5 if end == "terminated" else 0.0, np.float32)
    for _ in range(2):  # once per episode: again after the next reset
        terminated, truncated = _run_to_end(env, action, options)
        assert (terminated, truncated) == (end == "terminated", end == "truncated")
        with pytest.warns(UserWarning, match=re.escape(AFTER_DONE.format(end))):
            env.step(action)  # the step still runs (as CartPole-v1's)
        assert _after_done_warnings(env, action, 3) == []  # not again in this episode
    # through gym.make (OrderEnforcing, PassiveEnvChecker) the env's own guard warns the same
    wrapped = gym.make(env_id, **kwargs)
    _run_to_end(wrapped, action, options)
    messages = _after_done_warnings(wrapped, action, 3)
    assert len(messages) == 1 and AFTER_DONE.format(end) in messages[0]
    assert "You should always call 'reset()'" in messages[0]
