"""Training bookkeeping: evaluation on the shared cost J and its log, snapshots, durable writes, progress."""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from attitude_envs.evaluation.rollout import rollout
from experiments.sb3.policy import SB3Policy


def fsync_dir(path: Path) -> None:
    """Make a rename or a new file in directory ``path`` durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a fsynced temporary file and ``os.replace`` (never half-written)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", encoding="utf-8", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    fsync_dir(path.parent)


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


class EvalLog:
    """``evaluations.csv`` (``timesteps, J_mean, J_std``): each row appended and fsynced before the
    checkpoint that follows it; :meth:`restore` puts back the text a checkpoint recorded (a run
    killed after an evaluation but before its checkpoint evaluates that step again)."""

    FIELDS = ("timesteps", "J_mean", "J_std")

    def __init__(self, out_dir: Path) -> None:
        self.path = Path(out_dir) / "evaluations.csv"

    def row_text(self, row: dict[str, Any], header: bool) -> str:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=list(self.FIELDS))
        if header:
            writer.writeheader()
        writer.writerow({k: row[k] for k in self.FIELDS})
        return buffer.getvalue()

    def append(self, text: str) -> None:
        new = not self.path.is_file()
        with self.path.open("a", newline="", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        if new:
            fsync_dir(self.path.parent)

    def restore(self, text: str) -> None:
        if text:
            atomic_write_text(self.path, text)
        else:
            self.path.unlink(missing_ok=True)


def write_model_files(model, directory: Path) -> None:
    """``model.zip`` (SB3's portable format) and, with normalization, ``vecnormalize.pkl``."""
    model.save(Path(directory) / "model.zip")
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        vecnorm.save(str(Path(directory) / "vecnormalize.pkl"))


def save_snapshot(model, directory: Path, meta: dict[str, str] | None = None) -> None:
    """Model (+ VecNormalize statistics, + ``meta`` text files) into ``directory``, written as a
    temporary directory that replaces the old one."""
    directory = Path(directory)
    tmp = directory.with_name(directory.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    write_model_files(model, tmp)
    for name, text in (meta or {}).items():
        (tmp / name).write_text(text, encoding="utf-8")
    old = directory.with_name(directory.name + ".old")
    if old.exists():
        shutil.rmtree(old)
    if directory.exists():
        os.replace(directory, old)
    os.replace(tmp, directory)
    shutil.rmtree(old, ignore_errors=True)


def read_json(path: Path) -> Any:
    """A JSON file's content, or None if it is missing or cut."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (FileNotFoundError, json.JSONDecodeError):
        return None
