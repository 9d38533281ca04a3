"""Sensor faults in the JAX twins (:mod:`attitude_envs.jax.sensors`) against the numba
sensor layer (:class:`attitude_envs.sensors.SensorSuite`): every kind, on a vector and an
attitude channel, reading for reading under x64 (noise off, a sample period that holds
readings between samples); the noise increase in distribution; and what is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
import jax.numpy as jnp  # noqa: E402

from attitude_envs import quaternion  # noqa: E402
from attitude_envs.jax import make  # noqa: E402
from attitude_envs.jax import sensors as jsens  # noqa: E402
from attitude_envs.sensors import Channel, SensorSuite  # noqa: E402

VECTOR_FAULTS = [
    {"kind": "bias", "target": "sensor", "sensor": "rate", "index": 0, "value": 0.1, "onset_s": 0.3},
    {
        "kind": "drift",
        "target": "sensor",
        "sensor": "rate",
        "index": 1,
        "value": 0.05,
        "onset_s": 0.5,
        "duration_s": 1.0,
    },
    {"kind": "stuck", "target": "sensor", "sensor": "rate", "index": 2, "onset_s": 0.7, "duration_s": 0.6},
    {
        "kind": "stuck",
        "target": "sensor",
        "sensor": "rate",
        "index": 0,
        "value": -2.0,
        "onset_s": 2.0,
        "duration_s": 0.3,
    },
    {"kind": "dropout", "target": "sensor", "sensor": "rate", "index": 1, "onset_s": 1.8, "duration_s": 0.4},
    {"kind": "dropout", "target": "sensor", "sensor": "rate", "index": "all", "mode": "hold", "onset_s": 2.5},
    {"kind": "bias", "target": "sensor", "sensor": "star", "index": 2, "value": 0.01, "onset_s": 0.2},
    {"kind": "stuck", "target": "sensor", "sensor": "star", "index": "all", "onset_s": 0.9, "duration_s": 0.5},
    {"kind": "dropout", "target": "sensor", "sensor": "star", "index": "all", "mode": "hold", "onset_s": 1.6},
]
CHANNELS = [Channel("rate", 3), Channel("star", 4, "attitude")]
#: the action sizes of the envs whose episodes the observation tests play
ACTIONS = {"LinearSystem-v1": 3, "FuelSlosh-v1": 2, "ReactionWheel-v1": 4}
NOISELESS = {
    "rate": {"noise_std": 0.0},
    "star": {"noise_std": 0.0, "period_s": 0.2, "initial_bias": [1e-3, 0.0, -2e-3]},
}


def _truths(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` times' rates (a smooth curve) and attitudes (a slow turn)."""
    t = 0.1 * np.arange(n)
    rates = np.stack([np.sin(t), np.cos(2 * t), 0.1 * t], axis=1)
    attitudes = np.array([quaternion.from_rotvec(np.array([0.3, -0.2, 0.5]) * ti) for ti in t])
    return rates, attitudes


def _observations(env_id: str, kwargs: dict, module, actions: np.ndarray):
    """The numba env's observations of one episode from seed 0 under ``actions`` (until it
    ends) and the JAX twin's from its reset, given the numba episode's drawn parameters
    (``module.with_drawn_parameters``): ``(numba (k, n), JAX (k, n), the numba env)``, x64."""
    from attitude_envs.jax.make import numba_env

    ne = numba_env(env_id, **kwargs)
    obs0, _ = ne.reset(seed=0)
    want = [obs0]
    for a in actions:
        obs, _, terminated, truncated, _ = ne.step(a)
        want.append(obs)
        if terminated or truncated:
            break
    with jax.enable_x64(True):
        env, params = make(env_id, **kwargs)
        params = module.with_drawn_parameters(params, ne.drawn_parameters())
        o, s = env.reset(jax.random.PRNGKey(0), params)
        step = jax.jit(env.step_env)
        got = [np.asarray(o)]
        for i, a in enumerate(actions[: len(want) - 1]):
            o, s, *_ = step(jax.random.PRNGKey(i), s, jnp.asarray(a), params)
            got.append(np.asarray(o))
    return np.array(want), np.array(got), ne


