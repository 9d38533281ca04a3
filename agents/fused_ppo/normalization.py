"""Stable-Baselines3's ``VecNormalize`` as pure functions on a pytree (jax).

:class:`RunningMeanStd` is SB3's running mean and variance (Chan et al.'s parallel update,
prior count ``1e-4`` at mean 0, variance 1). Observations are normalized as
``clip((obs - mean) / sqrt(var + eps), ±clip_obs)`` with statistics that include the
observation being normalized (SB3 updates before it normalizes); rewards are divided by the
standard deviation of the discounted return ``R ← γR + r`` (reset to 0 at an episode's end),
then clipped to ``±clip_reward``. Both statistics are updated from training data only.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

#: SB3's prior count (``RunningMeanStd(epsilon=1e-4)``)
PRIOR_COUNT = 1e-4


@struct.dataclass
class RunningMeanStd:
    """Running ``mean`` and ``var`` over ``count`` samples (float32 arrays)."""

    mean: jax.Array
    var: jax.Array
    count: jax.Array

    @classmethod
    def create(cls, shape: tuple[int, ...] = ()) -> RunningMeanStd:
        return cls(jnp.zeros(shape, jnp.float32), jnp.ones(shape, jnp.float32), jnp.asarray(PRIOR_COUNT, jnp.float32))

    def update(self, batch: jax.Array) -> RunningMeanStd:
        """Statistics including ``batch`` (samples along axis 0), SB3's ``update_from_moments``."""
        batch = jnp.asarray(batch, jnp.float32)
        batch_mean = jnp.mean(batch, axis=0)
        batch_var = jnp.var(batch, axis=0)
        batch_count = jnp.asarray(batch.shape[0], jnp.float32)
        delta = batch_mean - self.mean
        total = self.count + batch_count
        mean = self.mean + delta * batch_count / total
        m2 = self.var * self.count + batch_var * batch_count + jnp.square(delta) * self.count * batch_count / total
        return RunningMeanStd(mean, m2 / total, total)


def normalize_obs(rms: RunningMeanStd, obs: jax.Array, clip: float, epsilon: float) -> jax.Array:
    """SB3's ``VecNormalize.normalize_obs`` (float32)."""
    return jnp.clip((obs - rms.mean) / jnp.sqrt(rms.var + epsilon), -clip, clip).astype(jnp.float32)


def normalize_reward(rms: RunningMeanStd, reward: jax.Array, clip: float, epsilon: float) -> jax.Array:
    """SB3's ``VecNormalize.normalize_reward``: ``reward`` over the return's standard deviation."""
    return jnp.clip(reward / jnp.sqrt(rms.var + epsilon), -clip, clip).astype(jnp.float32)


def update_return(
    rms: RunningMeanStd, returns: jax.Array, reward: jax.Array, done: jax.Array, gamma: jax.Array
) -> tuple[RunningMeanStd, jax.Array]:
    """One step of SB3's reward statistics: ``R ← γR + r``, the statistics updated with ``R``
    (over the envs); returns ``(rms, R reset to 0 where done)``."""
    returns = returns * gamma + reward
    return rms.update(returns), jnp.where(done, 0.0, returns)
