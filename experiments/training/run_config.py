"""What a training run is (its ``config.json``) and whether ``--resume`` may continue a run
directory: one definition for every backend (:mod:`experiments.training.training` for SB3 and SBX,
:mod:`experiments.training.jax_training` for the fused JAX trainer)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from experiments.jsonable import json_ready

#: the entries of config.json a resumed run must share with the run it continues
RESUME_KEYS = ("algo", "backend", "env_id", "env_kwargs", "seed", "hyperparams", "evaluation")


def config_value(value: Any) -> Any:
    """JSON-ready, callables and classes (schedules, activation classes) as their repr."""
    return json_ready(value, leaf=lambda v: repr(v) if callable(v) or isinstance(v, type) else v)


def run_config(
    algo: str,
    backend: str,
    env_id: str,
    env_kwargs: dict[str, Any],
    seed: int,
    entry: dict[str, Any],
    total: int,
    eval_freq: int,
    eval_episodes: int,
    eval_seed: int,
    eval_kwargs: dict[str, Any],
    checkpoint_freq: int,
) -> dict[str, Any]:
    """The run's ``config.json``: algorithm, backend, env, seed, hyperparameter entry, budget
    (env steps), evaluation (every ``eval_freq`` steps, ``eval_episodes`` from seed ``eval_seed``)
    and checkpoint period (env steps)."""
    return {
        "algo": algo,
        "backend": backend,
        "env_id": env_id,
        "env_kwargs": config_value(env_kwargs),
        "seed": int(seed),
        "hyperparams": config_value(entry),
        "total_timesteps": int(total),
        "evaluation": {
            "freq": int(eval_freq),
            "episodes": int(eval_episodes),
            "seed": int(eval_seed),
            "env_kwargs": config_value(eval_kwargs),
        },
        "checkpoint_freq": int(checkpoint_freq),
    }


def check_resume(
    out_dir: Path, config: dict[str, Any], saved: dict[str, Any] | None, checkpoint: Any, resume: bool
) -> None:
    """``ValueError`` when ``out_dir`` cannot start or continue the run ``config``: a new run in a
    directory that holds one, ``--resume`` with nothing to resume, or a resumed run that differs
    from the saved one (``saved``: its config.json, None if absent) in any of :data:`RESUME_KEYS`."""
    if checkpoint is None:
        if resume and saved is None:
            raise ValueError(
                f"--resume: no complete checkpoint under {str(out_dir / 'checkpoints')!r} and no run there"
            )
    elif not resume:
        raise ValueError(f"{str(out_dir)!r} already holds a run; pass --resume to continue it or choose another --out")
    if resume and saved is not None:
        for key in RESUME_KEYS:
            if key in saved and saved[key] != config[key]:
                hint = f" (pass --backend {saved['backend']})" if key == "backend" else ""
                raise ValueError(f"--resume: {key} {config[key]!r} differs from the run's {saved[key]!r}{hint}")
