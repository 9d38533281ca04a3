"""The fused JAX PPO (agents.fused_ppo) and the ``jax`` training backend: config checks, learning,
vmap over seeds and settings, export to numpy, normalization statistics, train/load/resume.

Compiling a fused program costs seconds, so the tests share three: one vmapped ``train`` on a
tiny env defined here (seeds and settings), its unvmapped chunked form (separate runs, learning,
export), and the chunked program ``train(backend="jax")`` compiles for LinearSystem-v1 (cached
for the process: the resume tests reuse it)."""

from __future__ import annotations

import csv
import dataclasses
import json
import shutil
import sys

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("flax")
pytest.importorskip("optax")

import gymnasium as gym  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import yaml  # noqa: E402
from flax import struct  # noqa: E402

import attitude_envs  # noqa: F401,E402
from agents.fused_ppo import (  # noqa: E402
    Hparams,
    NumpyPPOPolicy,
    PPOConfig,
    from_zoo,
    load_policy,
    make_chunked,
    make_train,
    per_update_episode_means,
    policy_arrays,
    select,
    stack_hparams,
)
from agents.fused_ppo.networks import gaussian_entropy, make_networks  # noqa: E402
from agents.fused_ppo.normalization import RunningMeanStd, normalize_obs  # noqa: E402
from attitude_envs.jax.environment import Environment  # noqa: E402
from attitude_envs.jax.spaces import Box  # noqa: E402


# ---- a tiny env in the gymnax API: two single integrators, x' = x + dt·u, cost Σx² + 0.01Σu² ----
@struct.dataclass
class TinyState:
    x: jax.Array
    time: jax.Array


@struct.dataclass
class TinyParams:
    max_steps_in_episode: int = 20
    dt: float = 0.25


class TwoIntegrators(Environment):
    """Drive two integrators from U(-1, 1)² to 0 with |u| ≤ 1; 20 decisions per episode."""

    @property
    def default_params(self) -> TinyParams:
        return TinyParams()

    def reset_env(self, key, params):
        state = TinyState(jax.random.uniform(key, (2,), minval=-1.0, maxval=1.0), jnp.asarray(0, jnp.int32))
        return state.x.astype(jnp.float32), state

    def step_env(self, key, state, action, params):
        u = jnp.clip(action, -1.0, 1.0)
        x = state.x + params.dt * u
        cost = jnp.sum(state.x**2) + 0.01 * jnp.sum(u**2)
        new = TinyState(x, state.time + 1)
        return x.astype(jnp.float32), new, -cost, jnp.asarray(False), {"cost": cost, "time_s": new.time * params.dt}

    def action_space(self, params=None) -> Box:
        return Box(-1.0, 1.0, (2,))

    def observation_space(self, params=None) -> Box:
        return Box(-np.inf, np.inf, (2,))


TINY_ENTRY = {
    "n_envs": 8,
    "n_steps": 20,
    "batch_size": 80,
    "n_epochs": 10,
    "gamma": 0.9,
    "learning_rate": 3e-3,
    "normalize": True,
    "policy_kwargs": "dict(log_std_init=-0.5, net_arch=dict(pi=[], vf=[16]))",
}
VMAP_UPDATES = 3  # updates of the vmapped train (its equality with separate runs)
FAST = {"xla_backend_optimization_level": 0}  # a third less compile time; these programs run for seconds


@pytest.fixture(scope="module", autouse=True)
def fast_compile():
    """``train(backend="jax")`` compiles as the tiny programs here do (FAST)."""
    from experiments.training.jax_training import FAST_COMPILE_ENV

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(FAST_COMPILE_ENV, "1")
        yield


@pytest.fixture(scope="module")
def tiny():
    env = TwoIntegrators()
    config, hp = from_zoo(TINY_ENTRY, total_timesteps=VMAP_UPDATES * 160)
    chunked = make_chunked(env, env.default_params, config)
    return {
        "env": env,
        "params": env.default_params,
        "config": config,
        "hp": hp,
        "init": jax.jit(chunked.init, compiler_options=FAST),
        "chunk": jax.jit(chunked.update_chunk, compiler_options=FAST),
        "vtrain": jax.jit(jax.vmap(make_train(env, env.default_params, config)), compiler_options=FAST),
    }


