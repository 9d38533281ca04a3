"""The JAX Magnetorquer plant (:mod:`attitude_envs.jax.magnetorquer`) against the numba env.

Equality: each configuration's numba env is reset with a seed, the JAX state built from it
(``state_from``), and both stepped with the same random actions; with ``jax_enable_x64`` the
physical state, reward, cost and the end flags agree at every step to 1e-12 (relative to
max(1, |x|) for the state) and the observations to the float32 rounding of the numba env's.
The configurations of one observation layout and sub-step count run as lanes of one
``jax.vmap`` (one compiled program per group): Magnetorquer-v1 (30 decisions of 10 s, the
whole episode) and Magnetorquer-v0 (0.1 s steps, the first 600), each with the paper's
faults (preset ``sadigh-2022-faults``, eq. 40 from t = 50 s), a rate-limit crossing (the
termination charge, ``"episode"`` and ``"hold"``) and the other modeled options.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from attitude_envs import quaternion
from attitude_envs.jax import faults as jfaults
from attitude_envs.jax import magnetorquer as mt
from attitude_envs.jax.make import make, numba_env
from attitude_envs.plants import magnetorquer_kernels as K

V1 = "attitude_envs/Magnetorquer-v1"
V0 = "attitude_envs/Magnetorquer-v0"
RTOL = 1e-12
# XLA:CPU compiles these programs ~2.5x faster without its fusion emitters (the results agree
# with the default build's to an ulp); only the test's own jits take the option
FAST_COMPILE = {"xla_cpu_use_fusion_emitters": False}
# the float32 API checks are loose: there LLVM's optimizations are skipped too (~3x faster again)
FASTER_COMPILE = {**FAST_COMPILE, "xla_backend_optimization_level": 0}
# Magnetorquer-v1 lanes: the registered task, the paper's faults, a rate-limit crossing charged
# T·xᵀQx, and the other options the JAX plant models (orbit, field, disturbance, inertia,
# reference, cost and fault variants)
V1_LANES = [
    ({}, 0),
    ({"preset": "sadigh-2022-faults"}, 1),
    ({"task": "regulation", "initial_rate_max_rad_s": 1e-3, "max_rate_rad_s": 2e-3}, 2),
    (
        {
            "orbit": {"model": "circular", "mean_anomaly_deg": 30.0},
            "field_model": "dipole-printed",
            "gravity_gradient": True,
            "disturbance_second_harmonic": True,
            "disturbance_scale": 3.0,
            "inertia_uncertainty": {"kind": "random", "moment_scale": 0.05, "axis_angle_deg": 5.0},
            "max_wheel_momentum_nms": 2e-3,  # the momentum limit blocks the wheel torque
            "Q": np.diag([1.0, 2.0, 3.0, 1e3, 2e3, 3e3]) + 0.1 * np.ones((6, 6)),
            "faults": [
                {"kind": "stuck", "index": 0, "onset_s": 20.0, "duration_s": 100.0},
                {"kind": "saturation", "index": 3, "value": 0.5, "onset_s": 0.0},
                {"kind": "effectiveness", "index": 1, "schedule": [[0.0, 1.0], [100.0, 0.5], [200.0, 0.2]]},
            ],
        },
        3,
    ),
    (
        {
            "task": "regulation",
            "target_euler_deg": (5.0, -10.0, 20.0),
            "initial_angle_deg": 30.0,
            "initial_rate_max_rad_s": 2e-3,
            "max_rate_rad_s": 5e-3,
            "termination_cost": "hold",
            "time_varying_inertia": None,
            "inertia_uncertainty": {"kind": "fixed", "inertia_kg_m2": np.diag([0.9, 1.0, 1.1])},
            "disturbance": {"kind": "sinusoidal", "amplitude_nm": [1e-5, 2e-5, 3e-5], "phase_rad": "random"},
            "faults": [
                {"kind": "bias", "index": 3, "value": 1e-4, "onset_s": 30.0},
                {"kind": "drift", "index": 2, "value": 1e-3, "onset_s": 10.0, "duration_s": 150.0},
                {"kind": "outage", "index": 1, "onset_s": 100.0, "duration_s": 60.0},
            ],
        },
        4,
    ),
    (
        {
            "reference": {"delta_deg": [-20.0, 5.0, 15.0], "t_final_s": 200.0},  # ends within the episode
            "disturbance": {"kind": "constant", "torque_nm": [1e-6, -2e-6, 5e-7]},
            "orbit": {"mean_anomaly_deg": 200.0, "raan_deg": 40.0, "arg_perigee_deg": 10.0},
            "R": np.array([[1e4, 1e3, 0.0], [1e3, 2e4, 0.0], [0.0, 0.0, 5e3]]),
            "faults": [{"kind": "loss_of_effectiveness", "index": "all", "value": 0.5, "onset_s": 60.0}],
        },
        5,
    ),
]
# Magnetorquer-v0 lanes (first 600 steps of 0.1 s): the paper's problem, its faults (onset 50 s)
# and a rate-limit crossing charged (T − t)·xᵀQx
V0_LANES = [
    ({}, 0),
    ({"preset": "sadigh-2022-faults"}, 1),
    ({"task": "regulation", "initial_rate_max_rad_s": 1e-4, "max_rate_rad_s": 1.1e-4}, 2),
]


def _numba_episode(env, seed: int, n_steps: int) -> dict:
    """Step the numba env (just reset with ``seed``) with random actions until the episode
    ends or ``n_steps``: what the JAX plant must reproduce."""
    actions = np.random.default_rng(1000 + seed).uniform(-1.0, 1.0, (n_steps, 4))
    rec = {k: [] for k in ("y", "obs", "reward", "cost", "terminated", "truncated")}
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        for k, v in zip(rec, (env.state_row.copy(), obs, reward, info["cost"], terminated, truncated), strict=True):
            rec[k].append(v)
        if terminated or truncated:
            break
    return {"env": env, "actions": actions, **{k: np.array(v) for k, v in rec.items()}}


def _stack(trees):
    """Stack pytrees along a new leading axis (in numpy: no eager JAX op to compile)."""
    return jax.tree.map(lambda *xs: jnp.asarray(np.stack([np.asarray(x) for x in xs])), *trees)


@partial(jax.jit, static_argnums=0, compiler_options=FAST_COMPILE)
def _rollout(env: mt.MagnetorquerEnv, state: mt.EnvState, actions: jax.Array, params: mt.EnvParams):
    """Per lane: the reset observation and every step's ``[q, ω_bo, Ω]``, observation,
    reward, cost and end flags (``step_env`` in a scan, lanes vmapped)."""

    def lane(state, actions, params):
        def body(s, a):
            obs, s, reward, terminated, info = env.step_env(jax.random.PRNGKey(0), s, a, params)
            truncated = env.is_truncated(s, params) & ~terminated
            y = jnp.concatenate([s.attitude, s.rate_rad_s, s.wheel_speed_rad_s])
            return s, (y, obs, reward, info["cost"], terminated, truncated)

        return env.observation(state, params), jax.lax.scan(body, state, actions)[1]

    return jax.vmap(lane)(state, actions, params)


def _run_group(env_id: str, lanes: list, n_steps: int) -> list[dict]:
    """The numba episodes of ``lanes`` and the JAX rollouts of the same, one vmapped program
    (faults padded to a common count). Call under the dtype setting to check."""
    numba_envs = [numba_env(env_id, **kw) for kw, _ in lanes]
    built = [make(env_id, **kw) for kw, _ in lanes]
    n_faults = max(env.n_faults for env, _ in built)
    first, _ = built[0]
    group = mt.MagnetorquerEnv(  # one static layout for the lanes, faults padded to n_faults
        built[0][1].replace(faults=jfaults.no_faults(n_faults)),
        n_substeps=first.n_substeps,
        observe_field=first.observe_field,
        fault_hint=first.fault_hint,
        obs_low=first.obs_low,
        obs_high=first.obs_high,
    )
    states, params, episodes = [], [], []
    for ne, (env, p), (_, seed) in zip(numba_envs, built, lanes, strict=True):
        assert not env.redraw_faults
        assert (env.n_substeps, env.observe_field, env.fault_hint) == (
            group.n_substeps,
            group.observe_field,
            group.fault_hint,
        )
        obs0, _ = ne.reset(seed=seed)
        states.append(group.state_from(ne))
        params.append(p.replace(faults=jfaults.from_realized(ne.fault_layer.realized, n_faults)))
        episodes.append({"obs0": obs0, **_numba_episode(ne, seed, n_steps)})
    actions = jnp.asarray(np.stack([e["actions"] for e in episodes]))
    obs0, (y, obs, reward, cost, terminated, truncated) = _rollout(group, _stack(states), actions, _stack(params))
    out = []
    for i, e in enumerate(episodes):
        k = len(e["reward"])
        jax_rec = {"obs0": obs0[i], "y": y[i, :k], "obs": obs[i, :k], "reward": reward[i, :k], "cost": cost[i, :k]}
        jax_rec |= {"terminated": terminated[i, :k], "truncated": truncated[i, :k]}
        out.append({"numba": e, "jax": {key: np.asarray(v) for key, v in jax_rec.items()}})
    return out


def _errors(lane: dict) -> dict[str, float]:
    """Max relative errors of one lane: state (to max(1, |x|)), reward and cost (to |x|),
    observations (to max(1, |x|), float32 numba values)."""
    n, j = lane["numba"], lane["jax"]

    def rel(a, b, floor):
        return float(np.max(np.abs(a - b) / np.maximum(floor, np.abs(b))))

    return {
        "state": rel(j["y"], n["y"], 1.0),
        "reward": rel(j["reward"], n["reward"], 1e-300),
        "cost": rel(j["cost"], n["cost"], 1e-300),
        "obs": max(rel(j["obs"], n["obs"], 1.0), rel(j["obs0"], n["obs0"], 1.0)),
    }


def _check_x64(lanes: list[dict]) -> None:
    for lane in lanes:
        n, j = lane["numba"], lane["jax"]
        err = _errors(lane)
        assert err["state"] <= RTOL and err["reward"] <= RTOL and err["cost"] <= RTOL, err
        np.testing.assert_array_equal(j["terminated"], n["terminated"])
        np.testing.assert_array_equal(j["truncated"], n["truncated"])
        for mine, theirs in ((j["obs"], n["obs"]), (j["obs0"][None], n["obs0"][None])):
            assert theirs.dtype == np.float32 and mine.dtype == np.float64
            # the numba env rounds to float32: half an ulp, plus the float64 difference
            np.testing.assert_allclose(mine, theirs, rtol=2.0**-24, atol=1e-11)


def _charged(lane: dict) -> tuple[float, float]:
    """The cost of a terminated lane's last step and the charge in it, ``T·xᵀQx`` (``"episode"``)
    or ``(T − t)·xᵀQx`` (``"hold"``), from the numba env's public state."""
    env = lane["numba"]["env"]
    x = env.error_state()
    held = (
        env.episode_duration_s
        if env.termination_cost == "episode"
        else env.episode_duration_s - env.steps_taken * env.control_dt_s
    )
    return float(lane["numba"]["cost"][-1]), float(x @ env.model.cost.Q @ x) * held


