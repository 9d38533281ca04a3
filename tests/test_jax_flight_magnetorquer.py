"""The JAX Magnetorquer under flight conditions (:mod:`attitude_envs.conditions`) against the
numba Magnetorquer env: the delay, the actuator chain (the dipoles' resolution and duty cycle,
the wheel's resolution, lag and friction), the faults between its stages and the drawn true
inertia and gains step for step (x64, whole episodes, the numba episode's draws given to the
JAX plant); the sensor wiring step for step with noiseless sensors (the observation built
from the readings, the star tracker's sample-and-hold); the parameter draws and the flight
sensors' errors in distribution (two-sample Kolmogorov–Smirnov tests against the numba env's)."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
scipy_stats = pytest.importorskip("scipy.stats")
import jax.numpy as jnp  # noqa: E402
from test_jax_magnetorquer import FAST_COMPILE, FASTER_COMPILE  # noqa: E402

from attitude_envs import quaternion  # noqa: E402
from attitude_envs.jax import magnetorquer as mt  # noqa: E402
from attitude_envs.jax.make import make, numba_env  # noqa: E402

NO_SENSORS = {"base": "flight", "sensors": 0}
#: noiseless flight sensors (readings equal the truth at their samples), the star tracker at
#: 0.3 s under the 0.1 s control period: the observation is of held attitudes between samples
NOISELESS = {
    "gyro": {"noise_std": 0.0},
    "star_tracker": {"noise_std": 0.0, "period_s": 0.3},
    "tachometer": {"noise_std": 0.0},
    "magnetometer": {"noise_std": 0.0, "period_s": 0.1},
}
#: tracking from a fixed orbit phase on the noiseless sensors, the field observed
NOISELESS_TRACKING = {
    "conditions": "flight",
    "sensors": NOISELESS,
    "observe_field": True,
    "orbit": {"mean_anomaly_deg": 30.0},
    "episode_duration_s": 6.0,
}
# id: (env id, keywords, seed, JAX start: "state_from" or "reset" with the numba draws given)
CONFIGS = {
    "Magnetorquer-v1 flight": ("Magnetorquer-v1", {"conditions": NO_SENSORS}, 3, "state_from"),
    "Magnetorquer-v1 regulation, faults, 2-period delay": (
        "Magnetorquer-v1",
        {
            "conditions": {**NO_SENSORS, "delay_steps": 2},
            "task": "regulation",
            "faults": [
                {"kind": "loss_of_effectiveness", "index": 0, "value": 0.4, "onset_s": 50.0},
                {"kind": "stuck", "index": 3, "onset_s": 120.0},
            ],
        },
        4,
        "state_from",
    ),
    # tracking from a fixed orbit phase: a deterministic start, so the JAX reset (with the
    # numba episode's inertia and gains given) is the numba episode's start
    "Magnetorquer-v0 flight, noiseless sensors": ("Magnetorquer-v0", NOISELESS_TRACKING, 5, "reset"),
    # the flight cells' sensor faults and the others, on the noiseless sensors: a gyro bias jump,
    # a magnetometer outage holding its last sample, a stuck star tracker and a tachometer drift,
    # with the fault flags in the observation
    "Magnetorquer-v0 flight, noiseless sensors, sensor faults": (
        "Magnetorquer-v0",
        {
            **NOISELESS_TRACKING,
            "fault_hint": True,
            "faults": [
                {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "value": 1e-3, "onset_s": 1.0},
                {
                    "kind": "dropout",
                    "target": "sensor",
                    "sensor": "magnetometer",
                    "index": "all",
                    "mode": "hold",
                    "onset_s": 2.0,
                    "duration_s": 2.0,
                },
                {"kind": "stuck", "target": "sensor", "sensor": "star_tracker", "index": "all", "onset_s": 3.0},
                {"kind": "drift", "target": "sensor", "sensor": "tachometer", "index": 0, "value": 0.5, "onset_s": 1.5},
            ],
        },
        5,
        "reset",
    ),
}
RTOL = 1e-12


@partial(jax.jit, static_argnums=0, compiler_options=FAST_COMPILE)
def _rollout(env: mt.MagnetorquerEnv, state: mt.EnvState, actions: jax.Array, params: mt.EnvParams):
    """Every step's ``[q, ω_bo, Ω]``, observation, reward, cost, end flags and applied outputs
    (``step_env`` in a scan; the sensors' noise keys are those of step ``i``)."""

    def body(s, xs):
        i, a = xs
        obs, s, reward, terminated, info = env.step_env(jax.random.PRNGKey(i), s, a, params)
        truncated = env.is_truncated(s, params) & ~terminated
        y = jnp.concatenate([s.attitude, s.rate_rad_s, s.wheel_speed_rad_s])
        return s, (y, obs, reward, info["cost"], terminated, truncated, info["applied"])

    return jax.lax.scan(body, state, (jnp.arange(actions.shape[0]), actions))[1]


def _numba_episode(ne, n_steps: int, seed: int) -> dict:
    """Step the numba env (just reset) with random actions to the episode's end."""
    actions = np.random.default_rng(1000 + seed).uniform(-1.0, 1.0, (n_steps, 4))
    keys = ("y", "obs", "reward", "cost", "terminated", "truncated", "applied", "commanded")
    rec = {k: [] for k in keys}
    for a in actions:
        obs, reward, terminated, truncated, info = ne.step(a)
        row = (ne.state_row.copy(), obs, reward, info["cost"], terminated, truncated)
        for k, v in zip(keys, (*row, info["truth"]["applied"], info["commanded"]), strict=True):
            rec[k].append(v)
        if terminated or truncated:
            break
    return {"actions": actions[: len(rec["y"])], **{k: np.array(v) for k, v in rec.items()}}


def _flight_episode(name: str) -> tuple[dict, dict, mt.MagnetorquerEnv]:
    """A numba flight episode and the JAX plant stepped from its start: (numba, JAX, env)."""
    env_id, kwargs, seed, start = CONFIGS[name]
    ne = numba_env(env_id, **kwargs)
    env, params = make(env_id, **kwargs)
    obs0, _ = ne.reset(seed=seed)
    params = mt.with_drawn_parameters(params, ne.drawn_parameters())
    obs0_j, state = env.reset(jax.random.PRNGKey(seed), params)
    if start == "state_from":
        from_numba = env.state_from(ne)
        # the reset with the given draws holds the numba episode's inertia and gains, bit for bit
        for a, b in zip(
            jax.tree.leaves((state.inertia_kg_m2, state.inertia_eff_inv, state.flight)),
            jax.tree.leaves((from_numba.inertia_kg_m2, from_numba.inertia_eff_inv, from_numba.flight)),
            strict=True,
        ):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        state, obs0_j = from_numba, env.observation(from_numba, params)
    ref = _numba_episode(ne, int(params.max_steps_in_episode), seed)
    y, obs, reward, cost, terminated, truncated, applied = _rollout(env, state, jnp.asarray(ref["actions"]), params)
    out = {"obs0": obs0_j, "y": y, "obs": obs, "reward": reward, "cost": cost}
    out |= {"terminated": terminated, "truncated": truncated, "applied": applied}
    return {"obs0": obs0, **ref}, {k: np.asarray(v) for k, v in out.items()}, env


def _relative(mine: np.ndarray, theirs: np.ndarray, floor: float) -> float:
    return float(np.max(np.abs(mine - theirs) / np.maximum(floor, np.abs(theirs))))


@pytest.mark.parametrize("name", list(CONFIGS))
def test_flight_episode_equals_numba_env_under_x64(name):
    """The delay line, the actuator chain, the faults between its stages and the drawn true
    inertia and gains (and, noiseless, the sensors' wiring): a whole episode as the numba env's.
    States, rewards, costs and the delivered outputs to 1e-12 relative (the lab twin's own
    agreement, ~1e-13: XLA fuses and orders some sums differently), observations to the numba
    env's float32 rounding."""
    with jax.enable_x64(True):
        ref, out, env = _flight_episode(name)
    assert ref["terminated"][-1] or ref["truncated"][-1]  # the whole episode
    errors = {
        "state": _relative(out["y"], ref["y"], 1.0),
        "reward": _relative(out["reward"], ref["reward"], 1e-300),
        "cost": _relative(out["cost"], ref["cost"], 1e-300),
        "applied": _relative(out["applied"], ref["applied"], 1e-300),
    }
    assert max(errors.values()) <= RTOL, errors
    np.testing.assert_array_equal(out["terminated"], ref["terminated"])
    np.testing.assert_array_equal(out["truncated"], ref["truncated"])
    for mine, theirs in ((out["obs"], ref["obs"]), (out["obs0"], ref["obs0"])):
        assert theirs.dtype == np.float32 and mine.dtype == np.float64
        np.testing.assert_allclose(mine, theirs, rtol=2.0**-24, atol=1e-11)
    # the flight stages acted: the delay's zero dipoles first (the wheel's friction acts once
    # it spins), then the torquers at 80 % duty
    delay = env.flight.actuators.delay_steps
    np.testing.assert_array_equal(ref["applied"][:delay, :3], 0.0)
    ratio = ref["applied"][delay + 1 :, :3] / ref["commanded"][1 : len(ref["applied"]) - delay, :3]
    assert np.median(np.abs(ratio)) < 0.95


def _statistics(inertia: np.ndarray, gain: np.ndarray) -> dict:
    """Per draw: the sorted principal moments, the inertia's products, the dipoles' and the
    wheel's gains."""
    moments = np.linalg.eigvalsh(inertia)
    stats = {f"moment {i}": moments[:, i] for i in range(3)}
    stats |= {f"I[{i},{j}]": inertia[:, i, j] for i, j in ((0, 1), (0, 2), (1, 2))}
    return stats | {"dipole gain": gain[:, :3].ravel(), "wheel gain": gain[:, 3]}


def test_parameter_draws_follow_the_numba_law():
    """2,000 JAX resets against 2,000 numba resets: the true inertia's principal moments and
    products and the actuators' gains have the same distributions (two-sample KS, p > 0.001)
    and stay within the cited tolerances; the start (orbit phase) is the lab's of the same key."""
    n = 2000
    conditions = {"parameters": True}
    with jax.enable_x64(True):
        env, params = make("Magnetorquer-v1", conditions=conditions)
        keys = jax.random.split(jax.random.PRNGKey(0), n)
        _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)(keys, params)
        lab_env, lab_params = make("Magnetorquer-v1")
        _, lab = jax.vmap(lab_env.reset, in_axes=(0, None))(keys[:4], lab_params)
    inertia, gain = np.asarray(states.inertia_kg_m2), np.asarray(states.flight.gain)
    ne = numba_env("Magnetorquer-v1", conditions=conditions)
    drawn = []
    for seed in range(n):
        ne.reset(seed=seed)
        drawn.append(ne.drawn_parameters())
    stats_j = _statistics(inertia, gain)
    stats_n = _statistics(np.array([d["inertia_kg_m2"] for d in drawn]), np.array([d["actuator_gain"] for d in drawn]))
    p_values = {key: scipy_stats.ks_2samp(stats_j[key], stats_n[key]).pvalue for key in stats_n}
    assert min(p_values.values()) > 1e-3, p_values
    table = ne.flight_table
    tol = table.plant_value("inertia_moment")
    nominal = np.sort(np.linalg.eigvalsh(ne.model.params.inertia_kg_m2))
    moments = np.linalg.eigvalsh(inertia)
    assert np.all(moments >= nominal * (1 - tol) * (1 - 1e-12)) and np.all(moments <= nominal * (1 + tol) * (1 + 1e-12))
    assert np.all(np.abs(gain - 1.0) <= np.asarray(table.gain_tolerance.value) + 1e-15)
    # the effective inertia's inverse is the drawn inertia's
    eff = inertia.copy()
    eff[:, 1, 1] -= float(params.plant.wheel_inertia_kg_m2)
    np.testing.assert_allclose(
        np.asarray(states.inertia_eff_inv) @ eff, np.broadcast_to(np.eye(3), eff.shape), atol=1e-12
    )
    np.testing.assert_array_equal(np.asarray(lab.mean_anomaly0_rad), np.asarray(states.mean_anomaly0_rad)[:4])
    np.testing.assert_array_equal(np.asarray(lab.attitude), np.asarray(states.attitude)[:4])