def test_every_fault_kind_reads_as_the_numba_layer():
    """Bias, drift, stuck (at the reading and at a value), dropout
    (NaN and hold) on a vector channel; bias, stuck and dropout hold of the whole attitude of
    a star tracker sampling every other step: 36 observations, every vector reading equal (NaN
    where the numba layer reads NaN), the attitudes to an ulp."""
    n = 36
    rates, attitudes = _truths(n)
    suite = SensorSuite(NOISELESS, CHANNELS, VECTOR_FAULTS)
    suite.reset(np.random.default_rng(0))
    want = [
        suite.measure({"rate": r, "star": q}, 0.1 * i) for i, (r, q) in enumerate(zip(rates, attitudes, strict=True))
    ]
    with jax.enable_x64(True):
        faults = jsens.channel_faults(suite, jnp.float64, "test")
        params = {
            "rate": jsens.params_of(suite.config["rate"], 3, jnp.float64, faults["rate"]),
            "star": jsens.params_of(suite.config["star"], 3, jnp.float64, faults["star"]),
        }
        key = jax.random.PRNGKey(0)
        for name, truth, attitude in (("rate", rates, False), ("star", attitudes, True)):
            p = params[name]
            s = jsens.initial_state(key, p, jnp.asarray(truth[0]))
            measure = jax.jit(lambda s, x, t, tl, p=p, a=attitude: jsens.measure(key, p, s, x, t, tl, a))
            t_last = 0.0
            for i in range(n):
                m, s = measure(s, jnp.asarray(truth[i]), 0.1 * i, t_last)
                t_last = 0.1 * i
                if attitude:  # the quaternion product: XLA may order its sums otherwise (an ulp)
                    np.testing.assert_allclose(
                        np.asarray(m), want[i][name], rtol=1e-15, atol=1e-17, err_msg=f"step {i}"
                    )
                else:
                    np.testing.assert_array_equal(np.asarray(m), want[i][name], err_msg=f"{name} at step {i}")
    # the faults acted: a NaN, a stuck value, a held attitude
    assert np.isnan(want[19]["rate"][1]) and want[20]["rate"][0] == -2.0
    assert np.array_equal(want[10]["star"], want[12]["star"])


def test_noise_increase_scales_the_noise_on_its_axis():
    """``noise_increase`` of 3 on axis 1 from 0.5 s: that axis' noise three times the others'
    (2,000 keys), before the onset all alike."""
    config = {"rate": {"noise_std": 0.1}}
    fault = [{"kind": "noise_increase", "target": "sensor", "sensor": "rate", "index": 1, "value": 3.0, "onset_s": 0.5}]
    suite = SensorSuite(config, [Channel("rate", 3)], fault)
    with jax.enable_x64(True):
        p = jsens.params_of(
            suite.config["rate"], 3, jnp.float64, jsens.channel_faults(suite, jnp.float64, "test")["rate"]
        )
        truth = jnp.zeros(3)

        def reading(key, t):
            s = jsens.initial_state(key, p, truth)
            return jsens.measure(key, p, s, truth, t, 0.0, False)[0]

        keys = jax.random.split(jax.random.PRNGKey(0), 2000)
        before = np.asarray(jax.vmap(reading, in_axes=(0, None))(keys, 0.2))
        after = np.asarray(jax.vmap(reading, in_axes=(0, None))(keys, 1.0))
    np.testing.assert_allclose(before.std(axis=0), 0.1, rtol=0.06)
    np.testing.assert_allclose(after.std(axis=0), [0.1, 0.3, 0.1], rtol=0.06)


DRAWN_FAULTS = [
    {
        "kind": "bias",
        "target": "sensor",
        "sensor": "rate",
        "index": "random",
        "value": {"uniform": [0.1, 0.3]},
        "onset_s": {"uniform": [1.0, 5.0]},
        "duration_s": {"uniform": [0.5, 2.0]},
    },
    {
        "kind": "drift",
        "target": "sensor",
        "sensor": "rate",
        "index": "all",
        "value": {"uniform": [-1.0, 1.0]},
        "onset_s": {"uniform": [0.0, 3.0]},
    },
    {
        "kind": "dropout",
        "target": "sensor",
        "sensor": "star",
        "index": "all",
        "mode": "hold",
        "onset_s": 2.0,
        "duration_s": {"uniform": [1.0, 4.0]},
    },
]