def test_v1_episodes_equal_numba():
    with jax.enable_x64(True):
        lanes = _run_group(V1, V1_LANES, 30)
    _check_x64(lanes)
    ends = [(bool(ln["numba"]["terminated"][-1]), bool(ln["numba"]["truncated"][-1])) for ln in lanes]
    assert ends[0] == ends[1] == (False, True) and len(lanes[0]["numba"]["reward"]) == 30  # whole episodes
    assert ends[2] == (True, False)  # the rate limit, charged T·xᵀQx
    cost, charge = _charged(lanes[2])
    assert 0.5 * cost < charge < cost


def test_v0_steps_equal_numba():
    with jax.enable_x64(True):
        lanes = _run_group(V0, V0_LANES, 600)
    _check_x64(lanes)
    assert [len(ln["numba"]["reward"]) for ln in lanes[:2]] == [600, 600]  # past the faults' onset at 50 s
    assert bool(lanes[2]["numba"]["terminated"][-1])  # the rate limit, charged (T − t)·xᵀQx
    cost, charge = _charged(lanes[2])
    assert 0.5 * cost < charge < cost


# ----------------------------------------------------------------------------- gymnax API
# A short task (3 decisions of 10 s, one sub-step each) with every per-episode draw: regulation
# start, orbit phase, inertia dispersion, sinusoid phases, a fault drawn per episode (random
# index and value) and a wheel outage from 10 s with its fault-hint flag (observation index 13).
API_KWARGS = {
    "integrator_dt_s": 10.0,
    "episode_duration_s": 30.0,
    "fault_hint": True,
    "task": "regulation",
    "initial_angle_deg": 20.0,
    "initial_rate_max_rad_s": 1e-3,
    "inertia_uncertainty": {"kind": "random", "moment_scale": 0.1, "axis_angle_deg": 10.0},
    "disturbance": {"kind": "sinusoidal", "amplitude_nm": [1e-5, 1e-5, 1e-5], "phase_rad": "random"},
    "faults": [
        {"kind": "outage", "index": 3, "onset_s": 10.0},
        {"kind": "bias", "index": "random", "value": {"uniform": [-0.2, 0.2]}, "onset_s": 5.0},
    ],
}
DIPOLES = (0.5, 0.1)  # the two lanes' max_dipole_am2: vmap over params


