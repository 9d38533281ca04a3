"""Train a Stable-Baselines3 agent on a registered env, with periodic J evaluation, checkpoints and resume.

Run directory layout (``out_dir``)::

    config.json            algorithm, env id, env kwargs, seed, resolved hyperparameters
    checkpoints/           step_<n>/{model.zip, vecnormalize.pkl, replay_buffer.pkl}, latest.json
    evaluations.csv        timesteps, J_mean, J_std of the periodic evaluations
    best/                  the snapshot with the lowest evaluation J
    final/                 model.zip (+ vecnormalize.pkl) when training completed
"""

from __future__ import annotations

import json
import pickle
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from attitude_envs.make import check_env_id, make_checked
from experiments.sb3.callbacks import (
    EvalCostCallback,
    NormalizedPredictor,
    ResumableCheckpointCallback,
    atomic_write_text,
    latest_checkpoint,
    save_snapshot,
)
from experiments.sb3.hyperparams import load_hyperparams, split_hyperparams
from experiments.sb3.registry import algorithm_class, check_algorithm, is_off_policy


@dataclass
class TrainResult:
    """Where the trained model is, how many steps it has seen and its last evaluation J."""

    out_dir: Path
    model_path: Path
    timesteps: int
    resumed_from: int | None
    wall_time_s: float
    last_eval: dict[str, float] | None


def _json_safe(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if callable(value) or isinstance(value, type):
        return repr(value)
    return value


def _make_vec_env(env_id: str, env_kwargs: dict, n_envs: int, seed: int):
    return make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=dict(env_kwargs))


def _tensorboard_dir(out_dir: Path, tensorboard: bool | None) -> str | None:
    if tensorboard is False:
        return None
    try:
        import tensorboard as _  # noqa: F401  (optional package: TensorBoard logs only when installed)
    except ImportError as exc:
        if tensorboard:
            raise ValueError(
                "tensorboard logging needs the optional package 'tensorboard' (pip install tensorboard)"
            ) from exc
        return None
    return str(out_dir / "tensorboard")


def train(
    algo: str,
    env_id: str,
    out_dir: str | Path,
    env_kwargs: dict[str, Any] | None = None,
    seed: int = 0,
    hyperparams_file: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    total_timesteps: int | None = None,
    checkpoint_freq: int = 10_000,
    eval_freq: int = 10_000,
    eval_episodes: int = 5,
    eval_seed: int = 10_000,
    eval_env_kwargs: dict[str, Any] | None = None,
    resume: bool = False,
    progress_bar: bool = False,
    tensorboard: bool | None = None,
    verbose: int = 0,
) -> TrainResult:
    """Train (or with ``resume`` continue) an agent; returns where the final model was saved.

    ``total_timesteps`` (env steps over all parallel envs) defaults to the hyperparameter
    file's ``n_timesteps``. ``checkpoint_freq`` and ``eval_freq`` are in env steps (a killed
    run loses at most one checkpoint interval). The eval env uses ``eval_env_kwargs``
    (default: the training kwargs) and seeds ``eval_seed + i``.
    """
    algo = check_algorithm(algo)
    check_env_id(env_id)
    if int(seed) < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    out_dir = Path(out_dir)
    env_kwargs = dict(env_kwargs or {})
    entry = load_hyperparams(algo, env_id, hyperparams_file, overrides)
    probe = make_checked(env_id, **env_kwargs)  # validates the env kwargs before anything is written
    n_actions = int(np.prod(probe.action_space.shape))
    probe.close()
    hp = split_hyperparams(entry, n_actions)
    total = int(total_timesteps if total_timesteps is not None else hp["n_timesteps"])
    if total < 1:
        raise ValueError(f"total_timesteps must be >= 1, got {total}")

    config = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": _json_safe(env_kwargs),
        "seed": int(seed),
        "hyperparams": _json_safe(entry),
        "total_timesteps": total,
    }
    checkpoint = latest_checkpoint(out_dir) if resume else None
    if resume and checkpoint is None:
        raise ValueError(f"--resume: no complete checkpoint under {str(out_dir / 'checkpoints')!r}")
    if checkpoint is None and (out_dir / "checkpoints" / "latest.json").is_file():
        raise ValueError(f"{str(out_dir)!r} already holds a run; pass --resume to continue it or choose another --out")
    if checkpoint is not None:
        saved = json.loads((out_dir / "config.json").read_text(encoding="utf-8"))
        for key in ("algo", "env_id", "env_kwargs", "seed"):
            if saved[key] != config[key]:
                raise ValueError(f"--resume: {key} {config[key]!r} differs from the run's {saved[key]!r}")
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out_dir / "config.json", json.dumps(config, indent=2) + "\n")

    set_random_seed(int(seed))
    torch.set_num_threads(1)
    cls = algorithm_class(algo)
    venv = _make_vec_env(env_id, env_kwargs, hp["n_envs"], int(seed))
    resumed_from = None
    if checkpoint is None:
        if hp["normalize"] is not None:
            venv = VecNormalize(venv, gamma=float(entry.get("gamma", 0.99)), **hp["normalize"])
        try:
            model = cls(
                hp["policy"],
                venv,
                seed=int(seed),
                verbose=verbose,
                tensorboard_log=_tensorboard_dir(out_dir, tensorboard),
                **hp["kwargs"],
            )
        except (TypeError, AssertionError, KeyError) as exc:  # SB3 reports bad hyperparameters this way
            venv.close()
            raise ValueError(f"bad hyperparameters for {algo} ({sorted(hp['kwargs'])}): {exc}") from exc
    else:
        path = checkpoint["path"]
        if (path / "vecnormalize.pkl").is_file():
            venv = VecNormalize.load(str(path / "vecnormalize.pkl"), venv)
        model = cls.load(path / "model.zip", env=venv, custom_objects=_schedules(hp["kwargs"]))
        if is_off_policy(algo) and (path / "replay_buffer.pkl").is_file():
            model.load_replay_buffer(path / "replay_buffer.pkl")
        resumed_from = int(model.num_timesteps)

    eval_env = gym.make(env_id, **dict(eval_env_kwargs if eval_env_kwargs is not None else env_kwargs))
    evaluator = EvalCostCallback(eval_env, out_dir, eval_freq, eval_episodes, eval_seed)
    checkpointer = ResumableCheckpointCallback(out_dir, checkpoint_freq, replay_buffer=is_off_policy(algo))
    start = time.perf_counter()
    remaining = total - int(model.num_timesteps)
    if remaining > 0:
        model.learn(
            remaining,
            callback=[checkpointer, evaluator],
            reset_num_timesteps=checkpoint is None,
            progress_bar=progress_bar,
            tb_log_name=algo,
        )
    last_eval = evaluator.run_evaluation() if not evaluator.history else evaluator.history[-1]
    done = latest_checkpoint(out_dir)
    if done is None or done["timesteps"] != int(model.num_timesteps):
        checkpointer.save()  # a finished run can be extended with --resume and a larger budget
    save_snapshot(model, out_dir / "final", replay_buffer=False)
    eval_env.close()
    venv.close()
    return TrainResult(
        out_dir=out_dir,
        model_path=out_dir / "final" / "model.zip",
        timesteps=int(model.num_timesteps),
        resumed_from=resumed_from,
        wall_time_s=time.perf_counter() - start,
        last_eval=last_eval,
    )


