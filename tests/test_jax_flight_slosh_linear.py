"""The JAX LinearSystem and FuelSlosh twins under flight conditions (:mod:`attitude_envs.conditions`)
against the numba envs: the delay and the actuator chain step for step (x64, whole episodes with
sensor noise off, the numba episode's drawn plant given to the JAX reset), the per-episode
parameter draws and the ``state`` sensor's errors in distribution (two-sample Kolmogorov–Smirnov
tests against the numba envs' draws), and what stays refused by name."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
scipy_stats = pytest.importorskip("scipy.stats")
import jax.numpy as jnp  # noqa: E402
from test_jax_fuel_slosh import _state_err as _slosh_state_err  # noqa: E402
from test_jax_gyrostat import _relative  # noqa: E402

from attitude_envs.jax import fuel_slosh, linear_system, make  # noqa: E402
from attitude_envs.jax.make import numba_env  # noqa: E402

NO_SENSORS = {"base": "flight", "sensors": 0}
# XLA:CPU compiles these programs fastest at its lowest backend optimization level (the sensors'
# and the draws' threefry programs: 1.5-2 s against 6-12 s with tests/test_jax_gyrostat.py's
# FAST_COMPILE, on a loaded 2-core machine); only the test's own jits take the option
QUICK_COMPILE = {"xla_backend_optimization_level": 0}
TOL = 1e-12
# id: (env id, keywords, seed); actions are uniform in ±1.2 (LinearSystem) or the bounded
# wandering of tests/test_jax_fuel_slosh.py (FuelSlosh: differences of uniforms in ±0.3)
CONFIGS = {
    "LinearSystem-v1 flight": ("LinearSystem-v1", {"conditions": NO_SENSORS}, 3),
    "LinearSystem-v0 faults, 2-period delay, hint": (
        "LinearSystem-v0",
        {
            "conditions": {**NO_SENSORS, "delay_steps": 2},
            "episode_steps": 300,
            "fault_hint": True,
            "faults": [
                {"kind": "stuck", "index": 2, "onset_s": 0.5, "duration_s": 1.0},
                {"kind": "bias", "index": 0, "value": {"uniform": [0.5, 1.0]}, "onset_s": 0.2, "duration_s": 1.0},
            ],
        },
        4,
    ),
    "LinearSystem-v1 parameters only": ("LinearSystem-v1", {"conditions": {"parameters": 2.0}}, 5),
    "FuelSlosh-v1 flight": ("FuelSlosh-v1", {"conditions": NO_SENSORS, "episode_duration_s": 20.0}, 6),
    "FuelSlosh-v0 faults, 2-period delay, hint": (
        "FuelSlosh-v0",
        {
            "conditions": {**NO_SENSORS, "delay_steps": 2},
            "episode_duration_s": 10.0,
            "observe_slosh": False,
            "fault_hint": True,
            "faults": [
                {"kind": "loss_of_effectiveness", "index": "random", "value": {"uniform": [0.3, 0.7]}, "onset_s": 3.0},
                {"kind": "bias", "index": 1, "value": 50.0, "onset_s": 5.0, "duration_s": 2.0},
            ],
        },
        7,
    ),
}


def _vector(state) -> jax.Array:
    """A JAX state's plant state: LinearSystem's ``x``, FuelSlosh's full ``y``."""
    return state.x if hasattr(state, "x") else state.y


def _rollout(env):
    """A jitted scan of ``env.step_env`` (no autoreset): per step the plant state, observation,
    reward, cost, terminated, truncated, time (s) and the delivered inputs."""

    def run(state, params, actions, keys):
        def body(s, xs):
            a, k = xs
            obs, s2, reward, terminated, info = env.step_env(k, s, a, params)
            truncated = env.is_truncated(s2, params) & ~terminated
            out = (_vector(s2), obs, reward, info["cost"], terminated, truncated, info["time_s"], info["applied"])
            return s2, out

        return jax.lax.scan(body, state, (actions, keys))[1]

    return jax.jit(run, compiler_options=QUICK_COMPILE)


