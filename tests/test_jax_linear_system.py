"""The JAX LinearSystem plant (attitude_envs.jax.linear_system) against the numba env, and its
gymnax API. Equality runs under ``jax.enable_x64`` (a context, never the global config): the
same episodes step by step to 1e-12 relative (to max(1, |x|)), observations to float32
rounding."""

from __future__ import annotations

import copy

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from attitude_envs.jax import linear_system, make
from attitude_envs.jax.make import numba_env

TOL = 1e-12

FAULTS = [
    {"kind": "stuck", "index": 0, "onset_s": 100.0, "duration_s": 60.0},  # latches the command at 100 s
    {"kind": "loss_of_effectiveness", "index": 1, "value": {"uniform": [0.2, 0.6]}, "onset_s": 50.0},
    {"kind": "bias", "index": 2, "value": 0.3, "onset_s": 200.0, "duration_s": 100.0},
    {"kind": "saturation", "index": 2, "value": 0.5, "onset_s": {"uniform": [150.0, 250.0]}},
    {"kind": "drift", "index": 1, "value": 0.01, "onset_s": 300.0},
]


def _pair(env_id: str, **kwargs):
    """The numba env of ``env_id`` and the JAX plant and params ``make`` builds without it."""
    return (numba_env(env_id, **kwargs), *make(env_id, **kwargs))


def _rollout(env):
    """A jitted scan of ``env.step_env`` (no autoreset) over actions and keys: one compile."""

    def run(state, params, actions, keys):
        def body(s, inp):
            a, k = inp
            obs, s2, reward, terminated, info = env.step_env(k, s, a, params)
            truncated = env.is_truncated(s2, params) & ~terminated
            out = {
                "obs": obs,
                "x": s2.x,
                "reward": reward,
                "cost": info["cost"],
                "terminated": terminated,
                "truncated": truncated,
                "time_s": info["time_s"],
                "applied": info["applied"],
            }
            return s2, out

        return jax.lax.scan(body, state, (actions, keys))[1]

    return jax.jit(run)


def _keys(seed: int, n: int) -> np.ndarray:
    """``n`` legacy (uint32) PRNG keys made in numpy (no split program to compile)."""
    return np.random.default_rng(seed).integers(0, 2**32, (n, 2), dtype=np.uint32)


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(a))))


def _compare(ne, env, params, actions, seed: int, run=None) -> dict:
    """Reset ``ne`` with ``seed``, step it and the JAX plant with ``actions`` until the
    episode ends; assert equality at every step. Returns the steps taken, the end flags and
    the number of steps a fault changed the input."""
    ne.reset(seed=seed)
    state = env.state_from(ne)
    np.testing.assert_array_equal(np.asarray(state.x), ne.state)
    run = run or _rollout(env)
    keys = _keys(seed, len(actions))
    out = jax.tree.map(np.asarray, run(state, params, jnp.asarray(actions), keys))
    err_x = err_r = 0.0
    faulted = 0  # steps whose delivered input is not the command
    for i, a in enumerate(actions):
        obs, reward, terminated, truncated, info = ne.step(a)
        err_x = max(err_x, _rel(ne.state, out["x"][i]) if np.isfinite(ne.state).all() else 0.0)
        err_r = max(err_r, _rel(reward, out["reward"][i]), _rel(info["cost"], out["cost"][i]))
        assert err_x <= TOL and err_r <= TOL, (i, err_x, err_r)
        assert _rel(info["truth"]["applied"], out["applied"][i]) <= TOL, i
        faulted += not np.array_equal(info["truth"]["applied"], info["commanded"])
        assert info["time_s"] == pytest.approx(out["time_s"][i], rel=TOL)
        assert (bool(out["terminated"][i]), bool(out["truncated"][i])) == (terminated, truncated), i
        # the numba obs is the float32 of the same numbers: equal to float32 rounding (one ulp)
        assert obs.shape == out["obs"][i].shape
        assert np.all(np.abs(obs - out["obs"][i]) <= np.spacing(np.abs(obs))), i
        if terminated or truncated:
            return {"steps": i + 1, "terminated": terminated, "truncated": truncated, "faulted": faulted}
    return {"steps": len(actions), "terminated": False, "truncated": False, "faulted": faulted}


