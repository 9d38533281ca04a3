"""The JAX gyrostat (:mod:`attitude_envs.jax.gyrostat`) against the numba ReactionWheel and
AirBearing envs, whole episodes under x64; its gymnax API; its "not modeled" errors."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
import jax.numpy as jnp  # noqa: E402

from attitude_envs.jax import gyrostat, make  # noqa: E402
from attitude_envs.jax.faults import KIND_CODES  # noqa: E402
from attitude_envs.jax.make import numba_env  # noqa: E402

#: fault entries the equality configs with faults are padded to (one compiled rollout per layout)
N_FAULTS = 4
TWO_WHEEL_FAILURE = [  # the two-wheel-failure scenario: wheels 0 and 1 out from t = 2 s
    {"kind": "outage", "index": 0, "onset_s": 2.0},
    {"kind": "outage", "index": 1, "onset_s": 2.0},
]
FAULT_MIX = [
    {"kind": "loss_of_effectiveness", "index": 0, "value": 0.4, "onset_s": 1.0},
    {"kind": "bias", "index": 2, "value": 0.05, "onset_s": 3.0, "duration_s": 10.0},
    {"kind": "stuck", "index": 1, "onset_s": 5.0},  # latches the command it sees at 5 s
]
AB_OPTIONS = {  # the layout options of the step and observation, on a short AirBearing-v0 run
    "episode_duration_s": 2.0,
    "observe_wheel_speeds": True,
    "fault_hint": True,
    "wheel_momentum_weight": 10.0,
    "cost_input": "wheel",
    "disturbance": {"kind": "constant", "torque_nm": [0.01, -0.02, 0.005]},
    "true_offset_torque_nm": [0.002, 0.0, 0.3],
    "faults": [
        {"kind": "saturation", "index": 0, "value": 0.3, "onset_s": 0.5},
        {"kind": "drift", "index": 1, "value": 0.2, "onset_s": 0.3, "duration_s": 1.0},
        {"kind": "effectiveness", "index": 2, "schedule": [[0.0, 1.0], [1.0, 0.2], [1.5, 0.6]]},
    ],
}
# id: (env id, keywords, seed, action scale, action bias, how the episode ends); actions are
# scale · U(−1.2, 1.2) + bias (beyond ±1 at scale 1: the clip is exercised)
CONFIGS = {
    "ReactionWheel-v1 two-wheel failure": (
        "ReactionWheel-v1",
        {"action_frame": "body", "faults": TWO_WHEEL_FAILURE},
        3,
        1.0,
        None,
        "truncated",
    ),
    "ReactionWheel-v0 fault mix, tumbles": (  # past every onset; "hold" charge at ~10 s
        "ReactionWheel-v0",
        {"action_frame": "body", "faults": FAULT_MIX, "max_rate_rad_s": 0.1},
        4,
        0.2,
        [0.1, 0.0, 0.0],
        "terminated",
    ),
    "AirBearing-v1": ("AirBearing-v1", {}, 5, 0.3, None, "truncated"),
    "AirBearing-v1 into the tilt stop": ("AirBearing-v1", {}, 6, 0.2, [1.0, 0.0, 0.0], "terminated"),
    "AirBearing-v0 options": ("AirBearing-v0", AB_OPTIONS, 7, 1.0, None, "truncated"),
}


def _row(state) -> jax.Array:
    return jnp.concatenate([state.attitude, state.rate_rad_s, state.wheel_speed_rad_s])


# XLA:CPU compiles these programs faster without its fusion emitters (this file: 29 s against
# 34 s; the results agree with the default build's to an ulp); only the test's own jits take
# the option
FAST_COMPILE = {"xla_cpu_use_fusion_emitters": False}


@partial(jax.jit, static_argnums=0, compiler_options=FAST_COMPILE)
def _rollout(env, state, actions, keys, params):
    """``step_env`` over ``actions``: per step the state row, observation, reward, cost,
    terminated, truncated and time (s)."""

    def body(s, xs):
        action, key = xs
        obs, s, reward, terminated, info = env.step_env(key, s, action, params)
        truncated = env.is_truncated(s, params) & ~terminated
        return s, (_row(s), obs, reward, info["cost"], terminated, truncated, info["time_s"])

    return jax.lax.scan(body, state, (actions, keys))[1]


def _numba_episode(env, actions):
    """The numba env stepped until the episode ends: the same outputs as :func:`_rollout`."""
    rows, obs, rewards, costs, terms, truncs, times = [], [], [], [], [], [], []
    for a in actions:
        o, r, terminated, truncated, info = env.step(a)
        rows.append(np.array(env.state_row))
        obs.append(o)
        rewards.append(r)
        costs.append(info["cost"])
        terms.append(terminated)
        truncs.append(truncated)
        times.append(info["time_s"])
        if terminated or truncated:
            break
    return [np.array(v) for v in (rows, obs, rewards, costs, terms, truncs, times)]


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.maximum(1.0, np.abs(np.asarray(b)))))


def _run_config(name: str):
    """Both plants over one whole episode: (numba outputs, JAX outputs, JAX reset obs,
    numba reset obs)."""
    env_id, kwargs, seed, scale, bias, _ = CONFIGS[name]
    ne = numba_env(env_id, **kwargs)
    obs0, _ = ne.reset(seed=seed)
    env, params = make(env_id, **kwargs)
    n_faults = N_FAULTS if kwargs.get("faults") else 0
    params = gyrostat.episode_params(ne, params, n_faults=n_faults)
    state = env.state_from(ne, n_faults=n_faults)
    steps = int(params.max_steps_in_episode)
    rng = np.random.default_rng(seed)
    actions = scale * rng.uniform(-1.2, 1.2, (steps, env.num_actions)) + (0.0 if bias is None else np.asarray(bias))
    ref = _numba_episode(ne, actions)
    keys = jax.random.split(jax.random.PRNGKey(seed), steps)
    out = [np.asarray(v) for v in _rollout(env, state, jnp.asarray(actions), keys, params)]
    return ref, out, np.asarray(env.get_obs(state, params)), obs0


def assert_same_episode(ref, out) -> int:
    """The JAX rollout ``out`` is the numba episode ``ref`` in x64: states, costs and rewards
    within 1e-12 relative, ends and times equal, observations equal to float32 rounding.
    Returns the episode's length."""
    rows, obs, rewards, costs, terms, truncs, times = ref
    k = len(rows)
    j_rows, j_obs, j_rewards, j_costs, j_terms, j_truncs, j_times = (v[:k] for v in out)
    assert j_rows.dtype == np.float64 and j_obs.dtype == np.float64
    assert _relative(j_rows, rows) <= 1e-12
    assert _relative(j_costs, costs) <= 1e-12
    assert _relative(j_rewards, rewards) <= 1e-12
    np.testing.assert_array_equal(j_terms, terms)
    np.testing.assert_array_equal(j_truncs, truncs)
    np.testing.assert_array_equal(j_times, times)
    # the numba env's float32 observations: the same values to float32 rounding
    np.testing.assert_allclose(j_obs.astype(np.float32), obs, rtol=2.0**-23, atol=1e-12)
    return k