def _numba_episode(ne, actions: np.ndarray) -> list[np.ndarray]:
    """The numba env stepped until its episode ends: the outputs of :func:`_rollout`."""
    out: list[list] = [[] for _ in range(8)]
    for a in actions:
        obs, reward, terminated, truncated, info = ne.step(a)
        row = (ne.state, obs, reward, info["cost"], terminated, truncated, info["time_s"], info["truth"]["applied"])
        for v, r in zip(out, row, strict=True):
            v.append(np.array(r))
        if terminated or truncated:
            break
    return [np.array(v) for v in out]


def _flight_episode(name: str):
    """One numba flight episode and the JAX twin stepped from its start (``state_from``) with its
    drawn plant also given to the JAX reset: (numba outputs, JAX outputs, numba env, reset
    state, state_from state)."""
    env_id, kwargs, seed = CONFIGS[name]
    module = linear_system if env_id.startswith("LinearSystem") else fuel_slosh
    ne = numba_env(env_id, **kwargs)
    env, params = make(env_id, **kwargs)
    ne.reset(seed=seed)
    if ne.drawn_parameters():
        params = module.with_drawn_parameters(params, ne.drawn_parameters())
    _, reset_state = env.reset(jax.random.PRNGKey(seed), params)
    state = env.state_from(ne)
    steps = int(params.max_steps_in_episode)
    rng = np.random.default_rng(seed)
    if module is linear_system:
        actions = rng.uniform(-1.2, 1.2, (steps, env.num_actions))
    else:
        actions = np.diff(rng.uniform(-0.3, 0.3, (steps + 1, 2)), axis=0)
    ref = _numba_episode(ne, actions)
    keys = jax.random.split(jax.random.PRNGKey(seed), steps)
    out = [np.asarray(v) for v in _rollout(env)(state, params, jnp.asarray(actions), keys)]
    return ref, out, ne, env, reset_state, state


def _max_errors(ref, out, ne) -> dict[str, float]:
    """The JAX rollout ``out`` against the numba episode ``ref`` (x64): ends and times equal,
    observations equal to float32 rounding (the terminal one clipped to the numba box); returns
    the largest relative differences of the states (FuelSlosh's scaled as in
    tests/test_jax_fuel_slosh.py), costs and rewards, and delivered inputs."""
    states, obs, rewards, costs, terms, truncs, times, applied = ref
    k = len(states)
    j_states, j_obs, j_rewards, j_costs, j_terms, j_truncs, j_times, j_applied = (v[:k] for v in out)
    assert j_states.dtype == np.float64 and j_obs.dtype == np.float64
    np.testing.assert_array_equal(j_terms, terms)
    np.testing.assert_array_equal(j_truncs, truncs)
    np.testing.assert_array_equal(j_times, times)
    for i in range(k):
        got = ne.clip_observation(j_obs[i]) if terms[i] else j_obs[i].astype(np.float32)
        np.testing.assert_allclose(got, obs[i], rtol=2.0**-23, atol=1e-12)
    if states.shape[1] == 10:  # FuelSlosh's full state
        state_err = max(_slosh_state_err(states[i], j_states[i]) for i in range(k))
    else:
        state_err = _relative(j_states, states)
    return {
        "state": state_err,
        "cost": max(_relative(j_costs, costs), _relative(j_rewards, rewards)),
        "applied": _relative(j_applied, applied),
    }


