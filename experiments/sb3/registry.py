"""Algorithm registry: name → Stable-Baselines3 (or sb3-contrib) class, imported lazily."""

from __future__ import annotations

import importlib

from experiments.sb3.backends import check_backend, sbx_class

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
    its JAX port); ``ValueError`` if unknown or its package is not installed."""
    if check_backend(backend, check_algorithm(name)) == "sbx":
        return sbx_class(check_algorithm(name))
    module, cls, _ = ALGORITHMS[check_algorithm(name)]
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError as exc:
        extra = "sb3-contrib" if module == "sb3_contrib" else "stable-baselines3"
        raise ValueError(f"algorithm {name!r} needs the package {extra!r} (pip install attitude-envs[sb3])") from exc


def is_off_policy(name: str) -> bool:
    """True for replay-buffer algorithms (their buffer is checkpointed)."""
    return ALGORITHMS[check_algorithm(name)][2]
