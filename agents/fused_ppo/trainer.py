"""PPO as one jitted program: env steps, rollout, GAE, minibatch epochs and the optax update.

The PureJaxRL design (Lu et al. 2022, "Discovered Policy Optimisation", NeurIPS; the
``purejaxrl`` repository): the env is a JAX function (:mod:`attitude_envs.jax`), so a whole
training run is a ``lax.scan`` over PPO updates, each a ``lax.scan`` over env steps followed by
``lax.scan`` over epochs and minibatches, and ``jax.vmap`` of it trains many seeds (over keys)
and many settings (over :class:`~agents.fused_ppo.config.Hparams`) in one compiled program.

What an update does is Stable-Baselines3's PPO (2.x) under ``VecNormalize``, step for step:

* rollout: the policy sees the normalized observation; the action ``a ~ N(μ(o), σ)`` is
  stored unclipped and applied clipped to the action box (with ``use_sde``, gSDE:
  ``a = μ(o) + z(o) W`` with ``z`` the actor's last hidden layer (the observation for a linear
  actor) and ``W ~ N(0, exp(log_std)²)`` per env, drawn at the rollout's start and every
  ``sde_sample_freq`` steps; its log-density is the Gaussian's with ``σ² = z² exp(log_std)²``); the observation statistics are
  updated with each new observation before it is normalized, rewards are scaled by the
  running std of the discounted return; at a time-limit truncation the reward gets
  ``γ V(normalized final observation)`` (SB3's bootstrap of ``TimeLimit.truncated``);
* GAE(γ, λ) with the value of the last observation; returns = advantages + values;
* ``n_epochs`` passes over a fresh permutation in minibatches of ``batch_size`` (the last
  one smaller when it does not divide the rollout), advantages normalized per minibatch
  (unbiased std, +1e-8), clipped surrogate, value MSE (clipped only with ``clip_range_vf``),
  entropy bonus, the global gradient norm clipped to ``max_grad_norm`` (torch's formula),
  Adam (ε = 1e-5) at the scheduled learning rate; with ``target_kl`` an update stops (for the
  rest of the rollout) at the first minibatch whose approximate KL exceeds 1.5 × target_kl;
* schedules are evaluated after each rollout on ``1 - steps / schedule_timesteps`` (as SB3,
  unclamped: a last rollout past the horizon gets a negative linear value, as in SB3).

:func:`make_train` gives ``train(key, hparams) -> (runner_state, metrics)`` (metrics per
update); :func:`make_chunked` gives ``init(key, hparams)`` and
``update_chunk(state, hparams, n_updates)`` (``n_updates`` traced: one compiled program for
every chunk length) for a Python loop that checkpoints and evaluates between chunks. The
functions are pure and not jitted: ``jax.jit(jax.vmap(train, in_axes=(0, None)))`` for seeds,
``in_axes=(None, 0)`` for settings.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct

from agents.fused_ppo.config import Hparams, PPOConfig
from agents.fused_ppo.export import PolicyArrays
from agents.fused_ppo.networks import gaussian_entropy, gaussian_log_prob, make_networks, sde_std
from agents.fused_ppo.normalization import RunningMeanStd, normalize_obs, normalize_reward, update_return

#: Adam's ε in Stable-Baselines3's policies (``optimizer_kwargs=dict(eps=1e-5)``)
ADAM_EPS = 1e-5


@struct.dataclass
class RunnerState:
    """Everything a training run carries from one update to the next (one seed and setting).

    ``obs`` is the normalized last observation (what the policy sees), ``returns`` the
    discounted return of reward normalization, ``episode_*`` the raw return, the cost J and
    the length (decisions) of each env's running episode, ``key`` a raw uint32 PRNG key,
    ``timesteps`` env steps so far (all envs), ``updates`` PPO updates so far; ``sde_weights``
    the gSDE noise weights of each env (n_envs, latent, actions), None without gSDE."""

    params: Any
    opt_state: Any
    env_state: Any
    obs: jax.Array
    obs_rms: RunningMeanStd
    ret_rms: RunningMeanStd
    returns: jax.Array
    episode_return: jax.Array
    episode_cost: jax.Array
    episode_length: jax.Array
    key: jax.Array
    timesteps: jax.Array
    updates: jax.Array
    sde_weights: Any = None


class Transition(NamedTuple):
    obs: jax.Array
    action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array
    done: jax.Array


class Batch(NamedTuple):
    obs: jax.Array
    action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    advantage: jax.Array
    returns: jax.Array


class Chunked(NamedTuple):
    """The chunked form: ``init(key, hparams) -> state``, ``update_chunk(state, hparams,
    n_updates) -> (state, metrics)`` (metrics: means over the chunk's updates, episode
    statistics over the episodes that ended in it), ``update(state, hparams) -> (state,
    metrics)`` one update."""

    init: Callable[..., RunnerState]
    update_chunk: Callable[..., tuple[RunnerState, dict[str, jax.Array]]]
    update: Callable[..., tuple[RunnerState, dict[str, jax.Array]]]


def _raw_key(key: jax.Array) -> jax.Array:
    key = jnp.asarray(key)
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        return jax.random.key_data(key)
    return key


def _hp32(hp: Hparams) -> Hparams:
    return Hparams(*(jnp.asarray(v, jnp.float32) for v in hp))


def _schedule(kind: str | None, start: jax.Array, progress: jax.Array) -> jax.Array:
    return start * progress if kind == "linear" else start


class _Program:
    """The pieces of one fused PPO program (``env``, ``env_params`` and ``config`` static)."""

    def __init__(self, env, env_params, config: PPOConfig) -> None:
        if not isinstance(config, PPOConfig):
            raise ValueError(f"config must be a PPOConfig (agents.fused_ppo.from_zoo), got {type(config).__name__}")
        self.env, self.env_params, self.config = env, env_params, config
        obs_space, act_space = env.observation_space(env_params), env.action_space(env_params)
        if len(obs_space.shape) != 1 or len(act_space.shape) != 1:
            raise ValueError(
                f"fused PPO needs flat observation and action boxes, got {obs_space.shape} and {act_space.shape}"
            )
        self.obs_dim, self.act_dim = int(obs_space.shape[0]), int(act_space.shape[0])
        self.latent_dim = config.pi_arch[-1] if config.pi_arch else self.obs_dim  # gSDE's features
        self.low = np.asarray(act_space.low, np.float32)
        self.high = np.asarray(act_space.high, np.float32)
        self.actor, self.critic = make_networks(
            config.pi_arch, config.vf_arch, self.act_dim, config.activation, config.ortho_init
        )
        self.adam = optax.scale_by_adam(eps=ADAM_EPS)
        n = config.rollout_size
        self.batch = min(config.batch_size, n)
        self.n_minibatches = -(-n // self.batch)

    # ---- pieces ---------------------------------------------------------------------------
    def _value(self, params, obs: jax.Array) -> jax.Array:
        return self.critic.apply(params["critic"], obs)[..., 0]

    def _sde_policy(self, params, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        """gSDE: ``(mean, latent)`` at ``obs``, the latent the actor's last hidden layer."""
        return self.actor.apply(params["actor"], obs, with_latent=True)

    def _sde_weights(self, key: jax.Array, log_std: jax.Array) -> jax.Array:
        """Fresh gSDE noise weights ``W ~ N(0, exp(log_std)²)``, one matrix per env."""
        shape = (self.config.n_envs, self.latent_dim, self.act_dim)
        return jnp.exp(log_std) * jax.random.normal(key, shape)

    def _norm_obs(self, rms: RunningMeanStd, obs: jax.Array) -> jax.Array:
        if not self.config.norm_obs:
            return obs.astype(jnp.float32)
        return normalize_obs(rms, obs, self.config.clip_obs, self.config.norm_epsilon)

    def init(self, key: jax.Array, hp: Hparams) -> RunnerState:
        hp = _hp32(hp)
        key, k_actor, k_critic, k_reset = jax.random.split(_raw_key(key), 4)
        dummy = jnp.zeros((1, self.obs_dim), jnp.float32)
        params = {
            "actor": self.actor.init(k_actor, dummy),
            "critic": self.critic.init(k_critic, dummy),
            "log_std": jnp.full(
                (self.latent_dim, self.act_dim) if self.config.use_sde else (self.act_dim,),
                hp.log_std_init,
                jnp.float32,
            ),
        }
        n = self.config.n_envs
        obs, env_state = jax.vmap(self.env.reset, in_axes=(0, None))(jax.random.split(k_reset, n), self.env_params)
        obs = obs.astype(jnp.float32)
        obs_rms = RunningMeanStd.create((self.obs_dim,))
        if self.config.norm_obs:
            obs_rms = obs_rms.update(obs)  # SB3's VecNormalize.reset updates with the first observations
        zeros = jnp.zeros((n,), jnp.float32)
        return RunnerState(
            params=params,
            opt_state=self.adam.init(params),
            env_state=env_state,
            obs=self._norm_obs(obs_rms, obs),
            obs_rms=obs_rms,
            ret_rms=RunningMeanStd.create(()),
            returns=zeros,
            episode_return=zeros,
            episode_cost=zeros,
            episode_length=jnp.zeros((n,), jnp.int32),
            key=key,
            timesteps=jnp.asarray(0, jnp.int32),
            updates=jnp.asarray(0, jnp.int32),
            sde_weights=jnp.zeros((n, self.latent_dim, self.act_dim), jnp.float32) if self.config.use_sde else None,
        )

    def _env_step(self, hp: Hparams, carry, step):
        rs, ep = carry
        obs_before = rs.obs
        key, k_act, k_env = jax.random.split(rs.key, 3)
        params = rs.params
        if self.config.use_sde:
            # SB3 draws at the rollout's start and, with sde_sample_freq > 0, when step % freq == 0
            freq = self.config.sde_sample_freq
            fresh = step == 0 if freq <= 0 else step % freq == 0
            weights = jnp.where(fresh, self._sde_weights(k_act, params["log_std"]), rs.sde_weights)
            mean, latent = self._sde_policy(params, rs.obs)
            action = mean + jnp.einsum("ei,eia->ea", latent, weights)
            log_prob = gaussian_log_prob(action, mean, jnp.log(sde_std(latent, params["log_std"])))
            rs = rs.replace(sde_weights=weights)
        else:
            mean = self.actor.apply(params["actor"], rs.obs)
            log_std = params["log_std"]
            action = mean + jnp.exp(log_std) * jax.random.normal(k_act, mean.shape)
            log_prob = gaussian_log_prob(action, mean, log_std)
        value = self._value(params, rs.obs)
        applied = jnp.clip(action, self.low, self.high)
        keys = jax.random.split(k_env, self.config.n_envs)
        obs, env_state, reward, terminated, truncated, info = jax.vmap(self.env.step, in_axes=(0, 0, 0, None))(
            keys, rs.env_state, applied, self.env_params
        )
        obs = obs.astype(jnp.float32)
        reward = reward.astype(jnp.float32)
        done = jnp.logical_or(terminated, truncated)
        obs_rms = rs.obs_rms.update(obs) if self.config.norm_obs else rs.obs_rms
        obs_n = self._norm_obs(obs_rms, obs)
        ret_rms, returns = rs.ret_rms, rs.returns
        scaled = reward
        if self.config.norm_reward:
            ret_rms, returns = update_return(ret_rms, returns, reward, done, hp.gamma)
            scaled = normalize_reward(ret_rms, reward, self.config.clip_reward, self.config.norm_epsilon)
        final_value = self._value(params, self._norm_obs(obs_rms, info["final_observation"].astype(jnp.float32)))
        scaled = scaled + hp.gamma * final_value * truncated.astype(jnp.float32)
        cost = info["cost"].astype(jnp.float32)
        episode_return = rs.episode_return + reward
        episode_cost = rs.episode_cost + cost
        episode_length = rs.episode_length + 1
        d = done.astype(jnp.float32)
        ep = {
            "episodes": ep["episodes"] + jnp.sum(d),
            "episode_return": ep["episode_return"] + jnp.sum(d * episode_return),
            "episode_cost": ep["episode_cost"] + jnp.sum(d * episode_cost),
            "episode_length": ep["episode_length"] + jnp.sum(d * episode_length),
        }
        rs = rs.replace(
            env_state=env_state,
            obs=obs_n,
            obs_rms=obs_rms,
            ret_rms=ret_rms,
            returns=returns,
            episode_return=jnp.where(done, 0.0, episode_return),
            episode_cost=jnp.where(done, 0.0, episode_cost),
            episode_length=jnp.where(done, 0, episode_length),
            key=key,
        )
        return (rs, ep), Transition(obs_before, action, log_prob, value, scaled, d)

    def _loss(self, params, b: Batch, w: jax.Array, clip, clip_vf, hp: Hparams):
        cfg = self.config
        n = jnp.sum(w)

        def mean(x):
            return jnp.sum(w * x) / n

        if cfg.use_sde:
            mu, latent = self._sde_policy(params, b.obs)
            log_std = jnp.log(sde_std(latent, params["log_std"]))  # per sample
            log_prob = gaussian_log_prob(b.action, mu, log_std)
            entropy_loss = -mean(gaussian_entropy(log_std))
        else:
            mu = self.actor.apply(params["actor"], b.obs)
            log_std = params["log_std"]
            log_prob = gaussian_log_prob(b.action, mu, log_std)
            entropy_loss = -gaussian_entropy(log_std)  # the same in every state: its batch mean
        value = self._value(params, b.obs)
        adv = b.advantage
        if cfg.normalize_advantage:
            m = mean(adv)
            std = jnp.sqrt(jnp.sum(w * jnp.square(adv - m)) / jnp.maximum(n - 1.0, 1.0))  # torch's unbiased std
            adv = jnp.where(n > 1.0, (adv - m) / (std + 1e-8), adv)
        log_ratio = log_prob - b.log_prob
        ratio = jnp.exp(log_ratio)
        pg_loss = -mean(jnp.minimum(adv * ratio, adv * jnp.clip(ratio, 1.0 - clip, 1.0 + clip)))
        if cfg.clip_vf_schedule is None:
            value_pred = value
        else:
            value_pred = b.value + jnp.clip(value - b.value, -clip_vf, clip_vf)
        value_loss = mean(jnp.square(b.returns - value_pred))
        loss = pg_loss + hp.ent_coef * entropy_loss + hp.vf_coef * value_loss
        aux = {
            "pg_loss": pg_loss,
            "value_loss": value_loss,
            "entropy_loss": entropy_loss,
            "approx_kl": jax.lax.stop_gradient(mean(ratio - 1.0 - log_ratio)),
            "clip_fraction": jax.lax.stop_gradient(mean((jnp.abs(ratio - 1.0) > clip).astype(jnp.float32))),
        }
        return loss, aux

    def update(self, rs: RunnerState, hp: Hparams) -> tuple[RunnerState, dict[str, jax.Array]]:
        """One PPO update: a rollout of ``n_steps`` × ``n_envs`` env steps, then the epochs."""
        cfg, hp = self.config, _hp32(hp)
        zero = jnp.asarray(0.0, jnp.float32)
        ep0 = {"episodes": zero, "episode_return": zero, "episode_cost": zero, "episode_length": zero}
        steps = jnp.arange(cfg.n_steps, dtype=jnp.int32)  # the step within the rollout (gSDE's draws)
        (rs, ep), traj = jax.lax.scan(lambda c, x: self._env_step(hp, c, x), (rs, ep0), steps)
        timesteps = rs.timesteps + cfg.rollout_size
        last_value = self._value(rs.params, rs.obs)

        def gae_step(carry, t: Transition):
            gae, next_value = carry
            nonterminal = 1.0 - t.done
            delta = t.reward + hp.gamma * next_value * nonterminal - t.value
            gae = delta + hp.gamma * hp.gae_lambda * nonterminal * gae
            return (gae, t.value), gae

        _, advantages = jax.lax.scan(gae_step, (jnp.zeros_like(last_value), last_value), traj, reverse=True)
        returns = advantages + traj.value
        n = cfg.rollout_size

        def flat(x):
            return x.reshape((n,) + x.shape[2:])

        data = Batch(*(flat(x) for x in (traj.obs, traj.action, traj.log_prob, traj.value, advantages, returns)))

        progress = 1.0 - timesteps.astype(jnp.float32) / hp.schedule_timesteps
        lr = _schedule(cfg.lr_schedule, hp.learning_rate, progress)
        clip = _schedule(cfg.clip_schedule, hp.clip_range, progress)
        clip_vf = _schedule(cfg.clip_vf_schedule, hp.clip_range_vf, progress)
        grad_fn = jax.value_and_grad(self._loss, has_aux=True)
        size, n_mb = self.batch, self.n_minibatches
        mask = (jnp.arange(n_mb * size) < n).astype(jnp.float32).reshape(n_mb, size)

        def minibatch(carry, xs):
            params, opt_state, going = carry
            b, w = xs
            (_, aux), grads = grad_fn(params, b, w, clip, clip_vf, hp)
            norm = jnp.sqrt(sum(jnp.sum(jnp.square(g)) for g in jax.tree.leaves(grads)))
            scale = jnp.minimum(1.0, hp.max_grad_norm / (norm + 1e-6))  # torch.nn.utils.clip_grad_norm_
            grads = jax.tree.map(lambda g: g * scale, grads)
            updates, new_opt = self.adam.update(grads, opt_state, params)
            new_params = jax.tree.map(lambda p, u: p - lr * u, params, updates)
            counted = going
            if cfg.use_target_kl:  # SB3 records the minibatch's losses, then stops before its step
                going = jnp.logical_and(going, aux["approx_kl"] <= 1.5 * hp.target_kl)
                new_params = jax.tree.map(lambda a, c: jnp.where(going, a, c), new_params, params)
                new_opt = jax.tree.map(lambda a, c: jnp.where(going, a, c), new_opt, opt_state)
            stats = {k: v * counted for k, v in aux.items()} | {"counted": counted.astype(jnp.float32)}
            return (new_params, new_opt, going), stats

        def epoch(carry, key):
            perm = jax.random.permutation(key, n)
            idx = jnp.concatenate([perm, jnp.zeros((n_mb * size - n,), perm.dtype)])  # padding: masked out
            shuffled = jax.tree.map(lambda x: jnp.take(x, idx, axis=0).reshape((n_mb, size) + x.shape[1:]), data)
            return jax.lax.scan(minibatch, carry, (shuffled, mask))

        key, k_epochs = jax.random.split(rs.key)
        going = jnp.asarray(True)
        (params, opt_state, _), stats = jax.lax.scan(
            epoch, (rs.params, rs.opt_state, going), jax.random.split(k_epochs, cfg.n_epochs)
        )
        counted = jnp.maximum(jnp.sum(stats.pop("counted")), 1.0)
        metrics = {k: jnp.sum(v) / counted for k, v in stats.items()}
        var_returns = jnp.var(data.returns)
        metrics |= {
            "explained_variance": jnp.where(
                var_returns > 0, 1.0 - jnp.var(data.returns - data.value) / var_returns, jnp.nan
            ),
            "learning_rate": lr,
            "clip_range": clip,
            "std": jnp.mean(jnp.exp(params["log_std"])),
            "timesteps": timesteps,
            **ep,
        }
        rs = rs.replace(params=params, opt_state=opt_state, key=key, timesteps=timesteps, updates=rs.updates + 1)
        return rs, metrics

    def train(self, key: jax.Array, hp: Hparams) -> tuple[RunnerState, dict[str, jax.Array]]:
        rs = self.init(key, hp)
        return jax.lax.scan(lambda r, _: self.update(r, hp), rs, None, length=self.config.num_updates)

    def update_chunk(self, rs: RunnerState, hp: Hparams, n_updates) -> tuple[RunnerState, dict[str, jax.Array]]:
        # the sums start from METRIC_KEYS, not from jax.eval_shape(self.update): that traced the
        # whole rollout and epochs a second time (about 0.5 s of AirBearing-v1's 1.8 s of tracing);
        # a key missing on either side fails the tree.map below at trace time
        acc0 = {k: jnp.zeros((), jnp.float32) for k in METRIC_KEYS}

        def body(_, carry):
            rs, acc = carry
            rs, m = self.update(rs, hp)
            return rs, jax.tree.map(lambda a, v: a + v.astype(jnp.float32), acc, m)

        n = jnp.asarray(n_updates, jnp.int32)
        rs, acc = jax.lax.fori_loop(0, n, body, (rs, acc0))
        return rs, summarize(acc, n, rs.timesteps)