@pytest.fixture(scope="module")
def learned(tiny):
    """A run of 30 updates (4800 env steps) in 6 chunks: the episode return of each chunk."""
    state = tiny["init"](jax.random.PRNGKey(0), tiny["hp"])
    returns, episodes = [], 0.0
    for _ in range(6):
        state, metrics = tiny["chunk"](state, tiny["hp"], 5)
        returns.append(float(metrics["episode_return"]))
        episodes += float(metrics["episodes"])
    return {"state": state, "returns": returns, "episodes": episodes}


# ---- config ---------------------------------------------------------------------------------
def test_a_zoo_entry_means_what_it_means_to_sb3():
    from experiments.training.hyperparams import load_hyperparams

    config, hp = from_zoo(load_hyperparams("ppo", "attitude_envs/AirBearing-v1"))
    assert (config.n_envs, config.n_steps, config.batch_size, config.n_epochs) == (8, 40, 80, 10)
    assert config.pi_arch == () and config.vf_arch == (64, 64) and config.activation == "tanh" and config.ortho_init
    assert config.norm_obs and config.norm_reward and (config.clip_obs, config.clip_reward) == (10.0, 10.0)
    assert config.lr_schedule == "linear" and config.clip_schedule == "constant" and config.clip_vf_schedule is None
    assert config.total_timesteps == 120_000 and config.num_updates == 375
    assert hp.learning_rate == pytest.approx(3e-4) and hp.gamma == 0.96 and hp.gae_lambda == 0.95
    assert (hp.clip_range, hp.ent_coef, hp.vf_coef, hp.max_grad_norm, hp.log_std_init) == (0.2, 0.0, 0.5, 0.5, -1.0)
    wheel, hp = from_zoo(load_hyperparams("ppo", "attitude_envs/ReactionWheel-v1"))  # gSDE, redrawn every 4 steps
    assert wheel.use_sde and wheel.sde_sample_freq == 4 and hp.log_std_init == -2.0 and not config.use_sde
    defaults, _ = from_zoo({"policy_kwargs": "dict(net_arch=[32], activation_fn=nn.ReLU)", "normalize": False})
    assert defaults.pi_arch == defaults.vf_arch == (32,) and defaults.activation == "relu"
    assert not defaults.norm_obs and (defaults.n_steps, defaults.batch_size) == (2048, 64)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"use_sde": "yes"}, "use_sde must be true or false"),
        ({"use_sde": True, "sde_sample_freq": -2}, "sde_sample_freq must be an integer >= -1"),
        ({"train_freq": 4}, r"hyperparameters \['train_freq'\] not supported"),
        ({"gamma": 1.5}, r"gamma must be in \(0.0, 1.0\], got 1.5"),
        ({"gae_lambda": -0.1}, r"gae_lambda must be in \[0.0, 1.0\]"),
        ({"learning_rate": "lin_x"}, "learning_rate schedule must look like lin_<float>"),
        ({"learning_rate": -1e-3}, "learning_rate must be > 0"),
        ({"clip_range": 0}, "clip_range must be > 0"),
        ({"batch_size": 1}, "batch_size must be an integer >= 2"),
        ({"n_envs": 0}, "n_envs must be an integer >= 1"),
        ({"n_steps": 2.5}, "n_steps must be an integer >= 1"),
        ({"max_grad_norm": 0}, "max_grad_norm must be > 0"),
        ({"frame_stack": 4}, "frame_stack 4 is not supported"),
        ({"policy": "CnnPolicy"}, "policy must be 'MlpPolicy'"),
        ({"policy_kwargs": "dict(net_arch=dict(pi=[0]))"}, r"net_arch.pi\[0\] must be an integer >= 1"),
        ({"policy_kwargs": "dict(net_arch=dict(qf=[64]))"}, r"net_arch accepts the keys \['pi', 'vf'\]"),
        ({"policy_kwargs": "dict(optimizer_class=1)"}, r"policy_kwargs keys \['optimizer_class'\] not supported"),
        ({"policy_kwargs": "dict(activation_fn=nn.Softplus)"}, "activation_fn must be one of"),
        ({"normalize": "{'gamma': 0.9}"}, r"normalize keys \['gamma'\] not supported"),
        ({"normalize": "{'clip_obs': -1}"}, "normalize.clip_obs must be > 0"),
        ({"target_kl": 0}, "target_kl must be > 0"),
    ],
)
def test_bad_hyperparameters_are_named(entry, message):
    with pytest.raises(ValueError, match=message):
        from_zoo(entry)