def test_faults_drawn_per_episode_follow_the_numba_law():
    """Axes, values, onsets and ends drawn at each reset: 3,000 JAX draws against 3,000 numba
    resets (two-sample KS, p > 0.001; the random axis' frequencies within 0.05 of a third);
    one onset and end per fault dict, one value per expanded axis, as the numba layer draws
    them; the fixed entries stay as given."""
    scipy_stats = pytest.importorskip("scipy.stats")
    n = 3000
    suite = SensorSuite(NOISELESS, CHANNELS, DRAWN_FAULTS)
    ref = {k: [] for k in ("axis", "value0", "onset0", "length0", "value1", "onset1", "end2")}
    for seed in range(n):
        suite.reset(np.random.default_rng(seed))
        r = suite.realized
        ref["axis"].append(r[0].index)
        ref["value0"].append(r[0].value)
        ref["onset0"].append(r[0].onset_s)
        ref["length0"].append(r[0].duration_s)
        ref["value1"].append(r[1].value)
        ref["onset1"].append(r[1].onset_s)
        ref["end2"].append(r[4].onset_s + r[4].duration_s)
        assert r[1].onset_s == r[2].onset_s == r[3].onset_s  # one onset per fault dict
    with jax.enable_x64(True):
        faults = jsens.channel_faults(suite, jnp.float64, "test")
        keys = jax.random.split(jax.random.PRNGKey(0), n)
        rate = jax.vmap(jsens.realize, in_axes=(0, None))(keys, faults["rate"])
        star = jax.vmap(jsens.realize, in_axes=(0, None))(keys, faults["star"])
    got = {
        "axis": np.asarray(rate.index[:, 0]),
        "value0": np.asarray(rate.value[:, 0]),
        "onset0": np.asarray(rate.onset_s[:, 0]),
        "length0": np.asarray(rate.end_s[:, 0] - rate.onset_s[:, 0]),
        "value1": np.asarray(rate.value[:, 1]),
        "onset1": np.asarray(rate.onset_s[:, 1]),
        "end2": np.asarray(star.end_s[:, 0]),
    }
    for key in ("value0", "onset0", "length0", "value1", "onset1", "end2"):
        assert scipy_stats.ks_2samp(got[key], ref[key]).pvalue > 1e-3, key
    for axis in range(3):
        assert abs(np.mean(got["axis"] == axis) - 1 / 3) < 0.05
    np.testing.assert_array_equal(rate.onset_s[:, 1], rate.onset_s[:, 3])  # one onset per dict
    assert np.all(rate.value[:, 1] != rate.value[:, 2])  # one value per axis
    np.testing.assert_array_equal(rate.index[:, 1:], np.tile([0, 1, 2], (n, 1)))
    np.testing.assert_array_equal(star.onset_s, 2.0)
    assert np.all(np.isinf(np.asarray(rate.end_s[:, 1:])))


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        (
            {
                "conditions": {"base": "flight", "sensors": 0},
                "faults": [{"kind": "bias", "target": "sensor", "sensor": "state", "index": 0, "value": 0.1}],
            },
            "flight conditions' sensors",
        ),
    ],
)
def test_make_names_the_sensor_faults_not_modeled(kwargs, named):
    with pytest.raises(ValueError, match=named) as err:
        make("LinearSystem-v1", **{"conditions": "flight", **kwargs})
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("fault_hint", [False, True])
def test_linear_system_flight_cell_faults_as_the_numba_env(fault_hint):
    """LinearSystem-v1 under flight conditions with a noiseless state sensor, its flight cell's
    outage (the state sensor holding its last sample for 100 s) and a bias on entry 3: from the
    paper's start (the numba episode's drawn gains given to the JAX reset), every observation
    of a whole episode equals the numba env's to float32 rounding (x64), and the outage held;
    with ``fault_hint`` the sensor's flag among them."""
    from attitude_envs.jax import linear_system

    faults = [
        {
            "kind": "dropout",
            "target": "sensor",
            "sensor": "state",
            "index": "all",
            "mode": "hold",
            "onset_s": 50.0,
            "duration_s": 100.0,
        },
        {"kind": "bias", "target": "sensor", "sensor": "state", "index": 3, "value": 0.01, "onset_s": 200.0},
    ]
    kwargs = {
        "conditions": "flight",
        "sensors": {"state": {"noise_std": 0.0}},
        "faults": faults,
        "fault_hint": fault_hint,
    }
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (80, ACTIONS["LinearSystem-v1"]))  # 400 s of 5 s decisions
    want, got, ne = _observations("LinearSystem-v1", kwargs, linear_system, actions)
    np.testing.assert_allclose(got, want, rtol=2.0**-23, atol=1e-12)
    n = want.shape[1] - (ne.n_hint_flags if fault_hint else 0)
    held = want[10:30, :n]  # decisions every 5 s: the outage holds the reading of 45 s from 50 s to 150 s
    assert np.all(held == want[9, :n]) and not np.all(want[30, :n] == want[9, :n])
    if fault_hint:  # the state sensor's flag: on through the outage and from the bias on
        np.testing.assert_array_equal(want[:, -1], [1.0 if 10 <= k < 30 or k >= 40 else 0.0 for k in range(len(want))])


