"""The JAX gyrostat under flight conditions (:mod:`attitude_envs.conditions`) against the
numba ReactionWheel and AirBearing envs: the delay and the actuator chain step for step (x64,
whole episodes, the numba episode's drawn plant given to the JAX reset), the per-episode
parameter draws in distribution (two-sample Kolmogorov–Smirnov tests against the numba
env's draws), and what is not modeled (sensors or sensor faults outside flight conditions' sensors)
refused by name."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
scipy_stats = pytest.importorskip("scipy.stats")
import jax.numpy as jnp  # noqa: E402
from test_jax_gyrostat import FAST_COMPILE, _numba_episode, _relative, _rollout, assert_same_episode  # noqa: E402
from test_jax_magnetorquer import FASTER_COMPILE  # noqa: E402

from attitude_envs.actuator_dynamics import ActuatorChain, ActuatorModel  # noqa: E402
from attitude_envs.jax import actuators as jact  # noqa: E402
from attitude_envs.jax import gyrostat, make  # noqa: E402
from attitude_envs.jax.make import numba_env  # noqa: E402

NO_SENSORS = {"base": "flight", "sensors": 0}
N_FAULTS = 2
# id: (env id, keywords, seed, action scale, action bias); actions are
# scale · U(−1.2, 1.2) + bias
CONFIGS = {
    "ReactionWheel-v0 flight": ("ReactionWheel-v0", {"conditions": NO_SENSORS, "episode_duration_s": 6.0}, 3, 1.0),
    "ReactionWheel-v0 body frame, faults, 2-period delay": (
        "ReactionWheel-v0",
        {
            "conditions": {"base": "flight", "sensors": 0, "delay_steps": 2},
            "action_frame": "body",
            "episode_duration_s": 4.0,
            "faults": [
                {"kind": "loss_of_effectiveness", "index": 0, "value": 0.4, "onset_s": 1.0},
                {"kind": "stuck", "index": 1, "onset_s": 2.0},
            ],
        },
        4,
        1.0,
    ),
    "ReactionWheel-v1 delay only": ("ReactionWheel-v1", {"conditions": {"delay_steps": 3}}, 5, 1.0),
    "ReactionWheel-v1 parameters only": ("ReactionWheel-v1", {"conditions": {"parameters": 2.0}}, 6, 1.0),
    "AirBearing-v0 flight": ("AirBearing-v0", {"conditions": NO_SENSORS, "episode_duration_s": 4.0}, 7, 0.3),
    "AirBearing-v1 flight": ("AirBearing-v1", {"conditions": NO_SENSORS}, 8, 0.3),
    "AirBearing-v1 actuators only": ("AirBearing-v1", {"conditions": {"actuators": True}}, 9, 0.3),
}


def _flight_episode(name: str):
    """One numba flight episode and the JAX plant stepped from its start with its drawn plant
    (given to the JAX reset): (numba outputs, JAX outputs, JAX env, reset state, state_from state)."""
    env_id, kwargs, seed, scale = CONFIGS[name]
    ne = numba_env(env_id, **kwargs)
    env, params = make(env_id, **kwargs)
    ne.reset(seed=seed)
    n_faults = N_FAULTS if kwargs.get("faults") else 0
    params = gyrostat.episode_params(ne, params, n_faults=n_faults)
    if env.flight.draw_plant:
        params = gyrostat.with_drawn_parameters(params, ne.drawn_parameters())
    _, reset_state = env.reset(jax.random.PRNGKey(seed), params)
    state = env.state_from(ne, n_faults=n_faults)
    steps = int(params.max_steps_in_episode)
    rng = np.random.default_rng(seed)
    actions = scale * rng.uniform(-1.2, 1.2, (steps, env.num_actions))
    ref = _numba_episode(ne, actions)
    keys = jax.random.split(jax.random.PRNGKey(seed), steps)
    out = [np.asarray(v) for v in _rollout(env, state, jnp.asarray(actions), keys, params)]
    return ref, out, env, reset_state, state


@pytest.mark.parametrize("name", list(CONFIGS))
def test_flight_episode_equals_numba_env_under_x64(name):
    """The delay line, the actuator chain (resolution, lag as the period mean, gains, friction),
    the faults between them and the drawn true plant: a whole episode as the numba env's."""
    with jax.enable_x64(True):
        ref, out, env, reset_state, state = _flight_episode(name)
    assert ref[5][-1] or ref[4][-1]  # the numba episode ended
    assert_same_episode(ref, out)
    # the reset with the given draws holds the numba episode's plant and gains, bit for bit
    # (inertia_eff_inv computed with numpy as the numba plant computes it)
    for a, b in zip(jax.tree.leaves(reset_state.flight), jax.tree.leaves(state.flight), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the flight episode differs from the lab's: its commands act through the chain
    assert env.flight is not None


def test_the_lab_episode_is_not_the_flight_episode():
    """Sanity of the comparison above: the lab JAX plant stepped with the same actions from the
    same start leaves the flight numba episode (so the flight stages are what matched)."""
    with jax.enable_x64(True):
        ref, _, env, _, state = _flight_episode("AirBearing-v1 flight")
        lab_env, lab_params = make("AirBearing-v1")
        lab_state = lab_env.state_from(numba_env("AirBearing-v1"))
        lab_state = lab_state.replace(
            attitude=state.attitude, rate_rad_s=state.rate_rad_s, target_attitude=state.target_attitude
        )
        steps = len(ref[0])
        actions = 0.3 * np.random.default_rng(8).uniform(-1.2, 1.2, (int(lab_params.max_steps_in_episode), 3))
        keys = jax.random.split(jax.random.PRNGKey(8), len(actions))
        out = _rollout(lab_env, lab_state, jnp.asarray(actions), keys, lab_params)
    assert _relative(np.asarray(out[0])[:steps], ref[0]) > 1e-6


def _chain_model() -> ActuatorModel:
    """Every stage on, with per-actuator entries (one actuator without lag, one without
    resolution), a duty cycle and a rate limit."""
    return ActuatorModel.build(
        [0.5, 0.5, 0.2],
        lag_s=[0.03, 0.0, 0.1],
        resolution=[0.01, 0.0, 0.004],
        rate_limit=[2.0, np.inf, 1.0],
        duty=[1.0, 0.8, 0.9],
        coulomb=[1e-3, 0.0, 2e-3],
        viscous=[1e-5, 2e-5, 0.0],
    )


def test_actuator_chain_is_the_numba_chain_bit_for_bit():
    """:mod:`attitude_envs.jax.actuators` against :class:`ActuatorChain` on a model with every
    stage, a 2-period delay, gains, friction and ties of the resolution's rounding (half to
    even in both): op by op, bit for bit under x64."""
    model = _chain_model()
    dt = 0.1
    rng = np.random.default_rng(0)
    n_steps = 60
    commands = rng.uniform(-0.6, 0.6, (n_steps, 3))
    commands[5] = [0.005, 0.015, 0.002]  # exact halves of the resolution: round half to even
    commands[6] = [-0.025, 0.3, -0.006]
    speeds = rng.normal(0.0, 50.0, (n_steps, 3))
    speeds[3] = 0.0  # sign(0) = 0
    gain = np.array([1.03, 0.97, 1.01])
    chain = ActuatorChain(model, 2, dt)
    chain.reset(3, gain)
    ref = np.array([chain.deliver(c, lambda x: 0.9 * x, s) for c, s in zip(commands, speeds, strict=True)])
    with jax.enable_x64(True):
        layout = jact.layout_of(model, 2, True)
        p = jact.params_of(model, 3, dt, jnp.float64)
        state = jact.initial_state(layout, 3, jnp.float64)
        out = []
        with jax.disable_jit():
            for c, s in zip(commands, speeds, strict=True):
                cmd, state = jact.command(layout, p, state, jnp.asarray(c))
                y, state = jact.output(layout, p, state, 0.9 * cmd, jnp.asarray(gain), jnp.asarray(s))
                out.append(np.asarray(y))
    assert layout == jact.ActuatorLayout(2, True, True, True, True, True, True)
    np.testing.assert_array_equal(np.array(out), ref)


def _jax_draws(env_id: str, n: int, seed: int, conditions) -> dict:
    """``n`` episodes' drawn plants and gains from the JAX reset (vmapped over keys)."""
    with jax.enable_x64(True):
        env, params = make(env_id, conditions=conditions)
        keys = jax.random.split(jax.random.PRNGKey(seed), n)
        _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)(keys, params)
        f = states.flight
        return {
            "inertia_kg_m2": np.asarray(f.plant.inertia_kg_m2),
            "inertia_eff_inv": np.asarray(f.plant.inertia_eff_inv),
            "wheel_axes": np.asarray(f.plant.wheel_axes),
            "offset_torque_nm": np.asarray(f.plant.offset_torque_nm),
            "actuator_gain": np.asarray(f.gain),
            "attitude": np.asarray(states.attitude),
        }