def test_the_backend_is_checked(monkeypatch):
    from experiments.training.algorithm import check_backend

    assert check_backend("JAX", "ppo") == "jax"
    with pytest.raises(ValueError, match=r"backend 'jax' implements \['ppo'\], not 'sac'"):
        check_backend("jax", "sac")
    monkeypatch.setitem(sys.modules, "optax", None)  # as if not installed
    with pytest.raises(ValueError, match=r"missing: optax\): pip install 'attitude-envs\[jax\]'"):
        check_backend("jax", "ppo")


# ---- normalization ----------------------------------------------------------------------------
def test_running_statistics_match_numpy_on_the_same_data(rng):
    data = [rng.normal(3.0, 2.0, size=(n, 4)) * np.array([1.0, 10.0, 0.1, 1e3]) for n in (1, 8, 8, 3, 50)]
    rms = RunningMeanStd.create((4,))
    for batch in data:
        rms = rms.update(jnp.asarray(batch, jnp.float32))
    every = np.concatenate(data)
    prior = 1e-4  # SB3's prior: mean 0, variance 1, count 1e-4
    n = len(every)
    mean = every.mean(0) * n / (n + prior)
    var = (every.var(0) * n + prior + every.mean(0) ** 2 * n * prior / (n + prior)) / (n + prior)
    np.testing.assert_allclose(np.asarray(rms.mean), mean, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(rms.var), var, rtol=2e-4)
    assert float(rms.count) == pytest.approx(n + prior)
    sb3 = pytest.importorskip("stable_baselines3.common.running_mean_std")
    ref = sb3.RunningMeanStd(shape=(4,))
    for batch in data:
        ref.update(batch)
    np.testing.assert_allclose(np.asarray(rms.mean), ref.mean, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(rms.var), ref.var, rtol=2e-4)
    obs = every[:5]
    expected = np.clip((obs - ref.mean) / np.sqrt(ref.var + 1e-8), -10, 10)
    np.testing.assert_allclose(
        np.asarray(normalize_obs(rms, jnp.asarray(obs, jnp.float32), 10.0, 1e-8)), expected, rtol=1e-3, atol=1e-4
    )


# ---- learning, vmap ---------------------------------------------------------------------------
def test_ppo_learns_the_tiny_task(learned):
    """Mean episode return (−J) of the first and the last 800 steps: a random policy's, then a
    controller's (an untrained policy drifts; a trained one drives x to 0)."""
    first, last = learned["returns"][0], learned["returns"][-1]
    assert learned["episodes"] == 30 * 8  # 20-decision episodes, 8 envs, 30 updates of 20 steps
    assert np.isfinite(learned["returns"]).all()
    assert last > first + 0.5 * abs(first), learned["returns"]
    count = float(learned["state"].obs_rms.count)
    assert count == pytest.approx(1e-4 + 8 * (1 + 600))  # the reset, then every step's observations


