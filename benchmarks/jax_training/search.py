"""The search section: ``attitude-envs tune --backend jax`` with many settings in a child
process, its wall time, compile/train/eval split and best value."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.jax_training.children import child_env
from benchmarks.jax_training.task import ROOT, Task, say


def search(
    task: Task, settings: int, timesteps: int, evaluations: int, eval_episodes: int, workdir: Path
) -> dict[str, Any]:
    """``attitude-envs tune --backend jax`` in a child process (this process's affinity): its
    wall time, compile/train/eval split (population.json) and best value."""
    out = workdir / "search"
    cmd = [sys.executable, "-m", "experiments.cli", "tune", "--algo", "ppo", "--env", task.env_id]
    cmd += ["--env-kwargs", json.dumps(task.env_kwargs), "--backend", "jax", "--trials", str(settings)]
    cmd += ["--timesteps", str(timesteps), "--evaluations", str(evaluations), "--eval-episodes", str(eval_episodes)]
    cmd += ["--out", str(out)]
    say(f"search: {settings} settings × {timesteps} steps")
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=child_env(), capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"tune failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    population = json.loads((out / "population.json").read_text(encoding="utf-8"))
    values = [min(e["J_mean"] for e in t["evaluations"]) for t in population["trials"] if t["evaluations"]]
    groups = population["groups"]
    return {
        "env": task.env_id,
        "env_kwargs": task.env_kwargs,
        "command": " ".join(["attitude-envs", *cmd[3:-1], "DIR"]),
        "settings": int(settings),
        "timesteps_per_setting": int(timesteps),
        "wall_s": wall,
        "compile_s": sum(g["compile_s"] for g in groups),
        "train_s": sum(g["train_s"] for g in groups),
        "eval_s": sum(g["eval_s"] for g in groups),
        "env_steps_per_s": sum(g["timesteps_per_setting"] * g["settings"] for g in groups)
        / max(sum(g["train_s"] for g in groups), 1e-9),
        "best_value": float(min(values)),
        "median_value": float(np.median(values)),
        "units": {
            "wall_s": "s of the whole tune process (interpreter start to exit)",
            "best_value": f"eval J of the best setting (mean over {eval_episodes} validation seeds 10000+)",
            "env_steps_per_s": "all settings together, training only",
        },
        "pinned": "one CPU (the child inherits this process's affinity)",
    }