def _numba_draws(env_id: str, n: int, conditions) -> dict:
    ne = numba_env(env_id, conditions=conditions)
    out: dict = {}
    for seed in range(n):
        ne.reset(seed=seed)
        for k, v in ne.drawn_parameters().items():
            out.setdefault(k, []).append(v)
    return {k: np.array(v) for k, v in out.items()}


def _statistics(draws: dict, nominal_axes: np.ndarray) -> dict:
    """Per draw: the sorted principal moments, the inertia's off-diagonal products, each
    wheel's misalignment angle (deg), the offset torque and the gains."""
    inertia = draws["inertia_kg_m2"]
    moments = np.linalg.eigvalsh(inertia)
    cos = np.clip(np.einsum("bkn,kn->bn", draws["wheel_axes"], nominal_axes), -1.0, 1.0)
    stats = {f"moment {i}": moments[:, i] for i in range(3)}
    stats |= {f"I[{i},{j}]": inertia[:, i, j] for i, j in ((0, 1), (0, 2), (1, 2))}
    stats["misalignment deg"] = np.degrees(np.arccos(cos)).ravel()
    stats |= {f"offset {i}": draws["offset_torque_nm"][:, i] for i in range(3)}
    stats["gain"] = draws["actuator_gain"].ravel()
    return stats