def test_vmap_over_seeds_equals_separate_runs(tiny):
    keys = jnp.stack([jax.random.PRNGKey(s) for s in range(4)])
    hps = stack_hparams([tiny["hp"]] * 4)
    states, metrics = tiny["vtrain"](keys, hps)
    assert metrics["pg_loss"].shape == (4, VMAP_UPDATES)
    kernels = np.asarray(states.params["critic"]["params"]["Dense_0"]["kernel"])
    for i in range(4):
        for j in range(i):
            assert not np.allclose(kernels[i], kernels[j])  # different seeds, different runs
        state = tiny["init"](keys[i], tiny["hp"])
        state, chunk = tiny["chunk"](state, tiny["hp"], VMAP_UPDATES)
        member = select(states, i)
        assert int(member.timesteps) == int(state.timesteps) == VMAP_UPDATES * 160
        for a, b in zip(jax.tree.leaves(member.params), jax.tree.leaves(state.params), strict=True):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(np.asarray(member.obs_rms.var), np.asarray(state.obs_rms.var), rtol=1e-5)
        np.testing.assert_allclose(float(jnp.mean(metrics["value_loss"][i])), float(chunk["value_loss"]), rtol=1e-3)


def test_vmap_over_settings_trains_each_its_own_way(tiny):
    hp = tiny["hp"]
    slow = hp._replace(learning_rate=1e-4, clip_range=0.1, log_std_init=-2.0)
    keys = jnp.stack([jax.random.PRNGKey(0)] * 2 + [jax.random.PRNGKey(1)] * 2)
    states, metrics = tiny["vtrain"](keys, stack_hparams([hp, slow, hp, slow]))
    np.testing.assert_allclose(np.asarray(metrics["learning_rate"][:, 0]), [3e-3, 1e-4, 3e-3, 1e-4], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(metrics["clip_range"][:, 0]), [0.2, 0.1, 0.2, 0.1], rtol=1e-6)
    std0 = np.exp([-0.5, -2.0])
    assert np.asarray(metrics["std"][1, -1]) == pytest.approx(std0[1], rel=0.05)  # a small step moves it little
    log_std = np.asarray(states.params["log_std"])
    assert not np.allclose(log_std[0], log_std[1]) and not np.allclose(log_std[0], log_std[2])
    means = per_update_episode_means(metrics)
    assert np.isfinite(np.asarray(means["episode_cost"])).all()  # an episode ends in every update


# ---- gSDE (use_sde) ---------------------------------------------------------------------------
def test_gsde_log_prob_and_entropy_are_sb3s():
    """The trainer's gSDE density is SB3's ``StateDependentNoiseDistribution`` (full std, exp,
    features detached) at the same latent, log-std matrix and actions."""
    th = pytest.importorskip("torch")
    from stable_baselines3.common.distributions import StateDependentNoiseDistribution

    from agents.fused_ppo.networks import gaussian_log_prob, sde_std

    rng = np.random.default_rng(3)
    latent = rng.normal(size=(16, 5)).astype(np.float32)
    log_std = rng.normal(-1.0, 0.5, size=(5, 3)).astype(np.float32)
    mean = rng.normal(size=(16, 3)).astype(np.float32)
    action = (mean + rng.normal(size=(16, 3))).astype(np.float32)
    dist = StateDependentNoiseDistribution(3)
    dist.latent_sde_dim = 5
    dist.proba_distribution(th.as_tensor(mean), th.as_tensor(log_std), th.as_tensor(latent))
    std = sde_std(jnp.asarray(latent), jnp.asarray(log_std))
    np.testing.assert_allclose(np.asarray(std), dist.distribution.stddev.numpy(), rtol=1e-6)
    expected = dist.log_prob(th.as_tensor(action)).numpy()
    log_prob = gaussian_log_prob(jnp.asarray(action), jnp.asarray(mean), jnp.log(std))
    np.testing.assert_allclose(np.asarray(log_prob), expected, rtol=1e-5)
    entropy = gaussian_entropy(jnp.log(std))  # the entropy bonus's per-sample term
    np.testing.assert_allclose(np.asarray(entropy), dist.entropy().numpy(), rtol=1e-5)


def _sde_program(freq: int):
    from agents.fused_ppo.trainer import _Program

    env = TwoIntegrators()
    entry = {**TINY_ENTRY, "use_sde": True, "sde_sample_freq": freq, "n_steps": 8}
    config, hp = from_zoo(entry, total_timesteps=64)
    return _Program(env, env.default_params, config), hp