@pytest.mark.parametrize("name", list(CONFIGS))
def test_flight_episode_equals_numba_env_under_x64(name):
    """The delay line, the actuator chain (the gimbal's rate limit and lag, the gains), the faults
    between them and the drawn true plant: a whole episode as the numba env's, to 1e-12."""
    with jax.enable_x64(True):
        ref, out, ne, env, reset_state, state = _flight_episode(name)
    assert ref[4][-1] or ref[5][-1]  # the numba episode ended
    errors = _max_errors(ref, out, ne)
    assert max(errors.values()) <= TOL, errors
    # the reset given the numba draws holds the numba episode's plant and gains, bit for bit
    for a, b in zip(jax.tree.leaves(reset_state.flight), jax.tree.leaves(state.flight), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    delay = env.flight.delay_steps if hasattr(env.flight, "delay_steps") else env.flight.actuators.delay_steps
    if delay:  # the first periods act on the zero command
        np.testing.assert_array_equal(ref[7][:delay], 0.0)


# ---------------------------------------------------------------------- parameter draws
DRAWN = {
    "LinearSystem-v0": ("actuator_gain",),
    "FuelSlosh-v1": ("slosh_mass_kg", "length_m", "fuel_mass_kg", "actuator_gain"),
}


def _jax_draws(env_id: str, kwargs: dict, n: int) -> tuple[dict, np.ndarray]:
    """``n`` JAX resets' drawn parameters (vmapped over keys) and their starts."""
    with jax.enable_x64(True):
        env, params = make(env_id, **kwargs)
        keys = jax.random.split(jax.random.PRNGKey(0), n)
        _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=QUICK_COMPILE)(keys, params)
    f = states.flight
    out = {"actuator_gain": np.asarray(f.gain)}
    if getattr(f, "plant", None) is not None:
        out |= {k: np.asarray(getattr(f.plant, k)) for k in ("slosh_mass_kg", "length_m", "fuel_mass_kg")}
    return out, np.asarray(_vector(states))


def _numba_draws(env_id: str, kwargs: dict, n: int) -> dict:
    ne = numba_env(env_id, **kwargs)
    out: dict = {}
    for seed in range(n):
        ne.reset(seed=seed)
        for k, v in ne.drawn_parameters().items():
            out.setdefault(k, []).append(np.atleast_1d(v))
    return {k: np.array(v) for k, v in out.items()}


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [("LinearSystem-v0", {"x0_std": 0.1}), ("FuelSlosh-v1", {})],
)
def test_parameter_draws_follow_the_numba_law(env_id, kwargs):
    """1,000 JAX resets against 1,000 numba resets: every drawn entry (LinearSystem: each input's
    gain; FuelSlosh: the slosh masses, pendulum lengths, fixed propellant mass and gains) has the
    same distribution (two-sample KS, p > 0.001) and stays within the cited tolerances; the
    flight draws leave the start as the lab's of the same key."""
    n = 1000
    kwargs = {**kwargs, "conditions": {"parameters": True}}
    jax_draws, starts = _jax_draws(env_id, kwargs, n)
    ref = _numba_draws(env_id, kwargs, n)
    assert set(ref) == set(DRAWN[env_id])
    p_values = {}
    for key in DRAWN[env_id]:
        j, r = jax_draws[key].reshape(n, -1), ref[key].reshape(n, -1)
        for i in range(r.shape[1]):
            p_values[f"{key}[{i}]"] = scipy_stats.ks_2samp(j[:, i], r[:, i]).pvalue
    assert min(p_values.values()) > 1e-3, p_values
    ne = numba_env(env_id, **kwargs)
    table = ne.flight_table
    gain_tol = float(table.gain_tolerance.value)
    assert np.all(np.abs(jax_draws["actuator_gain"] - 1.0) <= gain_tol * (1 + 1e-12))
    if env_id.startswith("FuelSlosh"):
        nominal = ne.model.params
        for key, tol in (("slosh_mass_kg", "slosh_mass"), ("length_m", "pendulum_length")):
            ratio = jax_draws[key] / np.asarray(getattr(nominal, key))
            assert np.all(np.abs(ratio - 1.0) <= table.plant_value(tol) * (1 + 1e-12))
        total = jax_draws["slosh_mass_kg"].sum(axis=1) + jax_draws["fuel_mass_kg"]
        np.testing.assert_allclose(total, nominal.fuel_mass_kg + sum(nominal.slosh_mass_kg), rtol=1e-12)
    with jax.enable_x64(True):
        lab_env, lab_params = make(env_id, **{k: v for k, v in kwargs.items() if k != "conditions"})
        keys = jax.random.split(jax.random.PRNGKey(0), n)
        reset = jax.jit(jax.vmap(lab_env.reset, in_axes=(0, None)), compiler_options=QUICK_COMPILE)
        _, lab = reset(keys, lab_params)
    np.testing.assert_array_equal(np.asarray(_vector(lab)), starts)
    assert len(np.unique(starts, axis=0)) > 1  # the starts are drawn