@pytest.mark.parametrize("env_id", ["AirBearing-v1", "ReactionWheel-v1"])
def test_parameter_draws_follow_the_numba_law(env_id):
    """2,000 JAX resets against 2,000 numba resets: the principal moments, the inertia's
    products, the wheels' misalignment angles, the offset torque and the motor gains have the
    same distributions (two-sample KS, p > 0.001) and stay within the cited tolerances."""
    n = 2000
    conditions = {"parameters": True}
    j = _jax_draws(env_id, n, 0, conditions)
    ne = numba_env(env_id, conditions=conditions)
    nominal = ne.model.params
    table = ne.flight_table
    ref = _numba_draws(env_id, n, conditions)
    stats_j = _statistics(j, nominal.wheel_axes)
    stats_n = _statistics(ref, nominal.wheel_axes)
    p_values = {}
    for key, values in stats_n.items():
        if np.ptp(values) == 0.0:  # not drawn (ReactionWheel's offset torque): the same constant
            np.testing.assert_array_equal(stats_j[key], values)
            continue
        p_values[key] = scipy_stats.ks_2samp(stats_j[key], values).pvalue
    assert min(p_values.values()) > 1e-3, p_values
    # the bounds: moments within the tolerance of the nominal (order statistics), misalignment
    # within its angle, gains and the offset within theirs
    tol = table.plant_value("inertia_moment")
    nominal_moments = np.sort(np.linalg.eigvalsh(nominal.inertia_kg_m2))
    moments = np.linalg.eigvalsh(j["inertia_kg_m2"])
    assert np.all(moments >= np.sort(nominal_moments * (1 - tol)) * (1 - 1e-12))
    assert np.all(moments <= np.sort(nominal_moments * (1 + tol)) * (1 + 1e-12))
    sorted_moments = np.sort(moments, axis=1)
    assert np.all(sorted_moments[:, 0] + sorted_moments[:, 1] >= sorted_moments[:, 2])
    mis = stats_j["misalignment deg"]
    bound = table.plant_value("wheel_misalignment_deg")
    assert mis.max() <= bound + 1e-9 and mis.max() > 0.95 * bound
    np.testing.assert_allclose(np.linalg.norm(j["wheel_axes"], axis=1), 1.0, rtol=1e-15)
    gain_tol = float(table.gain_tolerance.value)
    assert np.all(np.abs(j["actuator_gain"] - 1.0) <= gain_tol + 1e-15)
    base_offset = np.asarray(ne.true_offset_torque_nm)
    if "offset_torque_nm" in table.plant:
        off = table.plant_value("offset_torque_nm")
        assert np.all(np.abs(j["offset_torque_nm"] - base_offset) <= off * (1 + 1e-12))
    # the effective inertia's inverse is the drawn plant's
    a = j["wheel_axes"]
    eff = j["inertia_kg_m2"] - float(nominal.wheel_inertia_kg_m2) * a @ np.swapaxes(a, 1, 2)
    np.testing.assert_allclose(j["inertia_eff_inv"] @ eff, np.broadcast_to(np.eye(3), eff.shape), atol=1e-12)
    # the flight draws leave the start as the lab's of the same key (a key folded in)
    with jax.enable_x64(True):
        lab_env, lab_params = make(env_id)
        keys = jax.random.split(jax.random.PRNGKey(0), 4)
        reset = jax.jit(jax.vmap(lab_env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)  # as the draws'
        _, lab = reset(keys, lab_params)
    np.testing.assert_array_equal(np.asarray(lab.attitude), j["attitude"][:4])


def test_autoreset_redraws_the_plant_and_rests_the_chain():
    """Under ``jax.vmap`` and the gymnax step's autoreset: each episode its own plant, the
    chain's delay line carrying the command, and at the time limit fresh draws and a chain at rest."""
    n = 8
    with jax.enable_x64(True):
        env, params = make("AirBearing-v1", conditions=NO_SENSORS)
        keys = jax.random.split(jax.random.PRNGKey(3), n)
        _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)(keys, params)
        step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)), compiler_options=FASTER_COMPILE)
        actions = jnp.full((n, 3), 0.5)
        _, s1, _, _, _, info = step(keys, states, actions, params)
        last = s1.replace(time=jnp.full(n, params.max_steps_in_episode - 1, dtype=s1.time.dtype))
        _, s2, _, _, truncated, _ = step(keys, last, actions, params)
    inertia = np.asarray(states.flight.plant.inertia_kg_m2)
    assert len({inertia[i].tobytes() for i in range(n)}) == n
    np.testing.assert_array_equal(np.asarray(info["applied"]), 0.0)  # the first period acts on the zero command
    np.testing.assert_array_equal(np.asarray(s1.flight.actuators.queue)[:, 0], 0.5 * 0.8)  # the delayed command
    assert bool(np.asarray(truncated).all())
    np.testing.assert_array_equal(np.asarray(s2.flight.actuators.queue), 0.0)
    np.testing.assert_array_equal(np.asarray(s2.flight.actuators.lagged), 0.0)
    assert not np.array_equal(np.asarray(s2.flight.plant.inertia_kg_m2), inertia)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "named"),
    [
        ("ReactionWheel-v1", {"sensors": {"gyro": {"noise_std": 1e-4}}}, "only as flight conditions' sensors"),
        (
            "AirBearing-v1",
            {
                "conditions": {"base": "flight", "sensors": 0},
                "faults": [{"kind": "bias", "target": "sensor", "sensor": "gyro", "index": "random", "value": 0.1}],
            },
            "only on flight conditions' sensors",
        ),
        (
            "FuelSlosh-v0",
            {"faults": [{"kind": "bias", "target": "sensor", "sensor": "state", "index": 2, "value": 1e-3}]},
            "only on flight conditions' sensors",
        ),
        ("LinearSystem-v0", {"sensors": {"state": {"noise_std": 1e-3}}}, "only as flight conditions' sensors"),
    ],
)
def test_make_names_the_flight_features_not_modeled(env_id, kwargs, named):
    with pytest.raises(ValueError, match=named) as err:
        make(env_id, **kwargs)
    assert "\n" not in str(err.value)