@pytest.mark.parametrize(("freq", "fresh_at"), [(4, [0, 4]), (-1, [0])])
def test_gsde_noise_weights_are_redrawn_as_sb3_redraws_them(freq, fresh_at):
    """Within a rollout the weights change at step 0 and every ``sde_sample_freq`` steps (SB3's
    ``collect_rollouts``), only at step 0 with -1; each env has its own; the action's noise is
    ``latent @ W`` (a linear actor: the normalized observation)."""
    prog, hp = _sde_program(freq)
    state = prog.init(jax.random.PRNGKey(0), hp)
    assert state.params["log_std"].shape == (2, 2) and state.sde_weights.shape == (8, 2, 2)
    ep0 = dict.fromkeys(("episodes", "episode_return", "episode_cost", "episode_length"), jnp.float32(0))
    weights, carry = [], (state, ep0)
    for step in range(8):
        before = carry[0]
        carry, tr = prog._env_step(hp, carry, jnp.int32(step))
        weights.append(np.asarray(carry[0].sde_weights))
        mean = prog.actor.apply(before.params["actor"], before.obs)
        noise = np.einsum("ei,eia->ea", np.asarray(before.obs), weights[-1])
        np.testing.assert_allclose(np.asarray(tr.action), np.asarray(mean) + noise, rtol=1e-5, atol=1e-6)
    changed = [s for s in range(8) if s == 0 or not np.array_equal(weights[s], weights[s - 1])]
    assert changed == fresh_at
    assert not np.allclose(weights[0][0], weights[0][1])  # per-env matrices


def test_gsde_trains_and_its_policy_plays_in_numpy(tmp_path):
    """A gSDE run of the tiny task learns (its episode return rises), and the numpy predictor
    plays its mean; its stochastic draws have gSDE's spread ``sqrt(z² @ exp(log_std)²)``."""
    from agents.fused_ppo.networks import sde_std

    env = TwoIntegrators()
    config, hp = from_zoo({**TINY_ENTRY, "use_sde": True, "sde_sample_freq": 4}, total_timesteps=4800)
    chunked = make_chunked(env, env.default_params, config)
    chunk = jax.jit(chunked.update_chunk, compiler_options=FAST)
    state = chunked.init(jax.random.PRNGKey(0), hp)
    returns = []
    for _ in range(6):
        state, metrics = chunk(state, hp, 5)
        returns.append(float(metrics["episode_return"]))
    assert np.isfinite(returns).all() and returns[-1] > returns[0] + 0.5 * abs(returns[0]), returns
    policy = NumpyPPOPolicy(policy_arrays(state, config, env, env.default_params), seed=0)
    obs = np.full((20000, 2), 0.3, np.float32)
    o = policy.normalize(obs[:1])
    std = np.asarray(sde_std(jnp.asarray(o), state.params["log_std"]))[0]
    mean = policy.mean(obs[:1])[0]
    np.testing.assert_array_equal(policy.predict(obs[:1])[0][0], np.clip(mean, -1.0, 1.0))
    policy.arrays.action_low[:], policy.arrays.action_high[:] = -1e9, 1e9  # no clipping: the raw draws
    draws = policy.predict(obs, deterministic=False)[0]
    np.testing.assert_allclose(draws.mean(axis=0), mean, atol=4 * std.max() / np.sqrt(len(obs)))
    np.testing.assert_allclose(draws.std(axis=0), std, rtol=0.03)
    loaded = NumpyPPOPolicy.load(policy.save(tmp_path / "model.zip"))
    assert loaded.arrays.log_std.shape == (2, 2)


