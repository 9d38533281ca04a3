"""The actor and the critic (flax linen): SB3's ``MlpPolicy`` for a Box action space.

Separate MLPs for the actor's mean and the critic's value (SB3's ``net_arch=dict(pi=…, vf=…)``;
the features extractor is a flatten, so nothing is shared), with SB3's initialization when
``ortho_init``: orthogonal weights of gain √2 in the hidden layers, 0.01 in the action layer,
1 in the value layer, zero biases. The Gaussian's log standard deviation is one parameter
vector, independent of the state (``params["log_std"]``), or with gSDE (Raffin, Kober & Stulp
2022) a (latent × actions) matrix that scales the noise weights applied to the actor's last
hidden layer (:func:`sde_std`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import flax.linen as nn
import jax
import jax.numpy as jnp

#: the activation functions by :data:`agents.fused_ppo.config.ACTIVATIONS` name
ACTIVATION_FNS: dict[str, Callable[[jax.Array], jax.Array]] = {
    "tanh": jnp.tanh,
    "relu": nn.relu,
    "elu": nn.elu,
    "gelu": lambda x: nn.gelu(x, approximate=False),  # torch's nn.GELU default: the exact erf form
    "silu": nn.silu,
    "leaky_relu": nn.leaky_relu,  # slope 0.01, torch's default
}


class MLP(nn.Module):
    """Hidden layers ``hidden`` (widths) with ``activation``, then a linear layer of ``out``
    units initialized with gain ``out_gain`` (orthogonal when ``ortho_init``; else flax's
    default LeCun-normal kernels and zero biases)."""

    hidden: tuple[int, ...]
    out: int
    activation: str = "tanh"
    out_gain: float = 1.0
    ortho_init: bool = True

    @nn.compact
    def __call__(self, x: jax.Array, with_latent: bool = False) -> jax.Array | tuple[jax.Array, jax.Array]:
        """The output; with ``with_latent`` also the last hidden layer (the input when there is none)."""
        act = ACTIVATION_FNS[self.activation]
        for width in self.hidden:
            kernel = nn.initializers.orthogonal(math.sqrt(2.0)) if self.ortho_init else nn.initializers.lecun_normal()
            x = act(nn.Dense(width, kernel_init=kernel, bias_init=nn.initializers.zeros)(x))
        kernel = nn.initializers.orthogonal(self.out_gain) if self.ortho_init else nn.initializers.lecun_normal()
        out = nn.Dense(self.out, kernel_init=kernel, bias_init=nn.initializers.zeros)(x)
        return (out, x) if with_latent else out


def make_networks(
    pi_arch: tuple[int, ...], vf_arch: tuple[int, ...], n_actions: int, activation: str, ortho_init: bool
) -> tuple[MLP, MLP]:
    """``(actor, critic)``: the actor maps a (normalized) observation to the action mean, the critic to a value."""
    actor = MLP(tuple(pi_arch), int(n_actions), activation, 0.01, ortho_init)
    critic = MLP(tuple(vf_arch), 1, activation, 1.0, ortho_init)
    return actor, critic


def gaussian_log_prob(action: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    """Log-density of a diagonal Gaussian, summed over the last axis."""
    z = (action - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * jnp.square(z) - log_std - 0.5 * math.log(2.0 * math.pi), axis=-1)


def sde_std(latent: jax.Array, log_std: jax.Array) -> jax.Array:
    """gSDE's action standard deviation ``sqrt((latent²) @ exp(log_std)² + 1e-6)`` (SB3's
    ``StateDependentNoiseDistribution`` with ``full_std``, ``exp``, features not learned: the
    latent enters without its gradient)."""
    latent = jax.lax.stop_gradient(latent)
    return jnp.sqrt(jnp.square(latent) @ jnp.square(jnp.exp(log_std)) + 1e-6)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    """Entropy of the diagonal Gaussian (nats), summed over the action dimensions."""
    return jnp.sum(log_std + 0.5 * math.log(2.0 * math.pi * math.e), axis=-1)