def test_state_from_a_stepped_flight_env_refuses():
    """The numba chain's runtime state is not public: ``state_from`` takes a flight env with a
    delay or actuator dynamics only at its reset."""
    ne = numba_env("ReactionWheel-v1", conditions={"delay_steps": 1})
    env, _ = make("ReactionWheel-v1", conditions={"delay_steps": 1})
    ne.reset(seed=0)
    ne.step(np.zeros(4))
    with pytest.raises(ValueError, match="time=0"):
        env.state_from(ne, time=1)


def test_lab_params_and_state_carry_no_flight():
    env, params = make("ReactionWheel-v1")
    _, state = env.reset(jax.random.PRNGKey(0), params)
    assert env.flight is None and params.flight is None and state.flight is None
    with pytest.raises(ValueError, match="flight env"):
        gyrostat.with_drawn_parameters(params, {})


#: a sensor model whose bias, bias walk and noise are all of a size the KS tests resolve
#: (an explicit ``sensors=`` replaces the flight sensors); the star tracker at 0.3 s
STRONG_SENSORS = {
    "gyro": {"noise_std": 1e-3, "bias_walk_std": 2e-3, "initial_bias_std": 2e-3, "initial_bias": [1e-3, 0.0, 0.0]},
    "star_tracker": {"noise_std": 1e-3, "initial_bias_std": 2e-3, "bias_walk_std": 3e-3, "period_s": 0.3},
    "tachometer": {"noise_std": 0.5, "bias_walk_std": 0.4, "initial_bias_std": 1.0},
}
SENSOR_STEPS = 7  # ReactionWheel-v0 decides every 0.1 s: star samples at 0, 0.3 and 0.6 s