# ---- export -----------------------------------------------------------------------------------
def test_the_numpy_predictor_plays_the_jax_policy(tiny, learned, tmp_path, rng):
    state, config = learned["state"], tiny["config"]
    policy = NumpyPPOPolicy(policy_arrays(state, config, tiny["env"], tiny["params"]))
    obs = rng.uniform(-3.0, 3.0, size=(64, 2)).astype(np.float32)
    actor, _ = make_networks(config.pi_arch, config.vf_arch, 2, config.activation, config.ortho_init)
    normalized = normalize_obs(state.obs_rms, jnp.asarray(obs), config.clip_obs, config.norm_epsilon)
    expected = np.clip(np.asarray(actor.apply(state.params["actor"], normalized)), -1.0, 1.0)
    action, hidden = policy.predict(obs)
    assert hidden is None and action.dtype == np.float32 and action.shape == (64, 2)
    np.testing.assert_allclose(action, expected, rtol=1e-5, atol=1e-6)
    assert np.abs(expected).max() == 1.0 and (np.abs(expected) < 1.0).any()  # the box clips some, not all
    single, _ = policy.predict(obs[0], state=None, episode_start=np.ones(1, bool), deterministic=True)
    np.testing.assert_allclose(single, action[0], rtol=1e-6)
    loaded = NumpyPPOPolicy.load(policy.save(tmp_path / "model.zip"))
    np.testing.assert_array_equal(loaded.predict(obs)[0], action)
    assert load_policy(tmp_path / "model.zip").activation == "tanh"
    noisy, _ = loaded.predict(obs, deterministic=False)
    assert np.all(np.abs(noisy) <= 1.0) and not np.allclose(noisy, action)
    with pytest.raises(ValueError, match=r"obs must have shape \(2,\)"):
        policy.predict(np.zeros(3))


# ---- the jax training backend on LinearSystem-v1 ---------------------------------------------
LS = "attitude_envs/LinearSystem-v1"
LS_TINY = {"n_envs": 2, "n_steps": 80, "batch_size": 80, "n_epochs": 2, "backend": "jax"}  # 160 steps per update


def _train(out, total, **kw):
    from experiments.training.training import train

    kw = {"eval_freq": 160, "checkpoint_freq": 160, "eval_episodes": 2, "overrides": LS_TINY, **kw}
    return train("ppo", LS, out, total_timesteps=total, **kw)


def _final_arrays(run):
    return load_policy(run / "final" / "model.zip")


def test_train_backend_jax_writes_a_run_that_load_trained_plays(tmp_path, monkeypatch):
    from attitude_envs.evaluation.rollout import rollout
    from experiments.training.policy import SB3Policy
    from experiments.training.training import load_trained

    run = tmp_path / "run"
    result = _train(run, 320)
    assert result.timesteps == 320 and result.resumed_from is None and not result.already_complete
    config = json.loads((run / "config.json").read_text())
    assert config["backend"] == "jax" and config["hyperparams"]["n_envs"] == 2 and config["total_timesteps"] == 320
    rows = (run / "evaluations.csv").read_text().splitlines()
    assert rows[0] == "timesteps,J_mean,J_std" and [int(r.split(",")[0]) for r in rows[1:]] == [0, 160, 320]
    best = json.loads((run / "best" / "best.json").read_text())
    assert best["J_mean"] == min(float(r.split(",")[1]) for r in rows[1:])
    segment = json.loads((run / "timing.jsonl").read_text().splitlines()[0])
    assert segment["from_timesteps"] == 0 and segment["to_timesteps"] == 320 and segment["wall_time_s"] > 0
    assert json.loads((run / "checkpoints" / "latest.json").read_text())["timesteps"] == 320
    env = gym.make(LS)
    predictor = load_trained(run, env)  # the run directory: final/model.zip
    episode = rollout(env, SB3Policy(predictor), seed=3)
    assert np.isfinite(episode["J"]) and episode["J"] > 0
    last_eval = float(rows[-1].split(",")[1])
    from experiments.training.callbacks import evaluate_cost

    assert evaluate_cost(predictor, env, [10_000, 10_001])["J_mean"] == pytest.approx(last_eval, rel=1e-5)
    copied = tmp_path / "elsewhere" / "model.zip"  # without its run's config.json: told by the file
    copied.parent.mkdir()
    shutil.copy(run / "best" / "model.zip", copied)
    for name in ("jax", "flax", "optax"):  # playing a trained policy needs numpy only
        monkeypatch.setitem(sys.modules, name, None)
    assert load_trained(copied, env).predict(env.reset(seed=0)[0])[0].shape == (3,)
    monkeypatch.undo()
    with pytest.raises(ValueError, match="was trained on attitude_envs/LinearSystem-v1"):
        load_trained(run, gym.make("attitude_envs/AirBearing-v1"))
    with pytest.raises(ValueError, match="already holds a run"):
        _train(run, 480)