SENSOR_STEPS = 4  # Magnetorquer-v0 decides every 0.1 s: every channel samples at every step


def _errors(q, gyro_true, wheel, field_true, readings) -> dict:
    """Per episode and observation: each channel's error (the star tracker's as the body
    rotation vector ``e`` with ``q_m = q ⊗ exp(e)``)."""
    e, k = q.shape[:2]
    pairs = zip(q.reshape(-1, 4), readings["star_tracker"].reshape(-1, 4), strict=True)
    star = np.array([quaternion.to_rotvec(quaternion.multiply(quaternion.conjugate(a), b)) for a, b in pairs])
    return {
        "gyro": readings["gyro"] - gyro_true,
        "star_tracker": star.reshape(e, k, 3),
        "tachometer": readings["tachometer"] - wheel,
        "magnetometer": readings["magnetometer"] - field_true,
    }


def _numba_sensor_errors(n: int) -> dict:
    ne = numba_env("Magnetorquer-v0", conditions="flight", episode_duration_s=1.0)
    rows = {k: [] for k in ("q", "gyro", "wheel", "field", "gyro_m", "star_m", "tach_m", "mag_m")}
    for seed in range(n):
        _, info = ne.reset(seed=seed)
        episode = {k: [] for k in rows}
        for _ in range(SENSOR_STEPS + 1):
            truth, readings = info["truth"], info["sensors"]
            state = truth["state"]
            values = (state["attitude"], state["inertial_rate_rad_s"], state["wheel_speed_rad_s"])
            values += (truth["magnetic_field_body_t"], readings["gyro"], readings["star_tracker"])
            values += (readings["tachometer"], readings["magnetometer"])
            for k, v in zip(rows, values, strict=True):
                episode[k].append(np.array(v, dtype=float))
            _, _, _, _, info = ne.step(np.zeros(4))
        for k in rows:
            rows[k].append(episode[k])
    r = {k: np.array(v) for k, v in rows.items()}
    readings = {"gyro": r["gyro_m"], "star_tracker": r["star_m"], "tachometer": r["tach_m"], "magnetometer": r["mag_m"]}
    return _errors(r["q"], r["gyro"], r["wheel"], r["field"], readings)