def _rotvec_error(q_true: np.ndarray, q_meas: np.ndarray) -> np.ndarray:
    """The body rotation vector ``e`` with ``q_m = q ⊗ exp(e)`` (rows)."""
    from attitude_envs import quaternion

    return np.array(
        [
            quaternion.to_rotvec(quaternion.multiply(quaternion.conjugate(a), b))
            for a, b in zip(q_true, q_meas, strict=True)
        ]
    )


def _sensor_errors(rows: np.ndarray, meas: np.ndarray) -> dict:
    """Per episode and step: the gyro's, the star tracker's and the tachometers' errors."""
    e, k = rows.shape[:2]
    star = _rotvec_error(rows[..., :4].reshape(-1, 4), meas[..., :4].reshape(-1, 4)).reshape(e, k, 3)
    return {"gyro": meas[..., 4:7] - rows[..., 4:7], "star": star, "tach": meas[..., 7:] - rows[..., 7:]}


def _numba_sensor_episodes(n: int, kwargs: dict) -> tuple[np.ndarray, np.ndarray, list]:
    ne = numba_env("ReactionWheel-v0", **kwargs)
    rows, meas, obs = [], [], []
    for seed in range(n):
        o, info = ne.reset(seed=seed)
        r, m, ob = [], [], [o]
        for _ in range(SENSOR_STEPS + 1):
            r.append(
                np.concatenate([info["truth"]["state"][k] for k in ("attitude", "rate_rad_s", "wheel_speed_rad_s")])
            )
            m.append(np.concatenate([info["sensors"][k] for k in ("star_tracker", "gyro", "tachometer")]))
            o, _, _, _, info = ne.step(np.zeros(4))
            ob.append(o)
        rows.append(r)
        meas.append(m)
        obs.append(ob)
    return np.array(rows), np.array(meas), obs


def _jax_sensor_episodes(n: int, kwargs: dict):
    with jax.enable_x64(True):
        env, params = make("ReactionWheel-v0", **kwargs)
        keys = jax.random.split(jax.random.PRNGKey(1), n)
        # the distribution tests compare to the numba env at rtol 1e-12 at most: LLVM's optimizations skipped
        obs0, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)(keys, params)
        # no episode ends in these few steps: the step without the autoreset, half the program to compile
        step = jax.jit(jax.vmap(env.step_env, in_axes=(0, 0, 0, None)), compiler_options=FASTER_COMPILE)
        row_of = jax.jit(jax.vmap(lambda s: jnp.concatenate([s.attitude, s.rate_rad_s, s.wheel_speed_rad_s])))
        measured = jax.jit(jax.vmap(env.measured_row), compiler_options=FASTER_COMPILE)
        rows, meas, obs, sampled = [], [], [obs0], []
        for i in range(SENSOR_STEPS + 1):
            rows.append(np.asarray(row_of(states)))
            meas.append(np.asarray(measured(states)))
            sampled.append(np.asarray(states.sensors.star_tracker.sampled))
            o, states, *_ = step(jax.random.split(jax.random.PRNGKey(100 + i), n), states, jnp.zeros((n, 4)), params)
            obs.append(np.asarray(o))
        targets = np.asarray(states.target_attitude)
    return np.stack(rows, 1), np.stack(meas, 1), np.stack(obs, 1), np.stack(sampled, 1), targets, env, params