def test_a_resumed_run_continues_as_the_uninterrupted_one(tmp_path):
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    _train(whole, 480, evaluate_initial=False)
    _train(parts, 320, schedule_timesteps=480, evaluate_initial=False)
    result = _train(parts, 480, resume=True, evaluate_initial=False)
    assert result.resumed_from == 320 and result.timesteps == 480
    assert (parts / "evaluations.csv").read_text() == (whole / "evaluations.csv").read_text()
    a, b = _final_arrays(whole), _final_arrays(parts)
    for x, y in zip(a.kernels + [a.log_std, a.obs_mean], b.kernels + [b.log_std, b.obs_mean], strict=True):
        np.testing.assert_array_equal(x, y)
    again = _train(parts, 480, resume=True)
    assert again.already_complete and again.timesteps == 480
    with pytest.raises(ValueError, match="--resume: hyperparams"):
        _train(parts, 640, resume=True, overrides={**LS_TINY, "gamma": 0.9})


def test_the_cli_and_campaigns_accept_backend_jax():
    from experiments.campaign.spec import load_campaign
    from experiments.cli import build_parser

    args = build_parser().parse_args(["train", "--algo", "ppo", "--env", LS, "--out", "x", "--backend", "jax"])
    assert args.backend == "jax"
    agent = {"name": "ppo-jax", "policy": "sb3", "train": {"algo": "ppo", "backend": "jax", "timesteps": 320}}
    spec = {"name": "c", "seeds": 1, "envs": [{"name": "ls", "id": LS}], "agents": [agent]}
    assert load_campaign(spec).agents[0].train["backend"] == "jax"
    with pytest.raises(ValueError, match="backend 'jax' implements"):
        load_campaign({**spec, "agents": [{**agent, "train": {"algo": "sac", "backend": "jax"}}]})


def test_tune_backend_jax_trains_a_population_and_ranks_it(tmp_path, capsys):
    from experiments.cli import main

    out = tmp_path / "study"
    argv = ["tune", "--algo", "ppo", "--env", LS, "--backend", "jax", "--out", str(out), "--trials", "3"]
    argv += ["--timesteps", "320", "--evaluations", "2", "--eval-episodes", "1", "--params", "n_envs:2", "n_steps:80"]
    argv += ["batch_size:80", "n_epochs:2", "gae_lambda:0.97"]  # a fixed override is not drawn
    assert main(argv) == 0
    assert "3 of 3 settings in 1 compiled program(s)" in capsys.readouterr().out
    report = json.loads((out / "population.json").read_text())
    values = [min(e["J_mean"] for e in t["evaluations"]) for t in report["trials"]]
    assert [len(t["evaluations"]) for t in report["trials"]] == [2, 2, 2] and len(set(values)) == 3
    assert report["ranking"][0] == int(np.argmin(values)) and report["trials"][0]["evaluations"][0]["timesteps"] == 160
    rows = (out / "trials.csv").read_text().splitlines()
    assert rows[0].startswith("number,state,value,last_step,group,param_gamma")
    with open(out / "trials.csv", encoding="utf-8") as fh:  # what each setting trained with
        trained = list(csv.DictReader(fh))
    assert [float(r["param_gae_lambda"]) for r in trained] == pytest.approx([0.97] * 3)
    assert len({r["param_learning_rate"] for r in trained}) == 3
    best = yaml.safe_load((out / "best.yml").read_text())[LS]
    assert best["n_envs"] == 2 and best["backend"] == "jax" and best["learning_rate"].startswith("lin_")
    config, _ = from_zoo(best)  # a Zoo entry the trainer takes as is
    assert config.n_steps == 80 and config.vf_arch == (64, 64)


