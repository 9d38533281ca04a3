"""A training run and its directory, the same for every backend (:mod:`experiments.training.training`
for SB3 and SBX, :mod:`experiments.training.jax_training` for the fused JAX trainer)::

    config.json            algorithm, backend, env id, env kwargs, seed, hyperparameters, budget, eval settings
    checkpoints/           step_<n>/{state.pkl, model.zip, ...}, latest.json (the 2 newest)
    evaluations.csv        timesteps, J_mean, J_std of the periodic evaluations
    best/                  the snapshot with the lowest evaluation J (+ best.json)
    final/                 model.zip (+ final.json) when training completed
    timing.jsonl           per segment: from/to timesteps, wall time (s)

:class:`RunPlan` is what a run is (its ``config.json`` and when it evaluates and checkpoints);
:class:`RunDir` starts or resumes it in its directory (whether ``--resume`` may continue it,
what a run killed before its first checkpoint left, the best snapshot a checkpoint records),
logs its evaluations and writes its final snapshot.
"""

from __future__ import annotations

import json
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from attitude_envs.files import atomic_write
from attitude_envs.files import read_json as read_json_file
from experiments.jsonable import json_ready, repr_code
from experiments.training.algorithm import Algorithm
from experiments.training.callbacks import EvalLog, read_json, save_snapshot

#: the entries of config.json a resumed run must share with the run it continues
RESUME_KEYS = ("algo", "backend", "env_id", "env_kwargs", "seed", "hyperparams", "evaluation")
#: a checkpoint's resumable state, in ``checkpoints/step_<n>/``
STATE_FILE = "state.pkl"


def config_value(value: Any) -> Any:
    """JSON-ready, callables and classes (schedules, activation classes) as their repr."""
    return json_ready(value, leaf=repr_code)


def run_budget(total_timesteps: int | None, default: Any, schedule_timesteps: int | None) -> tuple[int, int]:
    """``(total, horizon)``: the run's budget in env steps (``total_timesteps``, else the entry's
    ``default``) and the one its schedules anneal over (``schedule_timesteps``, else ``total``)."""
    total = int(total_timesteps if total_timesteps is not None else float(default))
    if total < 1:
        raise ValueError(f"total_timesteps must be >= 1, got {total}")
    horizon = total if schedule_timesteps is None else int(schedule_timesteps)
    if horizon < total:
        raise ValueError(f"schedule_timesteps must be >= total_timesteps ({total}), got {schedule_timesteps}")
    return total, horizon


