"""Fused PPO: Stable-Baselines3's PPO as one jitted JAX program (PureJaxRL style).

Lu et al. 2022, "Discovered Policy Optimisation" (NeurIPS), showed that with the env written
in JAX a whole PPO run (env steps, rollout, GAE, minibatch epochs, optimizer) compiles into
one XLA program, and ``jax.vmap`` trains many seeds and settings at once. This package does
that on the suite's JAX plants (:mod:`attitude_envs.jax`) with the meaning of a Zoo PPO entry
(``experiments/training/hyperparams/ppo.yml``) under Stable-Baselines3 2.x. Modules, one job each:

* ``config`` — a Zoo entry → :class:`PPOConfig` (static shapes) + :class:`Hparams` (traced
  floats), checked; numpy only.
* ``networks`` — the actor and critic MLPs (flax linen) and the Gaussian's log-density.
* ``normalization`` — SB3's ``VecNormalize`` statistics as pure functions.
* ``trainer`` — :func:`make_train` (``train(key, hparams)``) and :func:`make_chunked`
  (``init``, ``update_chunk``), and :func:`policy_arrays` (a state's actor as numpy).
* ``export`` — :class:`PolicyArrays`, the model file, :class:`NumpyPPOPolicy` (SB3's
  ``predict``); numpy only, so a trained policy plays without jax.

The jax-dependent names are imported on first use: ``from agents.fused_ppo import
NumpyPPOPolicy`` needs no jax.
"""

from __future__ import annotations

from typing import Any

from agents.fused_ppo.config import Hparams, PPOConfig, from_zoo, stack_hparams
from agents.fused_ppo.export import NumpyPPOPolicy, PolicyArrays, load_policy, save_policy

_TRAINER = ("make_train", "make_chunked", "policy_arrays", "select", "RunnerState", "per_update_episode_means")

__all__ = [
    "Hparams",
    "NumpyPPOPolicy",
    "PPOConfig",
    "PolicyArrays",
    "from_zoo",
    "load_policy",
    "save_policy",
    "stack_hparams",
    *_TRAINER,
]


def __getattr__(name: str) -> Any:
    if name in _TRAINER:
        from agents.fused_ppo import trainer  # jax, flax, optax

        return getattr(trainer, name)
    raise AttributeError(f"module 'agents.fused_ppo' has no attribute {name!r}")