def test_a_killed_population_search_resumes_to_the_uninterrupted_one(tmp_path, monkeypatch):
    """The search saves its state after every evaluation; run again with the same arguments, a
    search killed in its second evaluation resumes there and ends with the uninterrupted search's
    evaluations, bit for bit. Another search's state in the folder is an error."""
    import experiments.training.jax_tuning as jt

    options = dict(n_trials=2, timesteps=480, n_evaluations=3, eval_episodes=1, overrides=LS_TINY, progress=False)
    reference = jt.tune_population("ppo", LS, tmp_path / "whole", **options)
    calls = {"n": 0}
    evaluate = jt.evaluate_cost

    def killed_in_the_second_evaluation(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:  # 2 settings per evaluation: the second setting of evaluation 2
            raise KeyboardInterrupt
        return evaluate(*args, **kwargs)

    monkeypatch.setattr(jt, "evaluate_cost", killed_in_the_second_evaluation)
    with pytest.raises(KeyboardInterrupt):
        jt.tune_population("ppo", LS, tmp_path / "killed", **options)
    assert not (tmp_path / "killed" / "population.json").exists()
    counted = {"n": 0}

    def counting(*args, **kwargs):
        counted["n"] += 1
        return evaluate(*args, **kwargs)

    monkeypatch.setattr(jt, "evaluate_cost", counting)
    resumed = jt.tune_population("ppo", LS, tmp_path / "killed", **options)
    assert counted["n"] == 4  # evaluations 2 and 3 of both settings: the first was kept
    whole = json.loads((tmp_path / "whole" / "population.json").read_text())["trials"]
    again = json.loads((tmp_path / "killed" / "population.json").read_text())["trials"]
    assert [t["evaluations"] for t in again] == [t["evaluations"] for t in whole]
    assert [len(t["evaluations"]) for t in again] == [3, 3] and resumed["best_value"] == reference["best_value"]
    finished = jt.tune_population("ppo", LS, tmp_path / "killed", **options)  # nothing left to train
    assert (
        counted["n"] == 4
        and finished["best_value"] == reference["best_value"]
        and finished["groups"] == resumed["groups"]
    )
    with pytest.raises(ValueError, match="holds another search's state"):
        jt.tune_population("ppo", LS, tmp_path / "killed", **{**options, "n_evaluations": 2})


def test_population_draws_keep_the_entry_shapes_in_group_zero():
    from experiments.training.hyperparams import load_hyperparams
    from experiments.training.jax_tuning import draw_population
    from experiments.training.tuning import PPO_SPACE

    entry = load_hyperparams("ppo", "attitude_envs/AirBearing-v1")
    trials = draw_population(entry, 6, 2, np.random.default_rng(0))
    configs = [from_zoo({**entry, **t["overrides"]})[0] for t in trials]
    assert configs[0] == configs[2] == configs[4] and configs[0].vf_arch == (64, 64) and configs[0].pi_arch == ()
    assert configs[1] == configs[3] == configs[5] and configs[1] != configs[0]
    lrs = [t["params"]["learning_rate"] for t in trials]
    low, high = PPO_SPACE["learning_rate"][1:]
    assert len(set(lrs)) == 6 and all(low <= lr <= high for lr in lrs)
    assert all(t["params"]["gamma"] in PPO_SPACE["gamma"] for t in trials)


def test_hparams_are_a_pytree_and_config_is_static():
    leaves = jax.tree.leaves(Hparams())
    assert len(leaves) == len(Hparams._fields)
    assert hash(PPOConfig()) == hash(dataclasses.replace(PPOConfig()))


def test_saved_leaves_go_back_only_into_a_state_they_fit():
    from experiments.training.jax_training import leaves_into

    state = {"a": jnp.zeros((2, 3), jnp.float32), "b": (jnp.arange(4, dtype=jnp.int32),)}
    leaves = [np.full((2, 3), 1.5, np.float32), np.arange(4, dtype=np.int32) * 2]
    back = leaves_into(state, leaves)
    assert np.array_equal(back["a"], leaves[0]) and np.array_equal(back["b"][0], leaves[1])
    assert leaves_into(state, leaves[:1]) is None  # fewer leaves
    assert leaves_into(state, [leaves[0].astype(np.float64), leaves[1]]) is None  # another dtype
    assert leaves_into(state, [leaves[0][:1], leaves[1]]) is None  # another shape