def test_drawn_faults_hold_through_an_episode_and_redraw_at_autoreset():
    """LinearSystem-v1 under flight conditions with a drawn state-sensor outage: each env's
    onset is fixed through its episode (80 decisions), differs between envs and is drawn anew
    by the autoreset; a fixed outage stays in the params (no per-episode state)."""
    drawn = {
        "kind": "dropout",
        "target": "sensor",
        "sensor": "state",
        "index": "all",
        "mode": "hold",
        "onset_s": {"uniform": [10.0, 300.0]},
        "duration_s": 50.0,
    }
    with jax.enable_x64(True):
        env, params = make("LinearSystem-v1", conditions="flight", faults=[drawn])
        keys = jax.random.split(jax.random.PRNGKey(0), 3)
        _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
        step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
        onsets = [np.asarray(state.sensors.channel.faults.onset_s[:, 0])]
        for i in range(int(params.max_steps_in_episode)):
            obs, state, *_ = step(
                jax.random.split(jax.random.PRNGKey(i + 1), 3), state, jnp.zeros((3, env.num_actions)), params
            )
            onsets.append(np.asarray(state.sensors.channel.faults.onset_s[:, 0]))
        _, fixed_params = make("LinearSystem-v1", conditions="flight", faults=[{**drawn, "onset_s": 50.0}])
    onsets = np.array(onsets)
    assert np.all(onsets[:-1] == onsets[0]) and len(set(onsets[0])) == 3  # fixed per episode, differ between envs
    assert np.all(onsets[-1] != onsets[0])  # the autoreset drew them anew
    assert np.all((onsets >= 10.0) & (onsets <= 300.0)) and bool(jnp.all(jnp.isfinite(obs)))
    assert fixed_params.sensors.faults is not None and fixed_params.sensors.faults.draws is None


def test_fuel_slosh_hint_flags_as_the_numba_env():
    """FuelSlosh-v1 under flight conditions from its fixed start, a noiseless state sensor and
    ``fault_hint``: an actuator bias and a bias on the pitch rate's reading each raise their
    flag when the numba env's do (the hint's last entry is the state sensor's), every
    observation equal to float32 rounding (x64)."""
    from attitude_envs.jax import fuel_slosh

    faults = [
        {"kind": "bias", "target": "actuator", "index": 1, "value": 50.0, "onset_s": 2.0, "duration_s": 3.0},
        {"kind": "bias", "target": "sensor", "sensor": "state", "index": 2, "value": 1e-3, "onset_s": 4.0},
    ]
    kwargs = {
        "conditions": "flight",
        "sensors": {"state": {"noise_std": 0.0}},
        "randomize_initial_state": False,
        "episode_duration_s": 8.0,
        "fault_hint": True,
        "faults": faults,
    }
    actions = np.diff(np.random.default_rng(0).uniform(-0.3, 0.3, (33, 2)), axis=0)
    want, got, ne = _observations("FuelSlosh-v1", kwargs, fuel_slosh, actions)
    np.testing.assert_allclose(got, want, rtol=2.0**-23, atol=1e-12)
    flags = want[:, -ne.n_hint_flags :]
    t = 0.25 * np.arange(len(want))
    np.testing.assert_array_equal(flags[:, 1], (t >= 2.0) & (t < 5.0))
    np.testing.assert_array_equal(flags[:, -1], t >= 4.0)


def test_reaction_wheel_hint_flags_as_the_numba_env():
    """ReactionWheel-v1 under flight conditions from a fixed start and target, noiseless
    sensors and ``fault_hint``: a wheel's loss of effectiveness, a gyro bias jump and a star
    tracker outage raise their flags (the actuators', then gyro, star tracker, tachometer)
    when the numba env's do, every observation equal to float32 rounding (x64)."""
    from attitude_envs.jax import gyrostat

    faults = [
        {"kind": "loss_of_effectiveness", "index": 0, "value": 0.5, "onset_s": 1.0},
        {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 2, "value": 1e-3, "onset_s": 2.0},
        {
            "kind": "dropout",
            "target": "sensor",
            "sensor": "star_tracker",
            "index": "all",
            "mode": "hold",
            "onset_s": 3.0,
            "duration_s": 2.0,
        },
    ]
    noiseless = {name: {"noise_std": 0.0} for name in ("gyro", "star_tracker", "tachometer")}
    kwargs = {
        "conditions": "flight",
        "sensors": noiseless,
        "initial_attitude": [0.1, -0.2, 0.05, 0.9733961166965892],
        "initial_rate_rad_s": [0.01, 0.0, -0.01],
        "target_attitude": [0.0, 0.0, 0.0, 1.0],
        "fault_hint": True,
        "faults": faults,
    }
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, (60, ACTIONS["ReactionWheel-v1"]))
    want, got, ne = _observations("ReactionWheel-v1", kwargs, gyrostat, actions)
    np.testing.assert_allclose(got, want, rtol=2.0**-23, atol=1e-12)
    flags = want[:, -ne.n_hint_flags :]
    t = ne.control_dt_s * np.arange(len(want))
    assert t[-1] >= 5.9  # every window opened and closed within the episode
    np.testing.assert_array_equal(flags[:, 0], t >= 1.0)
    np.testing.assert_array_equal(flags[:, -3], t >= 2.0)  # gyro
    np.testing.assert_array_equal(flags[:, -2], (t >= 3.0) & (t < 5.0))  # star tracker
    np.testing.assert_array_equal(flags[:, -1], 0.0)  # tachometer