# ---------------------------------------------------------------------- the state sensor
SENSOR_STEPS = 6
#: LinearSystem-v0's state sensor with a bias, its walk and a 0.03 s period (3 control periods):
#: samples at 0, 0.03 and 0.06 s
STRONG_STATE_SENSOR = {
    "state": {
        "noise_std": 2e-3,
        "bias_walk_std": 0.05,
        "initial_bias_std": 4e-3,
        "initial_bias": 1e-3,
        "period_s": 0.03,
    }
}
SENSOR_CONFIGS = {
    "LinearSystem-v0 strong sensor": (
        "LinearSystem-v0",
        {"conditions": {"sensors": 1}, "sensors": STRONG_STATE_SENSOR},
    ),
    "FuelSlosh-v1 flight": ("FuelSlosh-v1", {"conditions": "flight"}),
}


def _truth_entries(ne, info) -> np.ndarray:
    """The true values of the ``state`` sensor's entries in a numba info."""
    if "full_state" in info["truth"]:
        return info["truth"]["full_state"][ne.observation_index]
    return info["truth"]["state"]


def _numba_sensor_episodes(env_id: str, kwargs: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per episode and observation (reset and ``SENSOR_STEPS`` zero-action steps): the state
    sensor's reading and its error."""
    ne = numba_env(env_id, **kwargs)
    readings, errors = [], []
    zero = np.zeros(ne.action_space.shape)
    for seed in range(n):
        _, info = ne.reset(seed=seed)
        r, e = [], []
        for _ in range(SENSOR_STEPS + 1):
            reading = info["sensors"]["state"]
            r.append(reading)
            e.append(reading - _truth_entries(ne, info))
            _, _, terminated, truncated, info = ne.step(zero)
            assert not (terminated or truncated)
        readings.append(r)
        errors.append(e)
    return np.array(readings), np.array(errors)


def _jax_sensor_episodes(env_id: str, kwargs: dict, n: int):
    """The JAX twin's: per episode and observation the observation, the sensor's sample and its
    error (vmapped resets and autoreset steps)."""
    with jax.enable_x64(True):
        env, params = make(env_id, **kwargs)
        keys = jax.random.split(jax.random.PRNGKey(1), n)
        obs, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)), compiler_options=QUICK_COMPILE)(keys, params)
        step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)), compiler_options=QUICK_COMPILE)
        index = np.array(env.obs_index) if hasattr(env, "obs_index") else np.arange(env.n)
        observations, samples, errors = [], [], []
        for i in range(SENSOR_STEPS + 1):
            sample = np.asarray(states.sensors.channel.last)
            observations.append(np.asarray(obs))
            samples.append(sample)
            errors.append(sample - np.asarray(_vector(states))[:, index])
            actions = jnp.zeros((n, env.num_actions))
            obs, states, _, terminated, truncated, _ = step(
                jax.random.split(jax.random.PRNGKey(100 + i), n), states, actions, params
            )
            assert not np.any(np.asarray(terminated) | np.asarray(truncated))
    return np.stack(observations, 1), np.stack(samples, 1), np.stack(errors, 1), env


