"""The JAX FuelSlosh plant (attitude_envs.jax.fuel_slosh) against the numba env, and its gymnax
API. Equality runs under ``jax.enable_x64`` (a context, never the global config): the same
episodes step by step, observations to float32 rounding.

Tolerances. XLA's CPU backend always contracts ``a·b + c`` into fused multiply-adds (its LLVM
target allows FP-op fusion unconditionally); the numba kernel rounds each product. The two
implementations therefore differ by an ulp here and there, and the plant amplifies that in three
places: the open-loop pitch integrates Ω̇'s rounding twice (θ drifts ~1e-13–1e-12 rad over a
100 s episode of the random actions below), the body-frame velocities ``[v_x, v_z]`` rotate a
~3000 m/s vector with θ (a component passing near zero keeps the vector's absolute rounding),
and the new input ``a_z = v̇_z − Ω v_x`` cancels two terms ~1e4 times its size, so the stage
cost's rounding is amplified ~1e2 over an ulp. Measured on the episodes below (x64, an FMA CPU):
state 1.1e-13, cost/reward 3.8e-13 at worst. The state is compared relative to max(1, |y_i|,
the norm of the 2-vector (X, Z) or (v_x, v_z) it belongs to) and cost and reward relative,
both at 1e-12.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml

from attitude_envs.jax import fuel_slosh, make
from attitude_envs.jax.make import numba_env
from attitude_envs.plants import slosh

STATE_TOL = 1e-12
COST_TOL = 1e-12  # the same bound as the state: cost error measured 3.8e-13
V1_STEPS = 400  # FuelSlosh-v1: 100 s of 0.25 s decisions
V0_STEPS = 200  # FuelSlosh-v0: 20 s of 0.1 s decisions (the preset's episode is 1500 s)
_CAMPAIGN = Path(__file__).resolve().parents[1] / "experiments" / "campaigns" / "slosh.yml"


def _campaign_faults() -> list[dict]:
    """The thruster faults of the slosh campaign (the packaged scenario slosh-actuator-faults)."""
    spec = yaml.safe_load(_CAMPAIGN.read_text())
    (fs,) = [e for e in spec["envs"] if e["name"] == "fs"]  # the lab cell (fs-flight: its flight twin)
    faults = fs["faults"]["actuator-faults-50s"]
    assert {f["kind"] for f in faults} == {"loss_of_effectiveness", "bias"}
    return faults


def _pair(env_id: str, **kwargs):
    """The numba env of ``env_id`` and the JAX plant and params ``make`` builds without it."""
    return (numba_env(env_id, **kwargs), *make(env_id, **kwargs))


def _wandering(rng: np.random.Generator, n: int, amplitude: float) -> np.ndarray:
    """Random actions whose sums stay bounded (differences of i.i.d. uniforms): they excite
    the slosh and pitch all episode without a random walk of Ω that would end it early."""
    u = rng.uniform(-amplitude, amplitude, (n + 1, 2))
    return np.diff(u, axis=0)


def _rollout(env):
    """A jitted scan of ``env.step_env`` (no autoreset) over actions and keys: one compile
    per static layout (the params are an argument)."""

    def run(state, params, actions, keys):
        def body(s, inp):
            a, k = inp
            obs, s2, reward, terminated, info = env.step_env(k, s, a, params)
            out = {
                "obs": obs,
                "y": s2.y,
                "reward": reward,
                "cost": info["cost"],
                "terminated": terminated,
                "truncated": env.is_truncated(s2, params) & ~terminated,
                "time_s": info["time_s"],
                "applied": info["applied"],
                "new_inputs": info["new_inputs"],
            }
            return s2, out

        return jax.lax.scan(body, state, (actions, keys))[1]

    return jax.jit(run)


def _state_err(ref: np.ndarray, got: np.ndarray) -> float:
    """Max of |Δy_i| / max(1, |y_i|, norm of y_i's 2-vector: position or body velocity)."""
    scale = np.maximum(1.0, np.abs(ref))
    for pair in ((slosh.IX, slosh.IZ), (slosh.IVX, slosh.IVZ)):
        scale[list(pair)] = np.maximum(scale[list(pair)], np.hypot(*ref[list(pair)]))
    return float(np.max(np.abs(got - ref) / scale))


def _rel(ref, got) -> float:
    ref, got = np.asarray(ref, float), np.asarray(got, float)
    return float(np.max(np.abs(got - ref) / np.maximum(np.abs(ref), 1e-300)))


def _compare(ne, env, params, run, actions: np.ndarray, seed: int) -> dict:
    """Reset ``ne`` with ``seed``, step it and the JAX plant (from ``state_from``) with
    ``actions`` until the numba episode ends, asserting equality at every step. Returns the
    step the episode ended at, its flags and the max errors."""
    ne.reset(seed=seed)
    state = env.state_from(ne)
    np.testing.assert_array_equal(np.asarray(state.y), ne.state)
    keys = jax.random.split(jax.random.PRNGKey(seed), len(actions))
    out = jax.tree.map(np.asarray, run(state, params, jnp.asarray(actions), keys))
    err = {"state_err": 0.0, "cost_err": 0.0, "new_inputs_err": 0.0}
    for i, a in enumerate(actions):
        obs, reward, terminated, truncated, info = ne.step(a)
        truth = info["truth"]
        err["state_err"] = max(err["state_err"], _state_err(ne.state, out["y"][i]))
        err["cost_err"] = max(err["cost_err"], _rel(info["cost"], out["cost"][i]), _rel(reward, out["reward"][i]))
        new_inputs_err = float(np.max(np.abs(truth["new_inputs"] - out["new_inputs"][i])))
        err["new_inputs_err"] = max(err["new_inputs_err"], new_inputs_err)
        assert err["state_err"] <= STATE_TOL and err["cost_err"] <= COST_TOL, (i, err)
        applied_err = np.abs(out["applied"][i] - truth["applied"]) / np.maximum(1.0, np.abs(truth["applied"]))
        assert np.all(applied_err <= STATE_TOL), (i, out["applied"][i], truth["applied"])
        assert out["time_s"][i] == info["time_s"], i
        assert (bool(out["terminated"][i]), bool(out["truncated"][i])) == (terminated, truncated), i
        # the numba obs is the float32 of the same numbers: equal to float32 rounding (one ulp);
        # on a limit crossing the numba env clips it to its box (the JAX step_env does not)
        got = ne.clip_observation(out["obs"][i]) if terminated else out["obs"][i]
        assert obs.shape == got.shape
        assert np.all(np.abs(got - obs) <= np.spacing(np.abs(obs))), (i, got, obs)
        if terminated or truncated:
            return {
                "end": i,
                "terminated": terminated,
                "truncated": truncated,
                "cost": info["cost"],
                "info": info,
                **err,
            }
    return {"end": None, "terminated": False, "truncated": False, **err}


@pytest.fixture(scope="module")
def v1_faults():
    """FuelSlosh-v1 with the campaign's thruster faults (from 50 s) and the fault flags."""
    with jax.enable_x64(True):
        ne, env, params = _pair("FuelSlosh-v1", faults=_campaign_faults(), fault_hint=True)
        return ne, env, params, _rollout(env)


@pytest.fixture(scope="module")
def v0_env():
    """FuelSlosh-v0 (fixed start, ``termination_cost="hold"``), observing ``[v_z, θ, Ω, v_x]``."""
    with jax.enable_x64(True):
        ne, env, params = _pair("FuelSlosh-v0", observe_slosh=False)
        return ne, env, params, _rollout(env)


def test_v1_whole_episode_with_campaign_faults(v1_faults):
    """A whole v1 episode (400 decisions, truncated at 100 s); from 50 s the gimbal delivers
    half its angle and the moment actuator adds 200 N·m, which the actions cancel (else Ω
    crosses its limit within a few decisions)."""
    ne, env, params, run = v1_faults
    assert env.n_substeps == 5 and int(params.max_steps_in_episode) == V1_STEPS
    actions = _wandering(np.random.default_rng(0), V1_STEPS, 0.01)
    onset = int(50.0 / ne.control_dt_s)
    actions[onset:, 1] -= 200.0 / ne.model.max_moment_nm
    with jax.enable_x64(True):
        res = _compare(ne, env, params, run, actions, seed=0)
    assert (res["end"], res["truncated"], res["terminated"]) == (V1_STEPS - 1, True, False), res
    limits = ne.actuator_limits
    expected = np.clip(actions[-1], -1.0, 1.0) * limits * [0.5, 1.0] + [0.0, 200.0]
    np.testing.assert_allclose(res["info"]["truth"]["applied"], expected, rtol=1e-12)
    assert res["info"]["truth"]["faults"] and all(f["active"] for f in res["info"]["truth"]["faults"])


def test_v1_termination_charge(v1_faults):
    """Full pitch moment: Ω crosses its limit within a few decisions; the step is charged
    ``T·xᵀQx`` (``termination_cost="episode"``) on top of its running cost."""
    ne, env, params, run = v1_faults
    actions = np.tile([0.3, 1.0], (V1_STEPS, 1))
    with jax.enable_x64(True):
        res = _compare(ne, env, params, run, actions, seed=1)
    assert res["terminated"] and res["end"] < 10, res
    assert abs(ne.state[slosh.IOM]) > ne.max_pitch_rate_rad_s
    x = ne.state[list(fuel_slosh.REDUCED_INDEX)]
    charge = ne.episode_duration_s * float(x @ ne.model.cost.Q @ x)
    assert res["cost"] > charge > 0.0


def test_v0_fixed_start(v0_env):
    ne, env, params, run = v0_env
    assert env.n_substeps == 2 and env.obs_size == 4
    actions = _wandering(np.random.default_rng(2), V0_STEPS, 0.05)
    with jax.enable_x64(True):
        res = _compare(ne, env, params, run, actions, seed=2)
        # the fixed start (Table 4), not a draw
        _, state = jax.jit(env.reset_env)(jax.random.PRNGKey(5), params)
    assert res["end"] is None, res
    np.testing.assert_array_equal(np.asarray(state.y)[list(fuel_slosh.INITIAL_ORDER)], ne.initial_state)


def test_v0_slosh_limit_hold_charge(v0_env):
    """A slosh limit of 35° (ψ1 starts at 30°) crossed under full gimbal (the moment
    countering its pitch torque): charged ``(T − t)·xᵀQx``. Same static layout as the v0 env:
    its compiled rollout, other params (limits)."""
    _, env, _, run = v0_env
    with jax.enable_x64(True):
        ne, env2, params = _pair(
            "FuelSlosh-v0", observe_slosh=False, max_slosh_angle_deg=35.0, max_pitch_rate_rad_s=1.0
        )
        assert (env2.n_substeps, env2.obs_index, env2.n_faults) == (env.n_substeps, env.obs_index, env.n_faults)
        actions = np.tile([-1.0, 0.5], (V0_STEPS, 1))
        res = _compare(ne, env, params, run, actions, seed=3)
    assert res["terminated"], res
    assert max(abs(ne.state[slosh.IPSI1]), abs(ne.state[slosh.IPSI2])) > ne.max_slosh_angle_rad
    assert abs(ne.state[slosh.IOM]) <= ne.max_pitch_rate_rad_s  # the slosh limit ended it
    x = ne.state[list(fuel_slosh.REDUCED_INDEX)]
    t = (res["end"] + 1) * ne.control_dt_s
    assert res["cost"] > (ne.episode_duration_s - t) * float(x @ ne.model.cost.Q @ x) > 0.0


@pytest.mark.parametrize(("duration", "dt"), [(0.7, 0.1), (0.3, 0.1), (1.0, 0.3)])
def test_time_limit_matches_numba(duration, dt):
    """``max_steps_in_episode`` reproduces the numba env's test ``t >= T − 1e-9·Δt`` (s)."""
    ne, _, params = _pair("FuelSlosh-v0", episode_duration_s=duration, control_dt_s=dt)
    ne.reset(seed=0)
    steps = 1
    while not ne.step(np.zeros(2))[3]:
        steps += 1
    assert int(params.max_steps_in_episode) == steps


# ---------------------------------------------------------------------- gymnax API (float32)
RANDOM_FAULT = {"kind": "loss_of_effectiveness", "index": "random", "value": {"uniform": [0.2, 0.8]}}


@pytest.fixture(scope="module")
def api_env():
    """FuelSlosh-v1 in the default dtype (x64 off)."""
    return make("FuelSlosh-v1")


def test_reset_step_shapes_and_autoreset(api_env):
    env, params = api_env
    key = jax.random.PRNGKey(0)
    obs, state = env.reset(key, params)
    assert obs.shape == (8,) == env.observation_space(params).shape and obs.dtype == jnp.float32
    assert state.y.shape == (10,) and int(state.time) == 0
    assert env.action_space(params).shape == (2,) and env.num_actions == 2
    assert bool(env.observation_space(params).contains(obs))
    # a mid-episode step does not reset
    k = jax.random.PRNGKey(1)
    action = jnp.array([0.1, -0.1])
    obs1, state1, reward, terminated, truncated, info = env.step(k, state, action, params)
    assert int(state1.time) == 1 and not bool(terminated | truncated)
    assert reward.shape == () and float(reward) == -float(info["cost"]) < 0.0
    np.testing.assert_array_equal(obs1, state1.y[np.array(env.obs_index)])
    np.testing.assert_array_equal(info["final_observation"], obs1)
    # the same step one decision before the time limit truncates and autoresets
    last = state.replace(time=params.max_steps_in_episode - 1)
    obs2, state2, reward2, terminated, truncated, info = env.step(k, last, action, params)
    assert bool(truncated) and not bool(terminated) and bool(info["truncated"])
    assert float(info["time_s"]) == pytest.approx(100.0) and float(reward2) == float(reward)
    np.testing.assert_array_equal(info["final_observation"], obs1)  # the episode's last observation
    obs_re, state_re = env.reset(jax.random.split(k)[1], params)  # a fresh episode from the step's key
    np.testing.assert_array_equal(obs2, obs_re)
    np.testing.assert_array_equal(state2.y, state_re.y)
    assert int(state2.time) == 0 and not np.array_equal(state2.y, state1.y)


def test_vmap_over_keys_and_params(api_env):
    """One compiled program over a batch of keys, states, actions and plants (two thrusts);
    each row equals its own unbatched step."""
    env, params = api_env
    k0, k1, k2 = jax.random.split(jax.random.PRNGKey(2), 3)
    keys = jnp.stack([k0, k0, k1, k2])
    batch = jax.tree.map(lambda x: jnp.stack([x] * 4), params)
    thrust = jnp.array([2250.0, 1000.0, 2250.0, 1000.0], params.plant.thrust_n.dtype)
    batch = batch.replace(plant=batch.plant.replace(thrust_n=thrust))
    obs, states = jax.vmap(env.reset)(keys, batch)
    assert obs.shape == (4, 8) and states.y.shape == (4, 10)
    # v1's random start: v_z, θ, ψ1, ψ2 within Table 4's magnitudes
    assert len(np.unique(np.asarray(states.y[:, slosh.IVZ]))) == 3
    assert np.all(np.abs(states.y[:, slosh.IPSI1]) <= np.radians(30.0))
    actions = jnp.full((4, 2), 0.2, jnp.float32)  # strongly typed: the unbatched step reuses its program
    out = jax.vmap(env.step)(keys, states, actions, batch)
    obs2, states2, rewards, terminated, truncated, _ = out
    assert obs2.shape == (4, 8) and rewards.shape == (4,) and terminated.shape == truncated.shape == (4,)
    np.testing.assert_array_equal(states2.time, np.ones(4))
    assert not np.allclose(states2.y[0], states2.y[1])  # same start, other thrust
    for j in range(4):
        row = jax.tree.map(lambda x, j=j: x[j], (keys, states, actions, batch))
        one = env.step(*row)
        np.testing.assert_allclose(states2.y[j], one[1].y, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(rewards[j], one[2], rtol=1e-5)


def test_faults_drawn_per_episode():
    """A fault with random fields is drawn at each reset, from the step's key (the numba
    env's law: a random actuator, a uniform value)."""
    env, params = make("FuelSlosh-v1", faults=[RANDOM_FAULT])
    assert env.redraw_faults
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    faults = jax.tree.map(np.asarray, states.faults)
    assert faults.kind.shape == (16, 1) and np.all(faults.kind == faults.kind[0])
    assert set(faults.index.ravel()) == {0, 1}
    assert len(np.unique(faults.value)) == 16 and np.all((faults.value >= 0.2) & (faults.value <= 0.8))


# ---------------------------------------------------------------------- make
def test_make_rejects_what_is_not_modeled():
    with pytest.raises(ValueError, match="sensors"):
        make("FuelSlosh-v1", sensors={"state": {"noise_std": 0.01}})
    sensor_fault = {"kind": "bias", "target": "sensor", "sensor": "state", "index": 0, "value": 0.1}
    with pytest.raises(ValueError, match="flight conditions' sensors"):
        make("FuelSlosh-v0", faults=[sensor_fault])
    env, params = make("attitude_envs/FuelSlosh-v0")
    assert isinstance(env, fuel_slosh.FuelSloshEnv) and int(params.max_steps_in_episode) == 15000


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        ("FuelSlosh-v0", {}),
        ("FuelSlosh-v1", {"faults": _campaign_faults(), "fault_hint": True}),
        ("FuelSlosh-v0", {"preset": "navabi-fill-iii", "observe_slosh": False, "max_slosh_angle_deg": 35.0}),
    ],
)
def test_standalone_params_are_the_numba_envs_numbers(env_id, kwargs):
    """``make`` builds the params without a numba env: each leaf is the numba env's number,
    exactly (x64); the static layout is the numba env's; the groups default to FuelSlosh-v0's."""
    with jax.enable_x64(True):
        ne, env, params = _pair(env_id, **kwargs)
        p = ne.model.params
        expected = [(getattr(params.plant, k), getattr(p, k)) for k in ("mass_kg", "slosh_mass_kg", "thrust_n", "d_m")]
        expected += [
            (params.plant.actuator_limits, ne.actuator_limits),
            (params.timing.control_dt_s, ne.control_dt_s),
            (params.timing.integrator_dt_s, ne.integrator_dt_s),
            (params.cost.Q, ne.model.cost.Q),
            (params.cost.R, ne.model.cost.R),
            (params.cost.max_slosh_angle_rad, ne.max_slosh_angle_rad),
            (params.cost.max_pitch_rate_rad_s, ne.max_pitch_rate_rad_s),
            (params.cost.max_pitch_angle_rad, ne.max_pitch_angle_rad),
            (params.cost.horizon_s, ne.episode_duration_s),
            (params.start.initial_state, ne.initial_state),
        ]
        for got, want in expected:
            assert got.dtype == jnp.float64
            np.testing.assert_array_equal(got, want)
        assert env.obs_index == tuple(ne.observation_index) and env.n_hint_flags == ne.n_hint_flags
        np.testing.assert_array_equal(np.float32(env.observation_space(params).high), ne.observation_space.high)
        default = fuel_slosh.EnvParams()
        v0 = make("FuelSlosh-v0")[1]
        assert jax.tree.all(jax.tree.map(np.array_equal, default, v0))