@pytest.fixture(scope="module")
def api():
    """The JAX env of ``API_KWARGS`` (default dtype), its params for the two lanes, numba envs
    of the same and the jitted, 2-lane vmapped ``reset`` and ``step``."""
    numba_envs = [numba_env(V1, max_dipole_am2=d, **API_KWARGS) for d in DIPOLES]
    env, _ = make(V1, max_dipole_am2=DIPOLES[0], **API_KWARGS)
    params = _stack([make(V1, max_dipole_am2=d, **API_KWARGS)[1] for d in DIPOLES])
    reset = jax.jit(jax.vmap(env.reset), compiler_options=FASTER_COMPILE)
    step = jax.jit(jax.vmap(env.step), compiler_options=FASTER_COMPILE)
    return env, params, numba_envs, reset, step


def test_gymnax_api_autoreset_and_vmap(api):
    """reset/step shapes, the autoreset at truncation with ``final_observation``, vmap over
    keys and over params (two dipole limits), the fault-hint flags; in float32 the whole
    episode (3 decisions) stays near the numba env's (loose bounds: the measured error is
    in the report)."""
    env, params, numba_envs, reset, step = api
    assert env.redraw_faults and env.n_faults == 2
    assert env.num_actions == 4 and env.action_space(params).shape == (4,)
    assert env.observation_space(params).shape == (18,)  # 7 + field 3 + 8 flags
    np.testing.assert_array_equal(np.asarray(params.max_steps_in_episode), [3, 3])
    obs, state = reset(jax.random.split(jax.random.PRNGKey(3), 2), params)
    assert obs.shape == (2, 18) and obs.dtype == jnp.float32 and state.time.shape == (2,)
    assert float(state.mean_anomaly0_rad[0]) != float(state.mean_anomaly0_rad[1])  # per-key orbit starts
    # the same episodes as the numba envs: start from their reset states
    for seed, ne in enumerate(numba_envs):
        ne.reset(seed=seed)
    state = _stack([env.state_from(ne) for ne in numba_envs])
    actions = np.random.default_rng(7).uniform(-1.0, 1.0, (3, 2, 4))
    step_keys = jax.random.split(jax.random.PRNGKey(4), (3, 2))
    rows = []
    for a, keys in zip(actions, step_keys, strict=True):
        obs, state, reward, terminated, truncated, info = step(keys, state, jnp.asarray(a, jnp.float32), params)
        rows.append((obs, state, reward, terminated, truncated, info))
    obs, states, reward, terminated, truncated, info = (_stack([r[i] for r in rows]) for i in range(6))
    assert obs.shape == (3, 2, 18) and reward.shape == (3, 2) and obs.dtype == jnp.float32
    assert not bool(terminated.any())
    np.testing.assert_array_equal(np.asarray(truncated), [[False, False], [False, False], [True, True]])
    np.testing.assert_array_equal(np.asarray(states.time), [[1, 1], [2, 2], [0, 0]])  # fresh after the limit
    np.testing.assert_allclose(np.asarray(info["time_s"][:, 0]), [10.0, 20.0, 30.0])
    final = np.asarray(info["final_observation"])
    assert np.all(final[1:, :, 13] == 1.0) and np.all(np.asarray(obs[2])[:, 13] == 0.0)  # wheel outage flag
    fresh, _ = reset(jax.vmap(lambda k: jax.random.split(k)[1])(step_keys[2]), params)
    np.testing.assert_array_equal(np.asarray(obs[2]), np.asarray(fresh))  # the step key's reset half
    assert not np.array_equal(final[2], np.asarray(fresh))
    # vmap over params: the first decision's dipoles scale with each lane's limit
    first = np.clip(actions[0, :, 0], -1.0, 1.0)
    np.testing.assert_allclose(np.asarray(info["applied"][0, :, 0]), first * np.array(DIPOLES), rtol=1e-6)
    # float32 against the numba envs over the whole episode
    for lane, ne in enumerate(numba_envs):
        ys, rewards, observations = [], [], []
        for a in actions[:, lane]:
            o, r, term, trunc, _ = ne.step(a)
            ys.append(ne.state_row.copy())
            rewards.append(r)
            observations.append(o)
        assert trunc and not term
        y = np.concatenate([states.attitude, states.rate_rad_s, states.wheel_speed_rad_s], axis=-1)[:2, lane]
        assert np.max(np.abs(y - ys[:2]) / np.maximum(1.0, np.abs(ys[:2]))) < 1e-4
        assert np.max(np.abs(np.asarray(reward[:, lane]) - rewards) / np.abs(rewards)) < 1e-2
        theirs = np.array(observations)
        mine = final[:, lane]  # each step's observation before the autoreset
        assert np.max(np.abs(mine - theirs) / np.maximum(1.0, np.abs(theirs))) < 1e-3