def test_sensors_follow_the_numba_law():
    """Flight conditions with a strong explicit sensor model, 1,500 JAX episodes against 1,500
    numba episodes over 8 observations: the gyro's, star tracker's and tachometers' errors at
    the start (initial bias + noise), later (+ bias walk) and their change (walk + noise) have
    the same distributions (KS, p > 0.001); the star tracker holds its samples between its
    0.3 s periods at the numba env's times; the observation is the error state of the readings."""
    n = 1500
    kwargs = {"conditions": {"sensors": 1}, "sensors": STRONG_SENSORS}
    rows_n, meas_n, _ = _numba_sensor_episodes(n, kwargs)
    rows_j, meas_j, obs_j, sampled_j, targets, env, params = _jax_sensor_episodes(n, kwargs)
    err_n, err_j = _sensor_errors(rows_n, meas_n), _sensor_errors(rows_j, meas_j)
    # star tracker sample-and-hold: new readings at the same steps in both
    new_n = np.any(meas_n[:, 1:, :4] != meas_n[:, :-1, :4], axis=2)
    new_j = np.any(meas_j[:, 1:, :4] != meas_j[:, :-1, :4], axis=2)
    expected = np.array([k in (3, 6) for k in range(1, SENSOR_STEPS + 1)])  # 0.3 s, 0.6 s
    assert np.all(new_n == expected) and np.all(new_j == expected)
    np.testing.assert_allclose(sampled_j[0, -1], 0.6, rtol=1e-12)
    # the gyro and the tachometers sample every step
    assert np.all(meas_j[:, 1:, 4:] != meas_j[:, :-1, 4:])
    p_values = {}
    for name in ("gyro", "star", "tach"):
        steps = (0, 6, SENSOR_STEPS) if name == "star" else (0, 3, SENSOR_STEPS)
        for k in steps:
            for axis in range(err_n[name].shape[2]):
                p_values[f"{name} step {k} axis {axis}"] = scipy_stats.ks_2samp(
                    err_j[name][:, k, axis], err_n[name][:, k, axis]
                ).pvalue
        last = 6 if name == "star" else SENSOR_STEPS
        change_j = err_j[name][:, last] - err_j[name][:, 0]
        change_n = err_n[name][:, last] - err_n[name][:, 0]
        for axis in range(change_n.shape[1]):
            p_values[f"{name} change axis {axis}"] = scipy_stats.ks_2samp(change_j[:, axis], change_n[:, axis]).pvalue
    assert min(p_values.values()) > 1e-3, {k: round(v, 4) for k, v in p_values.items() if v < 0.05}
    # the bias walk is resolved: the change's spread exceeds the noise alone
    assert np.std(err_j["gyro"][:, SENSOR_STEPS] - err_j["gyro"][:, 0]) > 1.5 * np.sqrt(2) * 1e-3
    # the observation: the numba model's error state of the JAX readings
    ne = numba_env("ReactionWheel-v0", **kwargs)
    for i in range(0, n, 150):
        for k in (0, 3, SENSOR_STEPS):
            m = meas_j[i, k]
            x = ne.model.error_state(m[:4], m[4:7], m[7:], targets[i])
            np.testing.assert_allclose(obs_j[i, k], x, rtol=1e-12, atol=1e-15)


def test_flight_sensors_at_the_cited_values():
    """``conditions="flight"`` (every feature, the cited sensors): JAX and numba readings' errors
    of the same size (the gyro's white noise dominates: KS on its error)."""
    n = 600
    rows_n, meas_n, _ = _numba_sensor_episodes(n, {"conditions": "flight"})
    rows_j, meas_j, *_ = _jax_sensor_episodes(n, {"conditions": "flight"})
    err_n, err_j = _sensor_errors(rows_n, meas_n), _sensor_errors(rows_j, meas_j)
    for name in ("gyro", "tach", "star"):
        for axis in range(3):
            p = scipy_stats.ks_2samp(err_j[name][:, 0, axis], err_n[name][:, 0, axis]).pvalue
            assert p > 1e-3, (name, axis, p)


@pytest.mark.parametrize("x64", [False, True])
def test_star_tracker_period_of_two_control_periods_in_float32_and_x64(x64):
    """AirBearing-v0's flight attitude sensor samples every 0.02 s under its 0.01 s control:
    every second step over the whole 20 s episode, also in float32 (whose step times carry
    rounding beyond the numba test's 10⁻⁹ margin)."""
    with jax.enable_x64(x64):
        env, params = make("AirBearing-v0", conditions="flight")
        _, state = env.reset(jax.random.PRNGKey(0), params)

        def body(s, k):
            _, s2, *_ = env.step_env(k, s, jnp.zeros(3), params)
            return s2, s2.sensors.star_tracker.sampled != s.sensors.star_tracker.sampled

        steps = int(params.max_steps_in_episode)
        keys = jax.random.split(jax.random.PRNGKey(1), steps)
        _, new = jax.jit(lambda s: jax.lax.scan(body, s, keys), compiler_options=FAST_COMPILE)(state)
    new = np.asarray(new)
    assert steps == 2000 and new[1::2].all() and not new[0::2].any()
