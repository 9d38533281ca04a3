"""Training bookkeeping: evaluation on the shared cost J and its log, snapshots and checkpoint folders."""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.evaluation.rollout import rollout
from attitude_envs.files import atomic_write, fsync_dir
from experiments.training.policy import SB3Policy


def new_checkpoint_dir(root: Path, steps: int) -> tuple[Path, Path]:
    """``(root/step_<steps>, its fresh .tmp twin)`` for a checkpoint being written; removes the
    ``.tmp`` folders a run killed while writing one left behind."""
    directory = root / f"step_{int(steps):012d}"
    for stale in root.glob("step_*.tmp"):
        shutil.rmtree(stale)
    tmp = directory.with_name(directory.name + ".tmp")
    tmp.mkdir(parents=True)
    return directory, tmp


def publish_checkpoint(root: Path, tmp: Path, directory: Path, steps: int, keep: int) -> Path:
    """Move the fully written ``tmp`` to ``directory``, point ``root/latest.json`` at it (atomic,
    fsynced) and keep the ``keep`` newest ``step_*`` checkpoints."""
    if directory.exists():  # a checkpoint of the same step from a run killed before its pointer moved
        shutil.rmtree(directory)
    os.replace(tmp, directory)
    fsync_dir(root)
    atomic_write(
        root / "latest.json", json.dumps({"timesteps": int(steps), "dir": directory.name}) + "\n", durable=True
    )
    done = sorted(p for p in root.glob("step_*") if p.is_dir() and not p.name.endswith(".tmp"))
    for old in done[: -max(1, int(keep))]:
        shutil.rmtree(old, ignore_errors=True)
    return directory


class NormalizedPredictor:
    """A model whose ``predict`` first applies frozen VecNormalize observation statistics and,
    with ``frame_stack`` > 1, stacks the latest normalized observations as SB3's
    ``VecFrameStack`` does in training: oldest first, zeros before the episode's first one,
    reset where ``episode_start`` is set (one history per row of a batched ``obs``)."""

    def __init__(self, model, vec_normalize=None, frame_stack: int = 1) -> None:
        if int(frame_stack) < 1:
            raise ValueError(f"frame_stack must be >= 1, got {frame_stack!r}")
        self.model = model
        self.vec_normalize = vec_normalize
        self.frame_stack = int(frame_stack)
        self._stack: np.ndarray | None = None

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        if self.vec_normalize is not None and self.vec_normalize.norm_obs:
            obs = self.vec_normalize.normalize_obs(np.asarray(obs))
        if self.frame_stack > 1:
            obs = self._stacked(np.asarray(obs), episode_start)
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)

    def _stacked(self, obs: np.ndarray, episode_start) -> np.ndarray:
        single = obs.ndim == 1
        rows = obs.reshape(1, -1) if single else obs
        n, d = rows.shape
        starts = np.ones(n, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(n)
        if self._stack is None or self._stack.shape != (n, d * self.frame_stack):
            self._stack, starts = np.zeros((n, d * self.frame_stack), dtype=rows.dtype), np.ones(n, dtype=bool)
        self._stack[starts] = 0.0
        self._stack = np.roll(self._stack, -d, axis=1)
        self._stack[:, -d:] = rows
        return self._stack[0].copy() if single else self._stack.copy()


def evaluate_cost(predictor, env, seeds: list[int], name: str = "sb3") -> dict[str, float]:
    """Mean and std of the episode cost J (sum of ``info["cost"]``) over ``seeds`` (one episode
    each): on a single env one episode after the other, on a batched env (one sub-env per seed,
    :func:`episode_costs_batched`) all at once. For an env with constraints (single env), also
    ``violating_episodes``: the episodes with a violating step."""
    if isinstance(env, gym.vector.VectorEnv):
        costs = episode_costs_batched(predictor, env, seeds)
        return {"J_mean": float(costs.mean()), "J_std": float(costs.std())}
    runs = _rollouts(predictor, env, seeds, name)
    costs = np.array([r["J"] for r in runs])
    out = {"J_mean": float(costs.mean()), "J_std": float(costs.std())}
    if runs and all("violations" in r for r in runs):
        out["violating_episodes"] = int(sum(r["violations"] > 0 for r in runs))
    return out


def episode_costs(predictor, env, seeds: list[int], name: str = "sb3") -> np.ndarray:
    """The cost J of one episode per seed (see :func:`evaluate_cost`)."""
    if isinstance(env, gym.vector.VectorEnv):
        return episode_costs_batched(predictor, env, seeds)
    return np.array([r["J"] for r in _rollouts(predictor, env, seeds, name)])


def _rollouts(predictor, env, seeds: list[int], name: str) -> list[dict[str, Any]]:
    """One :func:`~attitude_envs.evaluation.rollout.rollout` per seed of the deterministic policy, one after the other."""
    policy = SB3Policy(predictor, deterministic=True, name=name)
    return [rollout(env, policy, seed=s) for s in seeds]


def episode_costs_batched(predictor, env, seeds: list[int]) -> np.ndarray:
    """J of ``len(seeds)`` episodes run as one batch: sub-env ``i`` of ``env`` (a natively batched
    env with ``autoreset_mode="next_step"`` and one sub-env per seed) plays the episode of seed
    ``seeds[i]``, one ``predict`` call per step for all of them; a sub-env whose episode ended
    stops contributing (its cost is summed in the single env's order, so J is the single env's
    given the same actions). The actions equal the one-by-one evaluation's up to the policy
    network's float rounding: a batched matrix product need not round each row as a single one."""
    n = int(env.num_envs)
    if len(seeds) != n:
        raise ValueError(f"the batched eval env has {n} sub-envs for {len(seeds)} seeds")
    obs, _ = env.reset(seed=[int(s) for s in seeds])
    totals = np.zeros(n)
    running = np.ones(n, dtype=bool)
    state, episode_start = None, np.ones(n, dtype=bool)
    while running.any():
        action, state = predictor.predict(obs, state=state, episode_start=episode_start, deterministic=True)
        episode_start = np.zeros(n, dtype=bool)
        obs, _, terminated, truncated, infos = env.step(np.asarray(action, dtype=np.float32))
        totals[running] += infos["cost"][running]
        running &= ~(terminated | truncated)
    return totals


class EvalLog:
    """``evaluations.csv`` (``timesteps, J_mean, J_std``, and ``violating_episodes`` for an env
    with constraints): each row appended and fsynced before the checkpoint that follows it;
    :meth:`restore` puts back the text a checkpoint recorded (a run killed after an evaluation
    but before its checkpoint evaluates that step again)."""

    FIELDS = ("timesteps", "J_mean", "J_std")
    OPTIONAL = ("violating_episodes",)

    def __init__(self, out_dir: Path) -> None:
        self.path = Path(out_dir) / "evaluations.csv"

    def row_text(self, row: dict[str, Any], header: bool) -> str:
        buffer = io.StringIO()
        fields = [*self.FIELDS, *(k for k in self.OPTIONAL if k in row)]
        writer = csv.DictWriter(buffer, fieldnames=fields)
        if header:
            writer.writeheader()
        writer.writerow({k: row[k] for k in fields})
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
            atomic_write(self.path, text, durable=True)
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