def test_reset_draws_follow_the_numba_law(api):
    """Regulation starts within ``initial_angle_deg`` of the target, rates uniform in
    ±``initial_rate_max_rad_s``, the orbit start uniform, the inertia dispersion, the
    sinusoid's random phases and the per-episode fault draws follow the numba env's laws
    (compared on their means over 400 draws each)."""
    env, params, numba_envs, reset, _ = api
    keys = jax.random.split(jax.random.PRNGKey(0), (200, 2))
    draws = [reset(k, params)[1] for k in keys]
    mine = jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *draws)
    ne = numba_envs[0]
    theirs = {k: [] for k in ("attitude", "rate", "anomaly", "phase", "inertia", "index", "value")}
    for seed in range(400):
        ne.reset(seed=seed)
        ep = np.asarray(ne.episode_constants)
        theirs["attitude"].append(ne.state_row[:4].copy())
        theirs["rate"].append(ne.state_row[4:7].copy())
        theirs["anomaly"].append(ep[K.EN_ORBIT + K.ORB_M0])
        theirs["phase"].append(ep[K.EN_DIST : K.EN_DIST + 3].copy())
        theirs["inertia"].append(ep[K.EN_INERTIA : K.EN_INERTIA + 9].reshape(3, 3))
        bias = ne.fault_layer.realized[1]
        theirs["index"].append(bias.index)
        theirs["value"].append(bias.value)
    theirs = {k: np.array(v) for k, v in theirs.items()}
    q_d = np.asarray(ne.model.reference.attitude(0.0)[0])

    def summary(attitude, rate, anomaly, phase, inertia, index, value):
        angles = [np.degrees(quaternion.error_angle_rad(q, q_d)) for q in attitude]
        return {
            "angle_max": np.max(angles),
            "angle_mean": np.mean(angles),
            "rate_max": np.max(np.abs(rate)),
            "rate_mean_abs": np.mean(np.abs(rate)),
            "anomaly_mean": np.mean(anomaly),
            "phase_mean": np.mean(phase),
            "moment_spread": np.std(np.linalg.eigvalsh(inertia)[:, 0]),
            "fault_index_mean": np.mean(index),
            "fault_value_abs": np.mean(np.abs(value)),
        }

    a = summary(
        mine.attitude,
        mine.rate_rad_s,
        mine.mean_anomaly0_rad,
        mine.disturbance,
        mine.inertia_kg_m2,
        mine.faults.index[:, 1],
        mine.faults.value[:, 1],
    )
    b = summary(*theirs.values())
    assert a["angle_max"] <= 20.0 + 1e-3 and a["rate_max"] <= 1e-3
    tolerances = {
        "angle_mean": 1.5,
        "rate_mean_abs": 5e-5,
        "anomaly_mean": 0.4,
        "phase_mean": 0.3,
        "moment_spread": 0.01,
        "fault_index_mean": 0.25,
        "fault_value_abs": 0.015,
    }
    for key, tol in tolerances.items():
        assert abs(a[key] - b[key]) < tol, (key, a[key], b[key])
    eff = mine.inertia_kg_m2.copy()
    eff[:, 1, 1] -= float(params.plant.wheel_inertia_kg_m2[0])
    np.testing.assert_allclose(mine.inertia_eff_inv, np.linalg.inv(eff), rtol=1e-4)