def _jax_sensor_errors(n: int) -> dict:
    with jax.enable_x64(True):
        env, params = make("Magnetorquer-v0", conditions="flight", episode_duration_s=1.0)

        def observe(s):
            t_s = s.time.astype(s.rate_rad_s.dtype) * params.timing.control_dt_s
            rate, _, _, field = mt.orbit_field(params, s.mean_anomaly0_rad, t_s)
            truth = s.replace(sensors=None)  # readings of a state without sensors: the truth
            return env.readings(truth, rate, field), env.readings(s, rate, field)

        def episode(key):
            # one program: the reset, then SENSOR_STEPS zero-command steps, reading before each
            key, start = jax.random.split(key)
            _, state = env.reset(start, params)

            def advance(s, step_key):
                seen = observe(s)
                _, s, *_ = env.step_env(step_key, s, jnp.zeros(4), params)
                return s, seen

            last, seen = jax.lax.scan(advance, state, jax.random.split(key, SENSOR_STEPS))
            return jax.tree.map(lambda a, b: jnp.concatenate([a, b[None]]), seen, observe(last))

        run = jax.jit(jax.vmap(episode), compiler_options=FASTER_COMPILE)
        truths, readings = run(jax.random.split(jax.random.PRNGKey(1), n))
    truth = {k: np.asarray(v) for k, v in truths.items()}
    read = {k: np.asarray(v) for k, v in readings.items()}
    return _errors(truth["star_tracker"], truth["gyro"], truth["tachometer"], truth["magnetometer"], read)


