"""What trains: an algorithm on a backend, parsed once into :class:`Algorithm` and passed down.

Backends: ``"sb3"`` (Stable-Baselines3 or sb3-contrib on PyTorch, the default), ``"sbx"`` (the
SB3 maintainers' JAX port with the same API, the optional ``sbx`` extra) and ``"jax"`` (PPO only:
the suite's fused trainer, :mod:`agents.fused_ppo`, one jitted program per run on the JAX plants
of :mod:`attitude_envs.jax`; the optional ``jax`` extra; :mod:`experiments.training.jax_training`).

A Zoo-format hyperparameter entry may say ``backend: sbx``; ``train --backend`` overrides it.
The same entry serves every backend: :meth:`Algorithm.policy_kwargs` maps what differs
(activation classes, PPO's orthogonal initialization, on in SB3 and off in SBX by default).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from dataclasses import dataclass
from typing import Any

# name → (module, class, off_policy)
ALGORITHMS: dict[str, tuple[str, str, bool]] = {
    "ppo": ("stable_baselines3", "PPO", False),
    "a2c": ("stable_baselines3", "A2C", False),
    "sac": ("stable_baselines3", "SAC", True),
    "td3": ("stable_baselines3", "TD3", True),
    "ddpg": ("stable_baselines3", "DDPG", True),
    "tqc": ("sb3_contrib", "TQC", True),
    "recurrentppo": ("sb3_contrib", "RecurrentPPO", False),
}

BACKENDS = ("sb3", "sbx", "jax")

#: the algorithms the fused JAX trainer implements
JAX_ALGORITHMS = ("ppo",)
#: the packages the jax backend needs (the jax extra)
JAX_PACKAGES = ("jax", "flax", "optax")

# the algorithms SBX implements (same names and constructor arguments as SB3's)
SBX_ALGORITHMS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "ddpg": "DDPG", "tqc": "TQC"}

#: the constructors' default rollout length (n_steps) of the on-policy algorithms
_DEFAULT_N_STEPS = {"ppo": 2048, "a2c": 5, "recurrentppo": 128}

# Threads: JAX sizes its CPU thread pool from the process's CPU affinity and has no setting for
# it (the XLA_FLAGS options --xla_cpu_multi_thread_eigen / intra_op_parallelism_threads, the
# usual advice, change nothing in jax 0.10: measured, 2 Eigen threads and 1.5 cores busy per
# process on 2 cores either way). Campaign workers therefore pin themselves to one CPU each
# (experiments.processes.pin_to_one_core); a single `train` run keeps JAX's default.

_FLAX_ACTIVATIONS = {
    "ReLU": "relu",
    "Tanh": "tanh",
    "ELU": "elu",
    "GELU": "gelu",
    "SiLU": "silu",
    "LeakyReLU": "leaky_relu",
}


def _installed(package: str) -> bool:
    """Whether ``package`` can be imported (without importing it)."""
    if package in sys.modules:
        return sys.modules[package] is not None  # None: blocked (as tests simulate a missing package)
    try:
        return importlib.util.find_spec(package) is not None
    except (ImportError, ValueError):
        return False


def check_algorithm(name: str) -> str:
    """The lower-cased algorithm name; ``ValueError`` naming the accepted ones otherwise."""
    key = str(name).lower()
    if key not in ALGORITHMS:
        raise ValueError(f"algorithm must be one of {sorted(ALGORITHMS)}, got {name!r}")
    return key


@dataclass(frozen=True)
class Algorithm:
    """An algorithm (``name``: a key of :data:`ALGORITHMS`) on a training ``backend`` (one of
    :data:`BACKENDS`), both lower-cased and checked at construction: ``ValueError`` naming the
    parameter and the accepted values, also when the backend does not implement the algorithm
    (whether its packages are installed: :meth:`trainable`)."""

    name: str
    backend: str = "sb3"

    def __post_init__(self) -> None:
        name, backend = check_algorithm(self.name), str(self.backend).lower()
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {list(BACKENDS)}, got {self.backend!r}")
        if backend == "sbx" and name not in SBX_ALGORITHMS:
            raise ValueError(f"backend 'sbx' implements {sorted(SBX_ALGORITHMS)}, not {name!r}; use backend 'sb3'")
        if backend == "jax" and name not in JAX_ALGORITHMS:
            raise ValueError(
                f"backend 'jax' implements {list(JAX_ALGORITHMS)}, not {name!r}; use backend 'sb3' or 'sbx'"
            )
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "backend", backend)

    def trainable(self) -> Algorithm:
        """Itself, once the packages the ``jax`` backend trains with are there (``ValueError``
        naming them otherwise; a saved model of any backend loads without them, and SBX's
        are checked when :meth:`model_class` imports it)."""
        if self.backend == "jax":
            missing = [package for package in JAX_PACKAGES if not _installed(package)]
            if missing:
                raise ValueError(
                    f"backend 'jax' needs the optional packages {', '.join(JAX_PACKAGES)} (missing: {', '.join(missing)}): "
                    "pip install 'attitude-envs[jax]'; or train with --backend sb3"
                )
        return self

    @property
    def off_policy(self) -> bool:
        """True for replay-buffer algorithms (their buffer is checkpointed)."""
        return ALGORITHMS[self.name][2]

    def model_class(self):
        """The class that trains and loads it: Stable-Baselines3's or sb3-contrib's (``sb3``), SBX's
        (``sbx``), or the fused trainer's numpy predictor (``jax``), whose ``load`` reads its model
        file (:class:`agents.fused_ppo.NumpyPPOPolicy`); ``ValueError`` when its package is not installed."""
        if self.backend == "jax":
            from agents.fused_ppo.export import NumpyPPOPolicy  # numpy only

            return NumpyPPOPolicy
        if self.backend == "sbx":
            try:
                import sbx  # optional: the sbx extra (JAX)
            except ImportError as exc:
                raise ValueError(
                    "backend 'sbx' needs the optional packages sbx-rl and jax (pip install 'attitude-envs[sbx]'; "
                    "or train on PyTorch: --backend sb3)"
                ) from exc
            return getattr(sbx, SBX_ALGORITHMS[self.name])
        module, cls, _ = ALGORITHMS[self.name]
        try:
            return getattr(importlib.import_module(module), cls)
        except ImportError as exc:
            extra = "sb3-contrib" if module == "sb3_contrib" else "stable-baselines3"
            raise ValueError(
                f"algorithm {self.name!r} needs the package {extra!r} (pip install attitude-envs[sb3])"
            ) from exc

    def rollout_steps(self, kwargs: dict[str, Any], n_envs: int) -> int | None:
        """Env steps (over all ``n_envs``) of one rollout when built with ``kwargs``: training stops
        at the end of the first rollout at or after its budget. On-policy: ``n_steps × n_envs``;
        off-policy: ``train_freq × n_envs`` when ``train_freq`` counts steps; None when it counts episodes."""
        if not self.off_policy:
            return int(kwargs.get("n_steps", _DEFAULT_N_STEPS[self.name])) * int(n_envs)
        freq = kwargs.get("train_freq", 1)
        if isinstance(freq, list | tuple):
            if len(freq) == 2 and str(freq[1]) == "episode":
                return None
            freq = freq[0]
        return int(freq) * int(n_envs)

    def policy_kwargs(self, policy_kwargs: dict[str, Any] | None) -> dict[str, Any] | None:
        """``policy_kwargs`` of a Zoo entry for this backend. For SBX: ``nn.<Activation>`` (a torch
        class) becomes the flax function of the same name, and PPO gets ``ortho_init=True`` unless
        the entry sets it (SB3's default; SBX's default False starts PPO far worse)."""
        if self.backend != "sbx":
            return policy_kwargs
        out = dict(policy_kwargs or {})
        activation = out.get("activation_fn")
        if isinstance(activation, type):
            flax_name = _FLAX_ACTIVATIONS.get(activation.__name__)
            if flax_name is None:
                raise ValueError(
                    f"activation_fn {activation.__name__} has no SBX equivalent here; accepted: {sorted(_FLAX_ACTIVATIONS)}"
                )
            import flax.linen as fnn  # optional: the sbx extra

            out["activation_fn"] = getattr(fnn, flax_name)
        if self.name == "ppo":
            out.setdefault("ortho_init", True)
        return out or None


def check_backend(backend: str, algo: str) -> str:
    """The lower-cased backend name, for a caller that only checks it (a command line, a
    benchmark): :class:`Algorithm`'s checks and :meth:`Algorithm.trainable`."""
    return Algorithm(algo, backend).trainable().backend


def algorithm_class(name: str, backend: str = "sb3"):
    """The class of ``name`` on ``backend`` for a caller that only needs it (checked as
    :func:`check_backend` does): :meth:`Algorithm.model_class`."""
    return Algorithm(name, backend).trainable().model_class()