def test_random_walk_disturbance_increments():
    env, params = make("Magnetorquer-v1", disturbance={"kind": "random_walk", "std_nm_per_sqrt_s": 1e-6})
    assert env.random_walk
    start = jnp.asarray([1e-6, 0.0, -1e-6])
    keys = jax.random.split(jax.random.PRNGKey(1), 4000)
    advance = jax.jit(jax.vmap(env.advance_disturbance, in_axes=(0, None, None)), compiler_options=FASTER_COMPILE)
    walked = advance(keys, start, params)
    steps = np.asarray(walked - start) / (1e-6 * np.sqrt(10.0))  # σ √Δt per step
    assert abs(steps.mean()) < 0.05 and abs(steps.std() - 1.0) < 0.05


# ----------------------------------------------------------------------------- not modeled
@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"sensors": {"gyro": {"noise_std": 1e-5}}}, "sensors"),
        (
            {"faults": [{"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "value": 0.1}]},
            "flight conditions' sensors",
        ),
        ({"field_model": "igrf"}, "field_model"),
        (
            {"time_varying_inertia": {"amplitude_kg_m2": [0.9, 0.9, 0.9]}, "inertia_uncertainty": {"kind": "random"}},
            "inertia_uncertainty",
        ),
        ({"no_such_keyword": 1}, "no_such_keyword"),
    ],
)
def test_make_rejects_what_is_not_modeled(kwargs, named):
    with pytest.raises(ValueError, match=named):
        make("Magnetorquer-v1", **kwargs)


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        (V0, {}),
        (V1, {"conditions": "flight"}),
        (
            V0,
            {
                "task": "regulation",
                "orbit": {"mean_anomaly_deg": "random"},
                "inertia_uncertainty": {"kind": "random", "moment_scale": 0.1, "axis_angle_deg": 3.0},
                "time_varying_inertia": None,
                "disturbance": {"kind": "sinusoidal", "amplitude_nm": [1e-6, 2e-6, 1e-6], "period_s": 300.0},
                "gravity_gradient": True,
                "fault_hint": True,
            },
        ),
    ],
)
def test_standalone_params_are_the_numba_envs_numbers(env_id, kwargs, monkeypatch):
    """``make`` builds the params without a numba env: each leaf checked is the numba env's
    number, exactly (x64); the observation bounds are its; the groups default to Magnetorquer-v0's."""
    ne = numba_env(env_id, **kwargs)
    with jax.enable_x64(True):
        with monkeypatch.context() as m:  # no numba env may be built by make
            m.setattr(type(ne), "_use_layers", lambda *a, **k: pytest.fail("make built a numba env"))
            env, params = make(env_id, **kwargs)
        p, orbit = ne.model.params, ne.orbit
        expected = [
            (params.plant.inertia_kg_m2, p.inertia_kg_m2),
            (params.plant.inertia_eff_inv, p.inertia_eff_inv),
            (params.plant.max_dipole_am2, p.max_dipole_am2),
            (params.plant.max_wheel_momentum_nms, p.max_wheel_momentum_nms),
            (params.orbit.eccentricity, orbit.packed[K.ORB_E]),
            (params.orbit.semi_major_axis_m, orbit.packed[K.ORB_A]),
            (params.orbit.inclination_rad, orbit.inclination_rad),
            (params.field.dipole_strength_t_m3, ne.field.strength),
            (params.start.reference, ne.model.reference.packed),
            (params.timing.control_dt_s, ne.control_dt_s),
            (params.timing.integrator_dt_s, ne.integrator_dt_s),
            (params.cost.Q, ne.model.cost.Q),
            (params.cost.R, ne.model.cost.R),
            (params.cost.max_rate_rad_s, ne.max_rate_rad_s),
            (params.cost.horizon_s, ne.episode_duration_s),
            (params.start.initial_rate_max_rad_s, ne.reset_distribution["initial_rate_max_rad_s"]),
        ]
        for got, want in expected:
            assert got.dtype == jnp.float64
            np.testing.assert_array_equal(got, want)
        assert bool(params.start.regulation) == (ne.task == "regulation")
        assert bool(params.start.mean_anomaly_random) == (ne.reset_distribution["mean_anomaly_deg"] == "random")
        space = env.observation_space(params)
        np.testing.assert_array_equal(np.float32(space.low), ne.observation_space.low)
        np.testing.assert_array_equal(np.float32(space.high), ne.observation_space.high)
        assert (params.flight is None) == ne.conditions.is_lab
        default = mt.EnvParams()
        v0 = make(V0)[1]
        assert jax.tree.all(jax.tree.map(np.array_equal, default, v0))