@pytest.mark.parametrize("name", list(CONFIGS))
def test_whole_episode_equals_numba_env_under_x64(name):
    with jax.enable_x64(True):
        ref, out, jax_obs0, obs0 = _run_config(name)
    terms, truncs = ref[4], ref[5]
    ending = CONFIGS[name][-1]
    assert terms[-1] if ending == "terminated" else truncs[-1], f"the numba episode did not end {ending}"
    assert_same_episode(ref, out)
    np.testing.assert_allclose(jax_obs0.astype(np.float32), obs0, rtol=2.0**-23, atol=1e-12)


def test_float32_episode_follows_numba_env_loosely():
    """x64 off (the default): the same AirBearing-v1 episode to float32 accuracy."""
    ref, out, _, _ = _run_config("AirBearing-v1")
    assert out[0].dtype == np.float32
    assert _relative(out[0][: len(ref[0])], ref[0]) < 1e-3
    assert _relative(out[3][: len(ref[3])], ref[3]) < 1e-3


def test_gymnax_api_autoreset_and_vmap():
    """reset/step shapes, spaces, autoreset at the time limit, ``jax.vmap`` over keys and
    params (two inertias, through ``with_inertia``) and the start law, in one batch."""
    n = 256
    with jax.enable_x64(True):
        env, params = make("AirBearing-v1")
        obs, state = env.reset(jax.random.PRNGKey(0))  # the default params
        n_obs = env.observation_space(params).shape[0]
        assert bool(env.observation_space(params).contains(obs))
        action = env.action_space(params).sample(jax.random.PRNGKey(1))
        assert bool(env.action_space(params).contains(action))
        inertia = np.asarray(params.plant.inertia_kg_m2)
        inertias = jnp.asarray(np.stack([inertia] * (n // 2) + [2.0 * inertia] * (n // 2)))
        batch = jax.jit(jax.vmap(gyrostat.with_inertia, in_axes=(None, 0)))(params, inertias)
        keys = jax.random.split(jax.random.PRNGKey(2), n)
        states = jax.tree.map(lambda x: jnp.broadcast_to(x, (n, *x.shape)), state)  # one start for all
        actions = jnp.tile(action, (n, 1))
        step = jax.jit(jax.vmap(env.step), compiler_options=FAST_COMPILE)
        obs1, s1, reward, terminated, truncated, info = step(keys, states, actions, batch)
        last = states.replace(time=jnp.full(n, params.max_steps_in_episode - 1, dtype=states.time.dtype))
        obs2, starts, _, terminated2, truncated2, info2 = step(keys, last, actions, batch)
    assert (n_obs, env.num_actions, int(params.max_steps_in_episode)) == (6, 3, 40)
    assert obs.shape == (n_obs,) and obs.dtype == np.float64 and obs1.shape == (n, n_obs)
    assert int(state.time) == 0 and action.shape == (3,)
    np.testing.assert_allclose(batch.plant.inertia_eff_inv[0], params.plant.inertia_eff_inv, rtol=1e-12, atol=0)
    assert reward.shape == (n,) and info["cost"].shape == (n,)
    np.testing.assert_array_equal(reward, -info["cost"])
    assert not bool(terminated.any() | truncated.any()) and np.all(np.asarray(s1.time) == 1)
    rate = np.asarray(s1.rate_rad_s)  # the inertia alone sets the two halves apart
    np.testing.assert_array_equal(rate[: n // 2], np.tile(rate[0], (n // 2, 1)))
    assert np.abs(rate[0] - rate[-1]).max() > 1e-4
    # at the time limit: truncated, and fresh episodes with the last observation in info
    assert bool(truncated2.all()) and not bool(terminated2.any())
    np.testing.assert_allclose(info2["time_s"], 20.0, rtol=1e-15)
    np.testing.assert_array_equal(info2["final_observation"], obs1)  # the same step from the same state
    assert np.all(np.asarray(starts.time) == 0) and np.all(np.asarray(starts.wheel_speed_rad_s) == 0)
    assert np.abs(np.asarray(obs2) - np.asarray(obs1)).max() > 1e-3
    # the fresh episodes follow the start law: 3-2-1 angles uniform within (20°, 20°, 45°),
    # rates within 2°/s, target identity
    x, y, z, w = np.asarray(starts.attitude).T
    roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
    pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1, 1)))
    yaw = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    for angle, bound in ((roll, 20.0), (pitch, 20.0), (yaw, 45.0)):
        assert np.abs(angle).max() <= bound + 1e-9 and np.abs(angle).max() > 0.9 * bound
    rates = np.abs(np.asarray(starts.rate_rad_s))
    assert rates.max() <= np.radians(2.0) and rates.max() > 0.9 * np.radians(2.0)
    np.testing.assert_array_equal(np.asarray(starts.target_attitude), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))


#: the fault configs of the air-bearing campaign's ppo-fault-randomized agent
#: (experiments/campaigns/air-bearing.yml): one wheel, drawn per episode, out from a uniform onset
RANDOM_OUTAGE = [{"kind": "outage", "target": "actuator", "index": "random", "onset_s": {"uniform": [0.0, 10.0]}}]


def test_faults_drawn_per_episode_follow_their_law_and_step_as_the_numba_env():
    """AirBearing-v1 with a random wheel outage at a uniform onset: ``reset_env`` draws each
    episode's faults from its key (index in range, onset within the bounds, different per
    key), and an episode with the drawn faults steps as the numba env given those faults."""
    n = 64
    with jax.enable_x64(True):
        ne = numba_env("AirBearing-v1", faults=RANDOM_OUTAGE)
        env, params = make("AirBearing-v1", faults=RANDOM_OUTAGE)
        keys = jax.random.split(jax.random.PRNGKey(11), n)
        _, states = jax.jit(jax.vmap(env.reset_env, in_axes=(0, None)))(keys, params)
        # params padded to more entries: the drawn faults are padded to them (traced only)
        padded = gyrostat.episode_params(ne, params, n_faults=N_FAULTS)
        shapes = jax.eval_shape(env.reset_env, keys[0], padded)[1].faults
        j = int(np.argmin(np.asarray(states.faults.onset[:, 0])))  # the earliest outage
        state = jax.tree.map(lambda x: x[j], states)
        index, onset = int(state.faults.index[0]), float(state.faults.onset[0])
        ne.reset(
            seed=0,
            options={
                "faults": [{"kind": "outage", "index": index, "onset_s": onset}],
                "attitude": np.asarray(state.attitude),
                "rate_rad_s": np.asarray(state.rate_rad_s),
            },
        )
        given = env.state_from(ne).faults
        steps = int(params.max_steps_in_episode)
        actions = 0.3 * np.random.default_rng(5).uniform(-1.2, 1.2, (steps, env.num_actions))
        ref = _numba_episode(ne, actions)
        step_keys = jax.random.split(jax.random.PRNGKey(5), steps)
        out = [np.asarray(v) for v in _rollout(env, state, jnp.asarray(actions), step_keys, params)]
    assert env.redraw_faults and env.fault_configs == tuple(RANDOM_OUTAGE)
    assert env != make("AirBearing-v1")[0]  # its own compiled reset
    # the law: one outage per episode, on a wheel in range, from an onset within [0, 10] s
    kind, idx, on = (np.asarray(a) for a in (states.faults.kind, states.faults.index, states.faults.onset))
    assert kind.shape == (n, 1) and np.all(kind == KIND_CODES["outage"])
    assert set(idx[:, 0].tolist()) == {0, 1, 2}
    assert np.all((on >= 0.0) & (on <= 10.0)) and on.min() < 1.0 and on.max() > 9.0
    assert len(np.unique(on)) == n  # every key its own draw
    assert np.all(np.isinf(np.asarray(states.faults.end)))
    assert shapes.kind.shape == (N_FAULTS,) and shapes.onset.dtype == np.float64
    # the drawn faults are the numba env's realized ones given as options
    for name in ("kind", "index", "value", "onset", "end"):
        np.testing.assert_array_equal(getattr(given, name), getattr(state.faults, name))
    # the episode with them: as the numba env's, past the outage's onset
    assert ref[6][-1] > onset + 1.0  # past the outage's onset
    assert_same_episode(ref, out)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"sensors": {"gyro": {"noise_std": 1e-4}}}, "sensors"),
        ({"faults": [{"kind": "bias", "target": "sensor", "sensor": "gyro", "value": 0.1}]}, "sensor faults"),
        ({"disturbance": {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-3}}, "random_walk"),
        ({"inertia_uncertainty": {"kind": "random"}}, "inertia_uncertainty"),
        ({"render_mode": "rgb_array"}, "render_mode"),
    ],
)
def test_make_names_what_is_not_modeled(kwargs, named):
    with pytest.raises(ValueError, match=named.replace("[", r"\[")) as err:
        make("ReactionWheel-v1", **kwargs)
    assert "\n" not in str(err.value)


