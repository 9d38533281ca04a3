"""Training backends: Stable-Baselines3 (PyTorch, the default), SBX (the SB3 maintainers' JAX
port with the same API, the optional ``sbx`` extra) and ``jax`` (PPO only: the suite's fused
trainer, :mod:`agents.fused_ppo`, one jitted program per run on the JAX plants of
:mod:`attitude_envs.jax`; the optional ``jax`` extra; :mod:`experiments.training.jax_training`).

A Zoo-format hyperparameter entry may say ``backend: sbx``; ``train --backend`` overrides it.
The same entry serves every backend: :func:`policy_kwargs_for` maps what differs (activation
classes, PPO's orthogonal initialization, on in SB3 and off in SBX by default).
"""

from __future__ import annotations

import importlib.util
import sys
from typing import Any

BACKENDS = ("sb3", "sbx", "jax")

#: the algorithms the fused JAX trainer implements
JAX_ALGORITHMS = ("ppo",)
#: the packages the jax backend needs (the jax extra)
JAX_PACKAGES = ("jax", "flax", "optax")

# the algorithms SBX implements (same names and constructor arguments as SB3's)
SBX_ALGORITHMS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "ddpg": "DDPG", "tqc": "TQC"}

# Threads: JAX sizes its CPU thread pool from the process's CPU affinity and has no setting for
# it (the XLA_FLAGS options --xla_cpu_multi_thread_eigen / intra_op_parallelism_threads, the
# usual advice, change nothing in jax 0.10: measured, 2 Eigen threads and 1.5 cores busy per
# process on 2 cores either way). Campaign workers therefore pin themselves to one CPU each
# (experiments.processes.pin_to_one_core); a single `train` run keeps JAX's default.


def _installed(package: str) -> bool:
    """Whether ``package`` can be imported (without importing it)."""
    if package in sys.modules:
        return sys.modules[package] is not None  # None: blocked (as tests simulate a missing package)
    try:
        return importlib.util.find_spec(package) is not None
    except (ImportError, ValueError):
        return False


def check_backend(backend: str, algo: str) -> str:
    """The lower-cased backend name; ``ValueError`` naming the accepted ones otherwise (SBX: for
    the algorithms it implements)."""
    key = str(backend).lower()
    if key not in BACKENDS:
        raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if key == "sbx" and algo not in SBX_ALGORITHMS:
        raise ValueError(f"backend 'sbx' implements {sorted(SBX_ALGORITHMS)}, not {algo!r}; use backend 'sb3'")
    if key == "jax":
        if algo not in JAX_ALGORITHMS:
            raise ValueError(
                f"backend 'jax' implements {list(JAX_ALGORITHMS)}, not {algo!r}; use backend 'sb3' or 'sbx'"
            )
        missing = [name for name in JAX_PACKAGES if not _installed(name)]
        if missing:
            raise ValueError(
                f"backend 'jax' needs the optional packages {', '.join(JAX_PACKAGES)} (missing: {', '.join(missing)}): "
                "pip install 'attitude-envs[jax]'; or train with --backend sb3"
            )
    return key


def sbx_class(algo: str):
    """The SBX class of ``algo`` (``ValueError`` when the ``sbx`` extra is not installed)."""
    check_backend("sbx", algo)
    try:
        import sbx  # optional: the sbx extra (JAX)
    except ImportError as exc:
        raise ValueError(
            "backend 'sbx' needs the optional packages sbx-rl and jax (pip install 'attitude-envs[sbx]'; "
            "or train on PyTorch: --backend sb3)"
        ) from exc
    return getattr(sbx, SBX_ALGORITHMS[algo])


_FLAX_ACTIVATIONS = {
    "ReLU": "relu",
    "Tanh": "tanh",
    "ELU": "elu",
    "GELU": "gelu",
    "SiLU": "silu",
    "LeakyReLU": "leaky_relu",
}


def policy_kwargs_for(backend: str, algo: str, policy_kwargs: dict[str, Any] | None) -> dict[str, Any] | None:
    """``policy_kwargs`` of a Zoo entry for ``backend``. For SBX: ``nn.<Activation>`` (a torch
    class) becomes the flax function of the same name, and PPO gets ``ortho_init=True`` unless
    the entry sets it (SB3's default; SBX's default False starts PPO far worse)."""
    if backend != "sbx":
        return policy_kwargs
    out = dict(policy_kwargs or {})
    activation = out.get("activation_fn")
    if isinstance(activation, type):
        name = _FLAX_ACTIVATIONS.get(activation.__name__)
        if name is None:
            raise ValueError(
                f"activation_fn {activation.__name__} has no SBX equivalent here; accepted: {sorted(_FLAX_ACTIVATIONS)}"
            )
        import flax.linen as fnn  # optional: the sbx extra

        out["activation_fn"] = getattr(fnn, name)
    if algo == "ppo":
        out.setdefault("ortho_init", True)
    return out or None