def test_v1_whole_episode_and_divergence_charge_match_numba():
    """LinearSystem-v1: an 80-decision episode (5 s exact holds of the 0.01 s model), then
    episodes with a divergence limit that the same program crosses (``"episode"`` charge)."""
    with jax.enable_x64(True):
        ne, env, params = _pair("LinearSystem-v1")
        assert (env.decision_steps, int(params.max_steps_in_episode)) == (500, 80)
        actions = np.random.default_rng(1).uniform(-1.2, 1.2, (80, 3)).astype(np.float32)
        run = _rollout(env)
        end = _compare(ne, env, params, actions, seed=3, run=run)
        assert end["steps"] == 80 and end["truncated"]
        # the same statics with another divergence limit: a new EnvParams, the same program
        ne_div, _, params_div = _pair("LinearSystem-v1", divergence_threshold=1.0)
        push = np.ones((80, 3), np.float32)
        end = _compare(ne_div, env, params_div, push, seed=4, run=run)
        assert end["terminated"] and 1 < end["steps"] < 80


def test_v1_actuator_faults_and_hint_match_numba():
    with jax.enable_x64(True):
        ne, env, params = _pair("LinearSystem-v1", faults=FAULTS, fault_hint=True)
        assert env.redraw_faults and env.n_faults == 5 and env.obs_size == 6 + 4
        actions = np.random.default_rng(2).uniform(-1, 1, (80, 3)).astype(np.float32)
        end = _compare(ne, env, params, actions, seed=5)
        assert end["steps"] == 80 and end["truncated"] and end["faulted"] > 60


def test_v0_whole_episode_with_faults_and_hold_charge_match_numba():
    """LinearSystem-v0 (k = 1, 1000 steps of 0.01 s) with actuator faults: a whole episode;
    then, the same program with another divergence limit, an episode that crosses it
    (``"hold"`` charge, ``(T − t) xᵀQx`` with t the plant steps elapsed)."""
    faults = [
        {"kind": "stuck", "index": 2, "onset_s": 0.5, "duration_s": 4.0},
        {"kind": "bias", "index": 0, "value": {"uniform": [0.5, 1.0]}, "onset_s": 0.2, "duration_s": 1.0},
    ]
    with jax.enable_x64(True):
        ne, env, params = _pair("LinearSystem-v0", faults=faults)
        assert env.decision_steps == 1 and int(params.max_steps_in_episode) == 1000
        run = _rollout(env)
        actions = np.random.default_rng(6).uniform(-1, 1, (1000, 3)).astype(np.float32)
        end = _compare(ne, env, params, actions, seed=7, run=run)
        assert end["steps"] == 1000 and end["truncated"] and end["faulted"] > 300

        ne_div, _, params_div = _pair("LinearSystem-v0", faults=faults, divergence_threshold=0.7)
        push = np.tile(np.float32([1.0, -1.0, 1.0]), (1000, 1))
        end = _compare(ne_div, env, params_div, push, seed=8, run=run)
        assert end["terminated"] and 10 < end["steps"] < 1000


def test_process_noise_fed_the_numba_draws_matches_and_keys_draw_the_same_law():
    """With process noise the k plant steps go one by one (``noisy_held_steps``): the JAX
    step fed the numba env's draws is the same trajectory; its own draws have the same law."""
    with jax.enable_x64(True):
        ne, env, params = _pair("LinearSystem-v0", process_noise_std=0.01, control_dt_s=0.05, episode_steps=100)
        assert env.noisy and env.decision_steps == 5
        ne.reset(seed=9)
        draws = copy.deepcopy(ne.np_random)  # the env's own generator, replayed
        actions = np.random.default_rng(10).uniform(-1, 1, (20, 3)).astype(np.float32)
        noise = np.stack([0.01 * draws.normal(size=(5, 6)) for _ in actions])
        step = jax.jit(env.plant_step)
        x, scale = jnp.asarray(ne.state), np.asarray(params.plant.action_scale)
        for a, w in zip(actions, noise, strict=True):
            _, reward, *_ = ne.step(a)
            x, cost = step(x, scale * a.astype(float), w, params)
            assert _rel(ne.state, x) <= TOL and _rel(-reward, cost) <= TOL

        # x⁺ − A_k x − B_k u = Σ_{i<k} Aⁱ w_{k−1−i}: zero mean, covariance σ² Σ Aⁱ Aⁱᵀ
        state = env.state_from(ne)
        zero = np.zeros(3)
        draw = jax.jit(lambda keys: jax.lax.map(lambda k: env.step_env(k, state, zero, params)[1].x, keys))
        x_next = draw(_keys(11, 4000))
        A, A_k = np.asarray(params.plant.A), np.asarray(params.hold.A_k)
        resid = np.asarray(x_next) - A_k @ np.asarray(state.x)
        cov = 0.01**2 * sum(np.linalg.matrix_power(A, i) @ np.linalg.matrix_power(A, i).T for i in range(5))
        np.testing.assert_allclose(resid.std(axis=0), np.sqrt(np.diag(cov)), rtol=0.06)
        assert np.all(np.abs(resid.mean(axis=0)) < 4 * np.sqrt(np.diag(cov) / 4000))