@pytest.mark.parametrize("name", list(SENSOR_CONFIGS))
def test_state_sensor_errors_follow_the_numba_law(name):
    """800 JAX episodes against 800 numba episodes over 7 observations: each measured entry's
    error at the start (initial bias + noise), at the end (+ the bias walk) and its change have
    the same distributions (KS, p > 0.001); a sensor with a period holds its samples at the numba
    env's times; the observation is the reading, with the slosh entries the flight sensors do
    not measure at 0."""
    env_id, kwargs = SENSOR_CONFIGS[name]
    n = 800
    readings_n, errors_n = _numba_sensor_episodes(env_id, kwargs, n)
    obs_j, samples_j, errors_j, env = _jax_sensor_episodes(env_id, kwargs, n)
    measured = np.ones(errors_n.shape[2], dtype=bool)
    measured[list(getattr(env, "unmeasured", ()))] = False
    assert np.array_equal(measured, numba_env(env_id, **kwargs).measured_entries)
    # new samples at the same steps in both (every step without a period)
    new_n = np.any(readings_n[:, 1:] != readings_n[:, :-1], axis=2)
    new_j = np.any(samples_j[:, 1:] != samples_j[:, :-1], axis=2)
    np.testing.assert_array_equal(new_n, new_j)
    period = kwargs.get("sensors", {}).get("state", {}).get("period_s", 0.0)
    if period:
        assert np.all(new_j == np.array([k % 3 == 0 for k in range(1, SENSOR_STEPS + 1)]))
    p_values = {}
    last = SENSOR_STEPS
    for axis in np.flatnonzero(measured):
        for k in (0, last):
            p_values[f"entry {axis} step {k}"] = scipy_stats.ks_2samp(errors_j[:, k, axis], errors_n[:, k, axis]).pvalue
        change_j, change_n = (
            errors_j[:, last, axis] - errors_j[:, 0, axis],
            errors_n[:, last, axis] - errors_n[:, 0, axis],
        )
        p_values[f"entry {axis} change"] = scipy_stats.ks_2samp(change_j, change_n).pvalue
    assert min(p_values.values()) > 1e-3, {k: round(v, 4) for k, v in p_values.items() if v < 0.05}
    # the observation is the reading (its unmeasured entries 0), as the numba env's (to rounding:
    # XLA may compute the reading twice, in two fusions)
    width = errors_n.shape[2]
    np.testing.assert_allclose(obs_j[..., :width][..., measured], samples_j[..., measured], rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(obs_j[..., :width][..., ~measured], 0.0)
    np.testing.assert_array_equal(readings_n[..., ~measured], 0.0)


# ---------------------------------------------------------------------- what is refused
@pytest.mark.parametrize(
    ("env_id", "kwargs", "named"),
    [
        ("LinearSystem-v1", {"sensors": {"state": {"noise_std": 0.01}}}, "sensors"),
        ("FuelSlosh-v1", {"conditions": NO_SENSORS, "sensors": {"state": {"noise_std": 0.01}}}, "flight conditions"),
        (
            "LinearSystem-v0",
            {
                "conditions": {"base": "flight", "sensors": 0},
                "faults": [{"kind": "bias", "target": "sensor", "sensor": "state", "index": "random", "value": 0.1}],
            },
            "only on flight conditions' sensors",
        ),
        ("FuelSlosh-v0", {"conditions": {"parameters": 7.0}}, "below 90 %"),
    ],
)
def test_make_names_what_is_not_modeled(env_id, kwargs, named):
    with pytest.raises(ValueError, match=named) as err:
        make(env_id, **kwargs)
    assert "\n" not in str(err.value)


def test_lab_params_and_state_carry_no_flight():
    for env_id, module in (("LinearSystem-v1", linear_system), ("FuelSlosh-v1", fuel_slosh)):
        env, params = make(env_id)
        _, state = env.reset(jax.random.PRNGKey(0), params)
        assert env.flight is None and not env.sensors
        assert params.flight is None and params.sensors is None and state.flight is None and state.sensors is None
        with pytest.raises(ValueError, match="flight env"):
            module.with_drawn_parameters(params, {})