def test_flight_sensors_follow_the_numba_law():
    """``conditions="flight"``, the cited sensors (noise, the bias drawn at reset, its walk):
    800 JAX episodes against 800 numba episodes over 5 observations, each channel's error
    at the start and at the last observation and its change have the same distributions
    per axis (KS, p > 0.001), of the cited sizes."""
    n = 800
    err_n, err_j = _numba_sensor_errors(n), _jax_sensor_errors(n)
    p_values = {}
    for name, e_n in err_n.items():
        e_j = err_j[name]
        samples = {"start": (e_j[:, 0], e_n[:, 0]), "last": (e_j[:, -1], e_n[:, -1])}
        samples["change"] = (e_j[:, -1] - e_j[:, 0], e_n[:, -1] - e_n[:, 0])
        for what, (a, b) in samples.items():
            for axis in range(b.shape[1]):
                p_values[f"{name} {what} axis {axis}"] = scipy_stats.ks_2samp(a[:, axis], b[:, axis]).pvalue
    assert min(p_values.values()) > 1e-3, {k: round(v, 4) for k, v in p_values.items() if v < 0.05}
    # the errors are the cited sizes: the magnetometer's 100 nT bias with its 10 nT noise, the
    # star tracker's 10″ noise (their changes are the noise alone)
    assert 80e-9 < np.std(err_j["magnetometer"][:, 0]) < 120e-9
    assert 8e-9 < np.std(err_j["magnetometer"][:, -1] - err_j["magnetometer"][:, 0]) / np.sqrt(2) < 12e-9
    assert 0.8 < np.std(err_j["star_tracker"][:, 0]) / np.radians(10.0 / 3600.0) < 1.2