_EPISODE_KEYS = ("episode_return", "episode_cost", "episode_length")
#: the keys of :meth:`_Program.update`'s metrics (all scalars)
METRIC_KEYS = (
    *("pg_loss", "value_loss", "entropy_loss", "approx_kl", "clip_fraction"),
    *("explained_variance", "learning_rate", "clip_range", "std", "timesteps", "episodes"),
    *_EPISODE_KEYS,
)


def summarize(sums: dict[str, jax.Array], n_updates, timesteps) -> dict[str, jax.Array]:
    """Chunk metrics from per-update sums: episode statistics averaged over the episodes that
    ended (NaN when none did), the others over the updates."""
    out = {}
    episodes = sums["episodes"]
    for k, v in sums.items():
        if k in _EPISODE_KEYS:
            out[k] = jnp.where(episodes > 0, v / jnp.maximum(episodes, 1.0), jnp.nan)
        elif k != "episodes":
            out[k] = v / jnp.maximum(jnp.asarray(n_updates, jnp.float32), 1.0)
    out["episodes"] = episodes
    out["timesteps"] = timesteps
    return out


def per_update_episode_means(metrics: dict[str, Any]) -> dict[str, Any]:
    """``metrics`` of :func:`make_train` with episode sums turned into means per update (NaN
    for an update in which no episode ended)."""
    out = dict(metrics)
    episodes = metrics["episodes"]
    for k in _EPISODE_KEYS:
        out[k] = jnp.where(episodes > 0, metrics[k] / jnp.maximum(episodes, 1.0), jnp.nan)
    return out