def test_fixed_inertia_uncertainty_is_the_plants():
    """A fixed ``inertia_uncertainty`` is the true plant's inertia, in the params from the start."""
    with jax.enable_x64(True):
        true = np.diag([5.0, 4.5, 3.5])
        uncertainty = {"kind": "fixed", "inertia_kg_m2": true}
        ne = numba_env("ReactionWheel-v0", inertia_uncertainty=uncertainty)
        _, params = make("ReactionWheel-v0", inertia_uncertainty=uncertainty)
        ne.reset(seed=0)
    np.testing.assert_array_equal(params.plant.inertia_kg_m2, true)
    np.testing.assert_array_equal(params.plant.inertia_eff_inv, np.asarray(ne.kernel_matrices[9:]).reshape(3, 3))


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("ReactionWheel-v0", {}),
        ("ReactionWheel-v0", {"preset": "pyramid-4wheel", "faults": TWO_WHEEL_FAILURE, "action_frame": "body"}),
        ("AirBearing-v1", {"true_offset_torque_nm": [0.0, 0.001, 0.0]}),
        ("ReactionWheel-v1", {"conditions": "flight"}),
    ],
)
def test_standalone_params_are_the_numba_envs_numbers(env_id, kwargs):
    """``make`` builds the params without a numba env: each leaf is the numba env's number,
    exactly (x64); the groups default to ReactionWheel-v0's."""
    with jax.enable_x64(True):
        ne = numba_env(env_id, **kwargs)
        env, params = make(env_id, **kwargs)
        plant, law = ne.model.params, ne.reset_distribution
        expected = [(getattr(params.plant, k), getattr(plant, k)) for k in ("wheel_axes", "max_wheel_torque_nm")]
        expected += [
            (params.plant.inertia_kg_m2, np.asarray(ne.kernel_matrices[:9]).reshape(3, 3)),
            (params.plant.inertia_eff_inv, np.asarray(ne.kernel_matrices[9:]).reshape(3, 3)),
            (params.plant.offset_torque_nm, ne.true_offset_torque_nm),
            (params.timing.control_dt_s, ne.control_dt_s),
            (params.timing.integrator_dt_s, ne.integrator_dt_s),
            (params.timing.episode_duration_s, ne.episode_duration_s),
            (params.cost.Q, ne.model.cost.Q),
            (params.cost.R, ne.model.cost.R),
            (params.cost.max_rate_rad_s, ne.max_rate_rad_s),
            (params.start.initial_angle_deg, law["initial_angle_deg"]),
            (params.start.target_angle_deg, law["target_angle_deg"]),
            (params.start.initial_rate_max_rad_s, law["initial_rate_max_rad_s"]),
        ]
        for got, want in expected:
            assert got.dtype == jnp.float64
            np.testing.assert_array_equal(got, want)
        assert env.n_substeps == ne.n_substeps and env.fault_configs == tuple(ne.fault_layer.configs)
        assert (env.flight is None) == ne.conditions.is_lab
        obs_high = np.asarray(env.observation_space(params).high, np.float32)
        np.testing.assert_array_equal(obs_high, ne.observation_space.high)
        default = gyrostat.EnvParams()
        v0 = make("ReactionWheel-v0")[1]
        assert jax.tree.all(jax.tree.map(np.array_equal, default, v0))