def test_autoreset_redraws_the_gains_and_rests_the_chain():
    """Under ``jax.vmap`` and the gymnax step's autoreset: the delay line carries the command,
    and at the time limit the next episode starts with fresh gains, the chain at rest and the
    sensors restarted at t = 0."""
    n = 4
    with jax.enable_x64(True):
        env, params = make("Magnetorquer-v0", conditions="flight", episode_duration_s=0.2)
        keys = jax.random.split(jax.random.PRNGKey(3), n)
        _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=FASTER_COMPILE)(keys, params)
        step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, None, None)), compiler_options=FASTER_COMPILE)
        _, s1, _, _, truncated1, info = step(keys, states, jnp.full(4, 0.5), params)
        _, s2, _, _, truncated2, _ = step(keys, s1, jnp.full(4, 0.5), params)
    assert not np.asarray(truncated1).any() and np.asarray(truncated2).all()
    np.testing.assert_array_equal(np.asarray(info["applied"])[:, :3], 0.0)  # the first period: the zero command
    np.testing.assert_array_equal(np.asarray(s1.flight.actuators.queue)[:, 0], np.asarray(info["commanded"]))
    np.testing.assert_array_equal(np.asarray(s2.flight.actuators.queue), 0.0)
    assert not np.any(np.asarray(s2.flight.gain) == np.asarray(states.flight.gain))
    np.testing.assert_array_equal(np.asarray(s2.sensors.star_tracker.sampled), 0.0)
    np.testing.assert_array_equal(np.asarray(s2.time), 0)


def test_make_refuses_flight_features_not_modeled():
    with pytest.raises(ValueError, match="only as flight conditions' sensors"):
        make("Magnetorquer-v1", sensors={"gyro": {"noise_std": 1e-5}})
    with pytest.raises(ValueError, match="flight conditions' sensors"):
        make(
            "Magnetorquer-v1", faults=[{"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "value": 0.1}]
        )
    with pytest.raises(ValueError, match="indefinite"):
        make("Magnetorquer-v1", conditions={"parameters": 10}, time_varying_inertia={"amplitude_kg_m2": [0.5] * 3})


def test_state_from_refuses_sensors_and_a_stepped_chain():
    ne = numba_env("Magnetorquer-v1", conditions={"delay_steps": 1})
    env, _ = make("Magnetorquer-v1", conditions={"delay_steps": 1})
    ne.reset(seed=0)
    ne.step(np.zeros(4))
    with pytest.raises(ValueError, match="right after its reset"):
        env.state_from(ne)
    sensed, _ = make("Magnetorquer-v1", conditions="flight")
    with pytest.raises(ValueError, match="sensors"):
        sensed.state_from(numba_env("Magnetorquer-v1", conditions="flight"))


def test_lab_params_and_state_carry_no_flight():
    env, params = make("Magnetorquer-v1")
    _, state = env.reset(jax.random.PRNGKey(0), params)
    assert env.flight is None and env.sensors == () and params.flight is None and params.sensors is None
    assert state.flight is None and state.sensors is None
    with pytest.raises(ValueError, match="flight env"):
        mt.with_drawn_parameters(params, {})