@dataclass(frozen=True)
class RunPlan:
    """What a training run is: ``algorithm`` on ``env_id`` with ``env_kwargs`` from ``seed``, its
    Zoo ``entry``, ``total`` env steps (schedules annealed over ``horizon``), evaluated every
    ``eval_freq`` env steps on ``eval_episodes`` episodes of ``eval_kwargs`` from seed
    ``eval_seed``, checkpointed every ``checkpoint_freq``."""

    algorithm: Algorithm
    env_id: str
    env_kwargs: dict[str, Any]
    eval_kwargs: dict[str, Any]
    seed: int
    entry: dict[str, Any]
    total: int
    horizon: int
    eval_freq: int
    eval_episodes: int
    eval_seed: int
    checkpoint_freq: int

    def config(self) -> dict[str, Any]:
        """The run's ``config.json``."""
        return {
            "algo": self.algorithm.name,
            "backend": self.algorithm.backend,
            "env_id": self.env_id,
            "env_kwargs": config_value(self.env_kwargs),
            "seed": int(self.seed),
            "hyperparams": config_value(self.entry),
            "total_timesteps": int(self.total),
            "evaluation": {
                "freq": int(self.eval_freq),
                "episodes": int(self.eval_episodes),
                "seed": int(self.eval_seed),
                "env_kwargs": config_value(self.eval_kwargs),
            },
            "checkpoint_freq": int(self.checkpoint_freq),
        }

    @property
    def eval_seeds(self) -> list[int]:
        """The seeds of the evaluation episodes."""
        return [int(self.eval_seed) + i for i in range(int(self.eval_episodes))]

    def segment_end(self, done: int) -> int:
        """Where the segment that starts at ``done`` env steps ends: the next multiple of
        ``eval_freq`` or ``checkpoint_freq``, or the budget."""
        return min(_next_multiple(done, self.eval_freq), _next_multiple(done, self.checkpoint_freq), self.total)

    def note_whole_rollouts(self, rollout: int | None, n_envs: int, hint: str = "") -> None:
        """Say on stderr when the budget is not a whole number of rollouts of ``rollout`` env steps
        (over ``n_envs`` envs; None: a rollout is an episode): training stops at the end of the
        rollout that reaches it. ``hint``: how to set the rollout."""
        planned = self.total if rollout is None else -(-self.total // rollout) * rollout
        if planned != self.total:
            print(
                f"note: {self.algorithm.name} trains in whole rollouts of {rollout} env steps ({n_envs} envs): "
                f"a budget of {self.total} steps trains {planned}{hint}",
                file=sys.stderr,
                flush=True,
            )

    def evaluates(self, done: int, steps: int) -> bool:
        """Whether the segment from ``done`` to ``steps`` env steps ends with an evaluation."""
        return steps // self.eval_freq > done // self.eval_freq or steps >= self.total


def _next_multiple(steps: int, every: int) -> int:
    return (steps // int(every) + 1) * int(every)


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


def latest_checkpoint(out_dir: Path) -> dict[str, Any] | None:
    """``{"timesteps", "path"}`` of the last complete checkpoint of a run, or None. ``ValueError``
    for a checkpoint without ``state.pkl`` (written by an earlier version: not resumable exactly)."""
    pointer = Path(out_dir) / "checkpoints" / "latest.json"
    if not pointer.is_file():
        return None
    data = read_json_file(pointer, "the checkpoint pointer")
    if not isinstance(data, dict) or not isinstance(data.get("dir"), str) or "timesteps" not in data:
        raise ValueError(
            f"the checkpoint pointer {str(pointer)!r} lacks its 'dir' and 'timesteps': restore or delete it"
        )
    path = pointer.parent / data["dir"]
    if not (path / STATE_FILE).is_file():
        raise ValueError(
            f"checkpoint {str(path)!r} has no {STATE_FILE} (written by an earlier version, or deleted); "
            "it cannot be resumed exactly: start the run again in an empty --out"
        )
    return {"timesteps": int(data["timesteps"]), "path": path}


@dataclass
class TrainResult:
    """Where the trained model is, how many steps it has seen and its last evaluation J."""

    out_dir: Path
    model_path: Path
    timesteps: int
    resumed_from: int | None
    wall_time_s: float
    last_eval: dict[str, float] | None
    already_complete: bool = False  # resumed at or past its budget: nothing trained


class RunDir:
    """The directory ``path`` of the run ``plan``. Construction checks that it may start or
    (``resume``) continue the run there (:func:`check_resume`; ``saved``: its config.json, None
    if absent) and writes nothing; ``checkpoint`` is its last complete checkpoint (None: start).

    ``run`` (checkpointed with the model) is the run's bookkeeping: ``eval_log`` (the text of
    ``evaluations.csv`` up to the checkpoint), ``best`` and ``last_eval`` (evaluation rows)."""

    def __init__(self, path: Path, plan: RunPlan, saved: dict[str, Any] | None, resume: bool) -> None:
        self.path = Path(path)
        self.plan = plan
        self.config = plan.config()
        self.checkpoint = latest_checkpoint(self.path)
        check_resume(self.path, self.config, saved, self.checkpoint, resume)
        self.evaluations = EvalLog(self.path)

    def start(self) -> dict[str, Any]:
        """A new run, or one killed before its first checkpoint, started (again) from scratch:
        what such a run left is removed and ``config.json`` written. Returns the empty ``run``."""
        for name in ("evaluations.csv", "evaluations.csv.tmp"):
            (self.path / name).unlink(missing_ok=True)
        for name in ("best", "best.tmp", "best.old", "final", "final.tmp", "final.old", "checkpoints"):
            if (self.path / name).is_dir():
                shutil.rmtree(self.path / name)
        self.path.mkdir(parents=True, exist_ok=True)
        self._write_config()
        return {"eval_log": "", "best": None, "last_eval": None}

    def resume(self, run: dict[str, Any], steps: int, model) -> None:
        """Continue from the checkpoint's ``run`` at ``steps`` env steps (``model``: its
        snapshot, as :func:`~experiments.training.callbacks.save_snapshot` writes it):
        ``evaluations.csv`` cut back to the checkpoint's, ``best/`` made the snapshot it records,
        ``config.json`` written."""
        self.evaluations.restore(run["eval_log"])  # drops rows written after this checkpoint by the killed run
        self._reconcile_best(run["best"], steps, model)
        self._write_config()

    def _write_config(self) -> None:
        atomic_write(self.path / "config.json", json.dumps(self.config, indent=2) + "\n", durable=True)

    def _reconcile_best(self, best: dict[str, Any] | None, steps: int, model) -> None:
        """Make ``best/`` the snapshot the checkpoint says is best. ``best/`` is written only after
        the checkpoint of its step, so it can lag behind (killed in between): then that checkpoint's
        model is the best one. A ``best/`` without a recorded best is from a killed run: removed."""
        best_dir = self.path / "best"
        if best is None:
            if best_dir.exists():
                shutil.rmtree(best_dir)
            return
        if read_json(best_dir / "best.json") == best and (best_dir / "model.zip").is_file():
            return
        if int(best["timesteps"]) != int(steps):
            raise ValueError(
                f"{str(best_dir)!r} does not hold the best snapshot its checkpoint records ({best}); "
                "the run directory was changed by hand: start it again in an empty --out"
            )
        self.save_best(best, model)

    def record(self, run: dict[str, Any], row: dict[str, Any]) -> bool:
        """Log the evaluation ``row`` (appended to ``evaluations.csv``, fsynced, before the
        checkpoint that follows it) in ``run``; True when it is the best so far: the fewest
        validation episodes with a constraint violated (an env with constraints), then the
        lowest mean J."""
        text = self.evaluations.row_text(row, header=not run["eval_log"])
        self.evaluations.append(text)
        run["eval_log"] += text
        run["last_eval"] = row

        def rank(r: dict[str, Any]) -> tuple[float, float]:
            return (float(r.get("violating_episodes", 0)), float(r["J_mean"]))

        if run["best"] is None or rank(row) < rank(run["best"]):
            run["best"] = row
            return True
        return False

    def save_best(self, best: dict[str, Any], model) -> None:
        """``model``'s snapshot in ``best/`` with ``best.json`` (its evaluation row)."""
        save_snapshot(model, self.path / "best", meta={"best.json": json.dumps(best) + "\n"})

    def finish(self, segment: dict[str, Any] | None, steps: int, model: Callable[[], Any]) -> Path:
        """Append the training ``segment`` (None: nothing trained) to ``timing.jsonl`` and write
        ``final/`` from ``model()`` unless it already holds the snapshot of ``steps``; returns
        the final model file."""
        if segment is not None:  # the run's training time over all its segments (the report sums them)
            with (self.path / "timing.jsonl").open("a", encoding="utf-8") as fh:
                fh.write(json.dumps(segment) + "\n")
        final = self.path / "final"
        marker = {"timesteps": int(steps)}
        if read_json(final / "final.json") != marker or not (final / "model.zip").is_file():
            save_snapshot(model(), final, meta={"final.json": json.dumps(marker) + "\n"})
        return final / "model.zip"
