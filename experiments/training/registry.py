"""Algorithm registry: name → Stable-Baselines3 (or sb3-contrib) class, imported lazily."""

from __future__ import annotations

import importlib

from experiments.training.backends import check_backend, sbx_class

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


def check_algorithm(name: str) -> str:
    """The lower-cased algorithm name; ``ValueError`` naming the accepted ones otherwise."""
    key = str(name).lower()
    if key not in ALGORITHMS:
        raise ValueError(f"algorithm must be one of {sorted(ALGORITHMS)}, got {name!r}")
    return key


def algorithm_class(name: str, backend: str = "sb3"):
    """The class of ``name`` on ``backend`` (``"sb3"``: Stable-Baselines3 or sb3-contrib; ``"sbx"``:
    its JAX port; ``"jax"``: the fused trainer's numpy predictor, whose ``load`` reads its model
    file, :class:`agents.fused_ppo.NumpyPPOPolicy`); ``ValueError`` if unknown or its package is
    not installed."""
    checked = check_backend(backend, check_algorithm(name))
    if checked == "sbx":
        return sbx_class(check_algorithm(name))
    if checked == "jax":
        from agents.fused_ppo.export import NumpyPPOPolicy  # numpy only

        return NumpyPPOPolicy
    module, cls, _ = ALGORITHMS[check_algorithm(name)]
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError as exc:
        extra = "sb3-contrib" if module == "sb3_contrib" else "stable-baselines3"
        raise ValueError(f"algorithm {name!r} needs the package {extra!r} (pip install attitude-envs[sb3])") from exc


def is_off_policy(name: str) -> bool:
    """True for replay-buffer algorithms (their buffer is checkpointed)."""
    return ALGORITHMS[check_algorithm(name)][2]


#: the constructors' default rollout length (n_steps) of the on-policy algorithms
_DEFAULT_N_STEPS = {"ppo": 2048, "a2c": 5, "recurrentppo": 128}


def rollout_steps(name: str, kwargs: dict, n_envs: int) -> int | None:
    """Env steps (over all ``n_envs``) of one rollout of ``name`` built with ``kwargs``: training
    stops at the end of the first rollout at or after its budget. On-policy: ``n_steps × n_envs``;
    off-policy: ``train_freq × n_envs`` when ``train_freq`` counts steps; None when it counts episodes."""
    name = check_algorithm(name)
    if not ALGORITHMS[name][2]:
        return int(kwargs.get("n_steps", _DEFAULT_N_STEPS[name])) * int(n_envs)
    freq = kwargs.get("train_freq", 1)
    if isinstance(freq, list | tuple):
        if len(freq) == 2 and str(freq[1]) == "episode":
            return None
        freq = freq[0]
    return int(freq) * int(n_envs)
