"""Training callbacks: periodic evaluation on the shared cost J, and resumable checkpoints."""

from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from attitude_envs.evaluation.rollout import rollout
from experiments.sb3.policy import SB3Policy


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and ``os.replace`` (never half-written)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


class NormalizedPredictor:
    """A model whose ``predict`` first applies frozen VecNormalize observation statistics."""

    def __init__(self, model, vec_normalize=None) -> None:
        self.model = model
        self.vec_normalize = vec_normalize

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        if self.vec_normalize is not None and self.vec_normalize.norm_obs:
            obs = self.vec_normalize.normalize_obs(np.asarray(obs))
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)


def evaluate_cost(predictor, env, seeds: list[int], name: str = "sb3") -> dict[str, float]:
    """Mean and std of the episode cost J (sum of ``info["cost"]``) over ``seeds`` (one episode each)."""
    policy = SB3Policy(predictor, deterministic=True, name=name)
    costs = np.array([rollout(env, policy, seed=s)["J"] for s in seeds])
    return {"J_mean": float(costs.mean()), "J_std": float(costs.std())}


class EvalCostCallback(BaseCallback):
    """Every ``eval_freq`` environment steps, runs the deterministic policy on a separate,
    seeded eval env (episode ``i`` seeded ``eval_seed + i``, the same episodes every time)
    and appends ``timesteps, J_mean, J_std`` to ``evaluations.csv``; keeps the best model."""

    def __init__(self, eval_env, out_dir: Path, eval_freq: int, n_episodes: int = 5, eval_seed: int = 10_000) -> None:
        super().__init__()
        if eval_freq < 1 or n_episodes < 1:
            raise ValueError(f"eval_freq and eval episodes must be >= 1, got {eval_freq} and {n_episodes}")
        self.eval_env = eval_env
        self.out_dir = Path(out_dir)
        self.eval_freq = int(eval_freq)
        self.seeds = [int(eval_seed) + i for i in range(int(n_episodes))]
        self._last = 0
        self.best_J = np.inf
        self.history: list[dict[str, float]] = []

    def _init_callback(self) -> None:
        self._last = int(self.model.num_timesteps)  # the callback's own counter is only set on the first step
        best = self.out_dir / "best" / "best.json"
        if best.is_file():
            self.best_J = float(json.loads(best.read_text())["J_mean"])

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.eval_freq:
            self._last = self.num_timesteps
            self.run_evaluation()
        return True

    def run_evaluation(self) -> dict[str, float]:
        vecnorm = self.model.get_vec_normalize_env()
        result = evaluate_cost(NormalizedPredictor(self.model, vecnorm), self.eval_env, self.seeds)
        row = {"timesteps": self.num_timesteps, **result}
        self.history.append(row)
        path = self.out_dir / "evaluations.csv"
        new = not path.is_file()
        with path.open("a", newline="", encoding="utf-8") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(row))
            if new:
                writer.writeheader()
            writer.writerow(row)
        self.logger.record("eval/J_mean", result["J_mean"])
        if result["J_mean"] < self.best_J:
            self.best_J = result["J_mean"]
            save_snapshot(self.model, self.out_dir / "best", replay_buffer=False)
            atomic_write_text(self.out_dir / "best" / "best.json", json.dumps(row) + "\n")
        if self.verbose or self.model.verbose:
            print(f"eval at {self.num_timesteps} steps: J = {result['J_mean']:.3f} ± {result['J_std']:.3f}")
        return result


def save_snapshot(model, directory: Path, replay_buffer: bool) -> None:
    """Model (+ VecNormalize statistics, + replay buffer) into ``directory`` (written via a temp dir)."""
    directory = Path(directory)
    tmp = directory.with_name(directory.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    model.save(tmp / "model.zip")
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        vecnorm.save(str(tmp / "vecnormalize.pkl"))
    if replay_buffer and getattr(model, "replay_buffer", None) is not None:
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    if directory.exists():
        shutil.rmtree(directory)
    os.replace(tmp, directory)


class ResumableCheckpointCallback(BaseCallback):
    """Every ``save_freq`` environment steps, saves model, VecNormalize statistics and (off-policy)
    the replay buffer to ``checkpoints/step_<n>/`` and only then points ``checkpoints/latest.json``
    at it, so a run killed at any moment resumes from its last complete checkpoint.
    Keeps the ``keep`` newest checkpoints."""

    def __init__(self, out_dir: Path, save_freq: int, replay_buffer: bool, keep: int = 2) -> None:
        super().__init__()
        if save_freq < 1:
            raise ValueError(f"checkpoint frequency must be >= 1 step, got {save_freq}")
        self.root = Path(out_dir) / "checkpoints"
        self.save_freq = int(save_freq)
        self.replay_buffer = bool(replay_buffer)
        self.keep = max(1, int(keep))
        self._last = 0

    def _init_callback(self) -> None:
        self._last = int(self.model.num_timesteps)  # the callback's own counter is only set on the first step

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.save_freq:
            self._last = self.num_timesteps
            self.save()
        return True

    def save(self) -> Path:
        steps = int(self.model.num_timesteps)
        directory = self.root / f"step_{steps:012d}"
        save_snapshot(self.model, directory, self.replay_buffer)
        atomic_write_text(self.root / "latest.json", json.dumps({"timesteps": steps, "dir": directory.name}) + "\n")
        done = sorted(p for p in self.root.glob("step_*") if p.is_dir() and not p.name.endswith(".tmp"))
        for old in done[: -self.keep]:
            shutil.rmtree(old, ignore_errors=True)
        return directory


def latest_checkpoint(out_dir: Path) -> dict[str, Any] | None:
    """``{"timesteps", "path"}`` of the last complete checkpoint of a run, or None."""
    pointer = Path(out_dir) / "checkpoints" / "latest.json"
    if not pointer.is_file():
        return None
    data = json.loads(pointer.read_text(encoding="utf-8"))
    path = pointer.parent / data["dir"]
    return {"timesteps": int(data["timesteps"]), "path": path} if (path / "model.zip").is_file() else None