def _schedules(kwargs: dict[str, Any]) -> dict[str, Any]:
    """Custom objects for ``load``: the run's own schedules (lambdas are not pickled portably)."""
    return {k: kwargs[k] for k in ("learning_rate", "clip_range", "clip_range_vf") if k in kwargs}


def load_trained(model_path: str | Path, env: gym.Env | None = None):
    """A saved model (``.../model.zip``; its ``vecnormalize.pkl`` beside it is applied) as a
    predictor with ``predict(obs, ...)``. With ``env``, checks that the observation and action
    spaces match the model's (``ValueError`` naming both otherwise)."""
    model_path = Path(model_path)
    if model_path.is_dir():
        inside = [model_path / "model.zip", model_path / "final" / "model.zip"]
        model_path = next((p for p in inside if p.is_file()), inside[0])
    if not model_path.is_file():
        raise ValueError(f"model file {str(model_path)!r} does not exist")
    algo = _algo_of(model_path)
    cls = algorithm_class(algo)
    model = cls.load(model_path, device="cpu")
    if env is not None:
        for what in ("observation_space", "action_space"):
            ours, theirs = getattr(env, what), getattr(model, what)
            if ours.shape != theirs.shape or not (
                np.allclose(getattr(ours, "low", 0), getattr(theirs, "low", 0))
                and np.allclose(getattr(ours, "high", 0), getattr(theirs, "high", 0))
            ):
                raise ValueError(
                    f"model {str(model_path)!r} was trained for a different env: its {what} is {theirs}, the env's is {ours}"
                )
    vecnorm = None
    stats = model_path.parent / "vecnormalize.pkl"
    if stats.is_file():
        with stats.open("rb") as fh:
            vecnorm = pickle.load(fh)
        vecnorm.training = False
    return NormalizedPredictor(model, vecnorm)


_POLICY_MODULES = {
    "stable_baselines3.sac": "sac",
    "stable_baselines3.td3": "td3",
    "sb3_contrib.tqc": "tqc",
    "sb3_contrib.ppo_recurrent": "recurrentppo",
    "sb3_contrib.common.recurrent": "recurrentppo",
    "stable_baselines3.common.policies": "ppo",  # PPO and A2C share the actor-critic policy
}


def _algo_of(model_path: Path) -> str:
    """The algorithm of a saved model: from the run's config.json, else from its policy's module."""
    for config in (model_path.parent / "config.json", model_path.parent.parent / "config.json"):
        if config.is_file():
            return json.loads(config.read_text(encoding="utf-8"))["algo"]
    try:
        with zipfile.ZipFile(model_path) as zf:
            data = json.loads(zf.read("data").decode("utf-8"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{str(model_path)!r} is not a Stable-Baselines3 model file") from exc
    module = str(data.get("policy_class", {}).get("__module__", ""))
    for prefix, algo in _POLICY_MODULES.items():
        if module.startswith(prefix):
            return algo
    raise ValueError(f"cannot tell the algorithm of {str(model_path)!r}; keep its config.json beside it")