def test_gymnax_api_reset_step_autoreset_vmap_and_spaces():
    env, params = make("LinearSystem-v1")
    key = _keys(0, 1)[0]
    obs, state = env.reset(key, params)
    assert obs.shape == (6,) and obs.dtype == jnp.float32 and int(state.time) == 0
    a = np.float32([0.3, -1.0, 0.7])
    obs2, state2, reward, terminated, truncated, info = env.step(key, state, a, params)
    assert obs2.shape == (6,) and reward.shape == () and int(state2.time) == 1
    assert not bool(terminated) and not bool(truncated)
    assert {"cost", "time_s", "final_observation", "terminated", "truncated"} <= set(info)
    assert float(info["time_s"]) == pytest.approx(5.0) and float(reward) == pytest.approx(-float(info["cost"]))

    # autoreset: the last decision truncates and returns a fresh episode
    last = state2.replace(time=np.int32(int(params.max_steps_in_episode) - 1))
    obs3, state3, _, terminated, truncated, info = env.step(key, last, a, params)
    assert bool(truncated) and not bool(terminated) and int(state3.time) == 0
    np.testing.assert_allclose(state3.x, params.start.x0_mean)  # v1's episodes start at the paper's state
    np.testing.assert_allclose(obs3, params.start.x0_mean)
    expected = env.step(key, last.replace(time=np.int32(0)), a, params)[0]  # the same step, not the last
    np.testing.assert_allclose(info["final_observation"], expected, rtol=1e-6)
    assert not np.allclose(info["final_observation"], obs3)
    # a divergence terminates: autoreset too, the final observation is the diverged state
    far = params.replace(cost=params.cost.replace(divergence_threshold=np.float32(0.1)))
    _, state4, _, terminated, truncated, info = env.step(key, state, a, far)
    assert bool(terminated) and not bool(truncated) and int(state4.time) == 0
    assert np.abs(info["final_observation"]).max() > 0.1

    # spaces: a sample is in the action space, observations in the observation space
    action_space, obs_space = env.action_space(params), env.observation_space(params)
    sample = action_space.sample(key)
    assert sample.shape == (3,) and bool(action_space.contains(sample)) and env.num_actions == 3
    assert not bool(action_space.contains(2 * np.ones(3, np.float32)))

    # vmap over keys, states and params at once (one program): every episode at its last
    # decision, so each autoresets and its new observation is a fresh draw of the numba env's
    # law x0 ~ N(x0_mean, diag(x0_std²)); the params alternate two action scales
    x0_std = np.float32([0.5, 2.0, 0.0, 1e-3, 1e-3, 1e-3])
    wide = params.replace(start=params.start.replace(x0_std=x0_std))
    small = wide.replace(plant=wide.plant.replace(action_scale=np.asarray(params.plant.action_scale) / 2))
    size = 4000
    batch = jax.tree.map(lambda u, v: np.stack([np.asarray(u), np.asarray(v)] * (size // 2)), wide, small)
    keys = _keys(0, size)
    states = jax.tree.map(lambda leaf: np.repeat(np.asarray(leaf)[None], size, 0), last)
    actions = np.random.default_rng(0).uniform(-1, 1, (size, 3)).astype(np.float32)
    actions[:2] = a

    @jax.jit
    def batched(keys, states, actions, batch):
        out = jax.vmap(env.step)(keys, states, actions, batch)
        return out, jax.vmap(obs_space.contains)(out[5]["final_observation"])

    (obs_b, states_b, rewards, terminated, truncated, info), inside = batched(keys, states, actions, batch)
    assert obs_b.shape == (size, 6) and rewards.shape == (size,) and bool(inside.all())
    assert bool(truncated.all()) and not terminated.any() and not np.asarray(states_b.time).any()
    x0 = np.asarray(obs_b, float)
    np.testing.assert_allclose(x0.mean(0)[:3], np.asarray(params.start.x0_mean)[:3], atol=0.1)
    np.testing.assert_allclose(x0.std(0), x0_std, rtol=0.06, atol=1e-5)
    single = [env.step(keys[i], last, a, p)[2] for i, p in enumerate((wide, small))]
    np.testing.assert_allclose(rewards[:2], single, rtol=1e-6)
    assert rewards[0] != rewards[1]


def test_faults_redrawn_per_episode_from_the_configs():
    configs = [*FAULTS, {"kind": "outage", "index": "all", "onset_s": {"uniform": [10.0, 20.0]}}]
    env, params = make("LinearSystem-v1", faults=configs)
    reset = jax.jit(env.reset_env)
    states = [reset(k, params)[1] for k in _keys(1, 32)]
    loe = np.array([np.asarray(s.faults.value)[1] for s in states])
    assert np.all((loe >= 0.2) & (loe <= 0.6)) and loe.std() > 0.05
    onset = np.array([np.asarray(s.faults.onset)[5:] for s in states])  # "all": one onset per episode and dict
    assert onset.shape == (32, 3) and np.all((onset >= 10.0) & (onset <= 20.0)) and onset.std() > 1.0
    assert np.all(onset == onset[:, :1])
    # without draws every episode's faults are params.faults
    env_d, params_d = make("LinearSystem-v1", faults=[{"kind": "outage", "index": 1, "onset_s": 10.0}])
    assert not env_d.redraw_faults
    _, state_d = env_d.reset(_keys(2, 1)[0], params_d)
    assert jax.tree.all(jax.tree.map(np.array_equal, state_d.faults, params_d.faults))


def test_float32_fault_onset_switches_on_the_numba_step():
    """In float32 the product 20 · 0.01f rounds below 0.2f: the plant's decision time is
    the correctly rounded steps / 100, so a fault starting at 0.2 s acts from step 20 on."""
    ne, env, params = _pair("LinearSystem-v0", faults=[{"kind": "bias", "index": 0, "value": 0.5, "onset_s": 0.2}])
    ne.reset(seed=3)
    state, key = env.state_from(ne), _keys(3, 1)[0]
    step = jax.jit(env.step_env)
    zero = np.zeros(3, np.float32)
    applied = [float(step(key, state.replace(time=np.int32(t)), zero, params)[4]["applied"][0]) for t in (19, 20)]
    assert applied == [0.0, 0.5]


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"sensors": {"state": {"noise_std": 1e-3}}}, "sensors"),
        ({"faults": [{"kind": "bias", "target": "sensor", "sensor": "state", "index": 0, "value": 0.1}]}, "sensor"),
        ({"no_such_keyword": 1}, "no_such_keyword"),
    ],
)
def test_make_names_what_is_not_modeled(kwargs, name):
    with pytest.raises(ValueError, match=name):
        make("LinearSystem-v0", **kwargs)


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        ("LinearSystem-v0", {}),
        ("LinearSystem-v1", {"faults": FAULTS, "fault_hint": True}),
        ("LinearSystem-v0", {"process_noise_std": 0.01, "control_dt_s": 0.05, "episode_steps": 100}),
        ("LinearSystem-v0", {"A": [[1.0, 0.1], [0.0, 1.0]], "B": [[0.0], [0.1]], "x0_std": 0.5}),
    ],
)
def test_standalone_params_are_the_numba_envs_numbers(env_id, kwargs):
    """``make`` builds the params without a numba env: each leaf is the numba env's number,
    exactly (x64); the observation bound is the numba env's; the groups default to
    LinearSystem-v0's."""
    with jax.enable_x64(True):
        ne, env, params = _pair(env_id, **kwargs)
        held, law = ne.decision_model, ne.reset_distribution
        expected = [
            (params.plant.A, ne.model.A),
            (params.plant.B, ne.model.B),
            (params.plant.dt_s, ne.model.dt_s),
            (params.plant.action_scale, ne.action_scale),
            (params.hold.A_k, held.A),
            (params.hold.B_k, held.B),
            (params.hold.Q_k, held.Q),
            (params.hold.R_k, held.R),
            (params.cost.Q, ne.cost.Q),
            (params.cost.R, ne.cost.R),
            (params.cost.divergence_threshold, ne.divergence_threshold),
            (params.cost.horizon_steps, ne.episode_steps),
            (params.start.x0_mean, law["x0_mean"]),
            (params.start.x0_std, law["x0_std"]),
            (params.disturbance.process_noise_std, ne.process_noise_std),
            (params.max_steps_in_episode, ne.episode_steps // ne.decision_steps),
        ]
        for got, want in expected:
            assert got.dtype in (jnp.float64, jnp.int32)
            np.testing.assert_array_equal(got, want)
        assert env.obs_bound == ne.observation_space.high[0] and env.n_faults == len(ne.fault_layer.configs)
        default = linear_system.EnvParams()
        v0 = make("LinearSystem-v0")[1]
        assert jax.tree.all(jax.tree.map(np.array_equal, default, v0))