def make_train(env, env_params, config: PPOConfig) -> Callable[..., tuple[RunnerState, dict[str, jax.Array]]]:
    """``train(key, hparams) -> (runner_state, metrics)``: ``config.num_updates`` PPO updates
    from a fresh start. ``metrics`` per update (leading axis): losses, approximate KL, clip
    fraction, explained variance, learning rate, clip range, the Gaussian's mean std, env steps
    so far, and the sums over the episodes that ended in the update (``episodes``,
    ``episode_return``: Σ reward, ``episode_cost``: Σ J, ``episode_length``: Σ decisions;
    :func:`per_update_episode_means` turns them into means). Pure, not jitted."""
    return _Program(env, env_params, config).train


def make_chunked(env, env_params, config: PPOConfig) -> Chunked:
    """The chunked form of the same program (:class:`Chunked`); ``config.total_timesteps`` is
    not used (the caller decides how many updates to run)."""
    program = _Program(env, env_params, config)
    return Chunked(program.init, program.update_chunk, program.update)


def select(tree: Any, index: int) -> Any:
    """Member ``index`` of a vmapped pytree (a runner state or metrics of many seeds/settings)."""
    return jax.tree.map(lambda x: x[index], tree)


def policy_arrays(state: RunnerState, config: PPOConfig, env, env_params) -> PolicyArrays:
    """The actor and the observation statistics of an (unbatched) runner state as numpy arrays
    (:class:`~agents.fused_ppo.export.PolicyArrays`)."""
    layers = state.params["actor"]["params"]
    names = sorted(layers, key=lambda s: int(s.split("_")[-1]))
    act_space = env.action_space(env_params)
    return PolicyArrays(
        kernels=[np.asarray(layers[k]["kernel"], np.float32) for k in names],
        biases=[np.asarray(layers[k]["bias"], np.float32) for k in names],
        activation=config.activation,
        log_std=np.asarray(state.params["log_std"], np.float32),
        action_low=np.asarray(act_space.low, np.float32),
        action_high=np.asarray(act_space.high, np.float32),
        obs_mean=np.asarray(state.obs_rms.mean, np.float32) if config.norm_obs else None,
        obs_var=np.asarray(state.obs_rms.var, np.float32) if config.norm_obs else None,
        clip_obs=float(config.clip_obs),
        epsilon=float(config.norm_epsilon),
    )
