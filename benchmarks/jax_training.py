"""JAX training: the same task and recipe on SB3, SBX and the fused JAX PPO trainer
(:mod:`agents.fused_ppo`, ``train(backend="jax")``), speed and quality side by side.

``python -m benchmarks.jax_training [--quick] [--rounds R] [--seeds S] [--skip-quality]
[--skip-search] [--skip-stepping] [--no-all-cores] [--speed-env ID ...] [--out DIR]`` prints a
markdown summary and writes ``DIR/jax_training.json`` (default ``results/benchmarks/``,
git-ignored; the committed numbers: ``--out benchmarks/results``). The task is a campaign
agent's: PPO on AirBearing-v1 (``experiments/sb3/hyperparams/ppo.yml``, 120 k env steps) with the
kwargs the ``air-bearing`` campaign trains it with, scored on that campaign's cell (AirBearing-v0's
regulation episodes, seeds 0–19) against J* from ``experiments/optimum_table.json``. Sections
(each row states its unit and what was pinned):

* ``speed``: env steps/s of training (rollouts and PPO updates, no evaluation) of SB3 and SBX on
  the native batched env (as ``train`` builds them) and of the fused trainer for one seed (the
  program ``train`` compiles) and for 16 ``jax.vmap``-ped seeds (aggregate steps/s, all seeds
  together). After a warm-up (compilation excluded, reported in ``compile``) the four alternate
  in ``--rounds`` rounds of equal env steps per seed, so that machine noise hits all alike; rows
  give the median and [min, max] of the rounds, ratios the median of the per-round ratios with
  their [min, max]. ``ppo_per_seed_vs_sbx`` = fused 1-seed rate / SBX rate;
  ``ppo_16_seeds_vs_sbx`` = fused 16-seed aggregate rate / SBX's one-seed rate. The process is
  pinned to one CPU (:func:`experiments.processes.pin_to_one_core`, which also sizes JAX's
  thread pool) with ``torch.set_num_threads(1)``, as campaign workers run; ``jax_all_cores``
  repeats the fused rows in a child process on every CPU this process may use (its own rounds;
  its ratios are to the pinned SBX median). ``--speed-env`` adds envs (``speed_other_envs``).
* ``quality``: ``train`` of the recipe with each backend for ``--seeds`` training seeds, each in
  a fresh pinned process (so compilation and jit warm-up count in its wall time: s, from the
  ``train`` call to its return, evaluations and checkpoints included), then each run's best
  snapshot (chosen on the validation seeds 10000–10004, as campaigns do) played on the cell's 20
  episodes by the campaign's episode runner; J / J* = ΣJ / ΣJ* over them (the campaign
  report's ratio). Parity: the fused trainer's mean J/J* over seeds ≤ the worst SBX seed's.
  ``time_to_target``: a twin of each fused run (same seed and program: the same policies)
  evaluates on the cell's 20 episodes instead; the wall time (s since the ``train`` call,
  compilation included) of its first evaluation with J/J* ≤ 1.05 (the evaluations are every
  10 k steps: a ceiling on the time); pinned to one CPU, then again on every CPU this process
  may use (``time_to_target_all_cores``: the issue's target is on 2 cores, and XLA compiles on
  all of them — 7–12 s on 2 cores against 13–20 s on one); ``time_to_target_warm_cache``: the
  twins once more (on every CPU where the all-cores twins ran) with JAX's persistent compilation
  cache, as the command line uses it, filled by one short run of the same program first: what
  every run after a machine's first one takes.
* ``search``: ``attitude-envs tune --backend jax`` with 64 settings at the recipe's budget
  (120 k steps each; ``tune``'s default is 300 k) in a pinned child process: wall s and the best
  setting's eval J (validation seeds 10000+).
* ``env_stepping``: env steps/s (decisions, all envs together) of the JAX AirBearing-v1 and
  ReactionWheel-v1 plants, ``jax.vmap`` over N envs in a jitted ``lax.scan``, against the numba
  batched env at the same N, alternating rounds, pinned; on a GPU also N = 65,536 (ReactionWheel).

Each section is kept in ``OUT/jax_training.partial.json`` as it finishes: a run killed or
failed in a later section, rerun with the same command on the same commit, takes the finished
ones from there (``meta.sections_from_an_earlier_run`` names them) and deletes the file when the
whole run is written.

Compilation comes from JAX's persistent cache only in ``time_to_target_warm_cache`` (a folder of
the run's own, emptied first); it is switched off in this process and every other child.
``--quick`` (tiny budgets, XLA's fast-compile option, 1 seed, 2 rounds: a smoke run of every
code path, not a measurement) takes about 3 min on a quiet 2-core machine; the full run 16–25
min there (about 10 of them the quality section, 6 the search). Nothing
here is asserted: the issue's targets are reported beside what was measured (``targets``).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import csv
import datetime
import io
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import attitude_envs  # noqa: F401  (registers the ids)
from benchmarks.env_speed import _median_range, _with_spread
from experiments.processes import pin_to_one_core

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "attitude_envs/AirBearing-v1"
#: the campaign whose ``ppo`` agent trains on an env id (task kwargs, cell episodes, J*)
CAMPAIGNS = {"attitude_envs/AirBearing-v1": "air-bearing", "attitude_envs/LinearSystem-v1": "linear"}
STEPPING_ENV_IDS = ("attitude_envs/AirBearing-v1", "attitude_envs/ReactionWheel-v1")
VMAPPED_SEEDS = 16
J_STAR_TARGET = 1.05
GPU_STEPPING = ("attitude_envs/ReactionWheel-v1", 65_536)
#: the issue's targets (reported beside the measurements, never asserted)
TARGETS = {
    "ppo_per_seed_vs_sbx": ">= 5",
    "ppo_16_seeds_vs_sbx": ">= 10",
    "compile_s": "<= 30",
    "time_to_1.05_J_star_s": "<= 20",
    "search_64_wall_s": "<= 600",
    "parity": "fused mean J/J* <= worst SBX seed",
}
RESULT_PREFIX = "JAX_TRAINING_RESULT "
FAST_COMPILE_ENV = "ATTITUDE_ENVS_JAX_FAST_COMPILE"  # experiments.sb3.jax_training.FAST_COMPILE_ENV
_PROGRESS = re.compile(r"(\d+)/(\d+) steps,")


# --------------------------------------------------------------------------- the task


@dataclass
class Task:
    """A campaign agent's task: the env it trains and plays on, the cell episodes it is scored
    on (one campaign episode job per seed) and their J* (from the shipped table)."""

    env_id: str
    env_kwargs: dict[str, Any]
    campaign: str
    cell: tuple[str, str, str]
    jobs: list[dict[str, Any]]
    j_star: dict[int, float]

    @property
    def seeds(self) -> list[int]:
        return [int(j["key"]["seed"]) for j in self.jobs]


def campaign_task(env_id: str, agent: str = "ppo") -> Task:
    """The task of ``agent`` in the campaign that trains it on ``env_id`` (:data:`CAMPAIGNS`):
    its first env's first scenario without faults; kwargs ``{}`` and no episodes for an env id
    no campaign trains on."""
    from experiments.campaign.jobs import episode_jobs
    from experiments.campaign.spec import load_campaign
    from experiments.optimum_table import table_value

    name = CAMPAIGNS.get(env_id)
    if name is None:
        return Task(env_id, {}, "", ("", "", ""), [], {})
    campaign = load_campaign(name)
    others = [a.name for a in campaign.agents if a.name != agent]
    jobs = episode_jobs(campaign, ROOT / "results" / "unused", skip_agents=others)
    first = jobs[0]["key"]
    cell = (first["env"], first["scenario"], "none")
    jobs = [
        j
        for j in jobs
        if (j["key"]["env"], j["key"]["scenario"], j["key"]["fault"]) == cell
        and j["key"]["train_seed"] == first["train_seed"]
    ]
    if jobs[0]["env_id"] != env_id:
        raise ValueError(f"campaign {name!r}: agent {agent!r} plays {jobs[0]['env_id']}, not {env_id}")
    j_star = {}
    for j in jobs:
        value = table_value(j["cell_env_id"], j["cell_env_kwargs"], j["key"]["seed"], j.get("options") or None)
        j_star[int(j["key"]["seed"])] = float("nan") if value is None else value
    return Task(env_id, dict(jobs[0]["env_kwargs"]), name, cell, jobs, j_star)


def _recipe(env_id: str) -> dict[str, Any]:
    from experiments.training.hyperparams import load_hyperparams

    return load_hyperparams("ppo", env_id, None, {"backend": "jax"})


# --------------------------------------------------------------------------- processes


def _no_compile_cache() -> None:
    """No persistent compilation cache in this process (compile times are measured)."""
    os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
    os.environ["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    if "jax" in sys.modules:
        import jax

        jax.config.update("jax_enable_compilation_cache", False)


def _child_env(compile_cache_dir: str | None = None) -> dict[str, str]:
    """This process's environment for a child: no persistent compilation cache, or the one in
    ``compile_cache_dir`` (the command line's own cache, in a folder of the benchmark's)."""
    env = dict(os.environ)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    env["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    if compile_cache_dir is not None:
        env["JAX_COMPILATION_CACHE_DIR"] = str(compile_cache_dir)
        env["JAX_ENABLE_COMPILATION_CACHE"] = "true"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    return env


def _run_child(spec: dict[str, Any], cpus: set[int] | None = None, timeout: float | None = None) -> dict[str, Any]:
    """Run :func:`child_main` on ``spec`` in a fresh interpreter (this process's CPU affinity, or
    ``cpus``); its result, with ``process_wall_s`` (s, interpreter start to exit)."""
    code = "import sys; from benchmarks.jax_training import child_main; raise SystemExit(child_main(sys.argv[1]))"
    if cpus is not None:  # set by the child itself, first thing (no preexec_fn: a fork of a JAX process)
        spec = {**spec, "cpus": sorted(cpus)}
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", code, json.dumps(spec)],
        cwd=ROOT,
        env=_child_env(spec.get("compile_cache_dir")),
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    wall = time.perf_counter() - start
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_PREFIX)]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"child {spec['kind']} failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    return {**json.loads(lines[-1][len(RESULT_PREFIX) :]), "process_wall_s": wall}


class _TimedLines(io.TextIOBase):
    """A text stream that keeps each complete line with the time (s since ``t0``) it was written."""

    def __init__(self, t0: float) -> None:
        self.t0, self.lines, self._part = t0, [], ""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        now = time.perf_counter() - self.t0
        if sys.__stderr__ is not None:  # still seen by whoever reads the child's stderr
            sys.__stderr__.write(text)
        self._part += text
        *done, self._part = self._part.split("\n")
        self.lines += [(now, line) for line in done]
        return len(text)


def child_main(spec_json: str) -> int:
    """Entry of the child processes (``kind``: ``train`` or ``jax_rates``); prints one result line."""
    spec = json.loads(spec_json)
    if spec.get("cpus"):  # before JAX starts: its CPU thread pool follows the affinity
        os.sched_setaffinity(0, set(spec["cpus"]))
    if not spec.get("compile_cache_dir"):  # else the cache its environment names (_child_env)
        _no_compile_cache()
    if spec.get("fast_compile"):
        os.environ[FAST_COMPILE_ENV] = "1"
    if spec["kind"] == "train":
        result = _train_run(spec)
    elif spec["kind"] == "jax_rates":
        result = _jax_rates(spec)
    else:
        raise ValueError(f"unknown child kind {spec['kind']!r}")
    print(RESULT_PREFIX + json.dumps(result), flush=True)
    return 0


# --------------------------------------------------------------------------- speed


def _jax_trainers(env_id: str, env_kwargs: dict[str, Any], rollouts: int, seeds: int) -> dict[str, Any]:
    """The fused trainer of ``env_id``'s recipe for one seed (``train``'s own compiled program,
    :func:`experiments.sb3.jax_training.program`) and for ``seeds`` vmapped seeds, compiled and
    warmed up by one chunk of ``rollouts`` updates: name → ``{"step": () -> env steps,
    "compile_s", "seeds", "device"}``. The schedules' horizon is set far out (1e12 steps), so the
    learning rate stays positive however many rounds run."""
    import jax
    import jax.numpy as jnp

    from agents.fused_ppo.config import as_float32, from_zoo, stack_hparams
    from agents.fused_ppo.trainer import make_chunked
    from experiments.training.jax_training import compiler_options, program

    config, hp = from_zoo(_recipe(env_id))
    hp = as_float32(hp._replace(schedule_timesteps=1e12))
    n = jnp.asarray(int(rollouts), jnp.int32)
    out: dict[str, Any] = {}

    prog = program(env_id, env_kwargs, config)
    before = prog.compile_s
    single = {"state": prog.init(jax.random.PRNGKey(0), hp)}

    def step_single() -> int:
        single["state"], _ = prog.update_chunk(single["state"], hp, int(rollouts))
        jax.block_until_ready(single["state"])
        return int(rollouts) * config.rollout_size

    step_single()  # compiles update_chunk (on first use), then runs one chunk
    out["jax 1 seed"] = {"step": step_single, "compile_s": prog.compile_s - before, "seeds": 1}

    chunked = make_chunked(prog.env, prog.env_params, config)
    keys = jnp.stack([jax.random.PRNGKey(s) for s in range(int(seeds))])
    hps = stack_hparams([hp] * int(seeds))
    start = time.perf_counter()
    options = compiler_options()
    init = jax.jit(jax.vmap(chunked.init), compiler_options=options).lower(keys, hps).compile()
    vstate = {"state": init(keys, hps)}
    vchunk = jax.vmap(chunked.update_chunk, in_axes=(0, 0, None))
    chunk = jax.jit(vchunk, compiler_options=options).lower(vstate["state"], hps, n).compile()
    compile_s = time.perf_counter() - start

    def step_vmapped() -> int:
        vstate["state"], _ = chunk(vstate["state"], hps, n)
        jax.block_until_ready(vstate["state"])
        return int(seeds) * int(rollouts) * config.rollout_size

    step_vmapped()
    out[f"jax {seeds} seeds"] = {"step": step_vmapped, "compile_s": compile_s, "seeds": int(seeds)}
    for entry in out.values():
        entry["device"] = str(jax.devices()[0])
    return out


def _jax_rates(spec: dict[str, Any]) -> dict[str, Any]:
    """Child: the fused trainer's rates on this process's CPUs (the all-cores row)."""
    trainers = _jax_trainers(spec["env_id"], spec["env_kwargs"], spec["rollouts"], spec["seeds"])
    rates: dict[str, list[float]] = {name: [] for name in trainers}
    for _ in range(int(spec["rounds"])):
        for name, t in trainers.items():
            start = time.perf_counter()
            steps = t["step"]()
            rates[name].append(steps / (time.perf_counter() - start))
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    return {
        "cpus": cpus,
        "stacks": {
            name: {"rates": rates[name], "compile_s": t["compile_s"], "seeds": t["seeds"], "device": t["device"]}
            for name, t in trainers.items()
        },
    }


def speed(
    env_id: str, env_kwargs: dict[str, Any], rollouts: int, rounds: int, pinned: str, all_cores: set[int] | None
) -> dict[str, Any]:
    """The speed section of ``env_id``'s PPO recipe (module docstring): rows, ratios, compile times."""
    import torch

    from benchmarks.training_throughput import _model

    torch.set_num_threads(1)
    config_rollout = int(_recipe(env_id)["n_envs"]) * int(_recipe(env_id)["n_steps"])
    per_round = int(rollouts) * config_rollout
    stacks: dict[str, dict[str, Any]] = {}
    for backend in ("sb3", "sbx"):
        model = _model("ppo", env_id, env_kwargs, backend, native=True)
        start = time.perf_counter()
        model.learn(per_round)  # warm-up: SBX jit-compiles its update here
        warm = time.perf_counter() - start

        def step(model=model) -> int:
            done = model.num_timesteps
            model.learn(per_round, reset_num_timesteps=False)
            return int(model.num_timesteps - done)

        stacks[f"{backend} native"] = {"step": step, "warmup_s": warm, "seeds": 1, "device": "cpu (torch)"}
    stacks["sbx native"]["device"] = _jax_device()
    stacks.update(_jax_trainers(env_id, env_kwargs, rollouts, VMAPPED_SEEDS))
    rates: dict[str, list[float]] = {name: [] for name in stacks}
    for _ in range(int(rounds)):
        for name, s in stacks.items():
            start = time.perf_counter()
            steps = s["step"]()
            rates[name].append(steps / (time.perf_counter() - start))
    sbx, sb3 = rates["sbx native"], rates["sb3 native"]
    rows = []
    for name, values in rates.items():
        s = stacks[name]
        row = {
            "benchmark": "train ppo (rollouts + updates, no evaluation)",
            "env": env_id,
            "stack": name,
            "seeds": s["seeds"],
            "env_steps_per_round_per_seed": per_round,
            "unit": "env steps/s" + (", all seeds together" if s["seeds"] > 1 else ""),
            "pinned": pinned,
            "device": s["device"],
        }
        _with_spread(row, "steps_per_s", values)
        _with_spread(row, "ratio_to_sbx", [v / r for v, r in zip(values, sbx, strict=True)])
        rows.append(_with_spread(row, "ratio_to_sb3", [v / r for v, r in zip(values, sb3, strict=True)]))
    vmapped = f"jax {VMAPPED_SEEDS} seeds"
    ratios = {
        "ppo_per_seed_vs_sbx": _ratio_entry(rates["jax 1 seed"], sbx, env_id, pinned, "fused PPO 1 seed / SBX 1 seed"),
        "ppo_16_seeds_vs_sbx": _ratio_entry(
            rates[vmapped], sbx, env_id, pinned, f"fused PPO {VMAPPED_SEEDS} vmapped seeds (aggregate) / SBX 1 seed"
        ),
    }
    compile_rows = []
    for name, s in stacks.items():
        key = "compile_s" if "compile_s" in s else "warmup_s"
        what = (
            "XLA compile of the init and update_chunk programs (ahead of time)"
            if key == "compile_s"
            else f"first learn() of {per_round} env steps (SBX: its jit compile included)"
        )
        compile_rows.append(
            {
                "env": env_id,
                "stack": name,
                key: s[key],
                "unit": "s",
                "what": what,
                "pinned": pinned,
                "device": s["device"],
            }
        )
    out = {"env": env_id, "env_kwargs": env_kwargs, "rows": rows, "compile": compile_rows, **ratios}
    if all_cores:
        child = _run_child(
            {
                "kind": "jax_rates",
                "env_id": env_id,
                "env_kwargs": env_kwargs,
                "rollouts": int(rollouts),
                "seeds": VMAPPED_SEEDS,
                "rounds": int(rounds),
                "fast_compile": os.environ.get(FAST_COMPILE_ENV, "") not in ("", "0"),
            },
            cpus=all_cores,
        )
        sbx_median = float(np.median(sbx))
        all_rows = []
        for name, s in child["stacks"].items():
            row = {
                "benchmark": "train ppo (rollouts + updates, no evaluation)",
                "env": env_id,
                "stack": name,
                "seeds": s["seeds"],
                "unit": "env steps/s" + (", all seeds together" if s["seeds"] > 1 else ""),
                "pinned": f"no: all {len(child['cpus'])} CPUs {child['cpus']} (a child process, its own rounds)",
                "device": s["device"],
                "compile_s": s["compile_s"],
            }
            _with_spread(row, "steps_per_s", s["rates"])
            row["ratio_to_pinned_sbx_median"] = row["steps_per_s"] / sbx_median
            all_rows.append(row)
        out["jax_all_cores"] = all_rows
    return out


def _ratio_entry(values: list[float], reference: list[float], env_id: str, pinned: str, what: str) -> dict[str, Any]:
    row = {"env": env_id, "what": what, "unit": "ratio of env steps/s (per-round ratios)", "pinned": pinned}
    median, spread = _median_range([v / r for v, r in zip(values, reference, strict=True)])
    return {**row, "median": median, "range": spread, "rounds": len(values)}


def _jax_device() -> str:
    import jax

    return str(jax.devices()[0])


# --------------------------------------------------------------------------- quality


def _train_run(spec: dict[str, Any]) -> dict[str, Any]:
    """Child: one ``train`` run; its wall time, timing.jsonl, evaluations with their wall times
    (the fused trainer's status lines, one per chunk, give them)."""
    import torch

    from experiments.training.training import train

    torch.set_num_threads(1)
    out_dir = Path(spec["out_dir"])
    start = time.perf_counter()
    lines = _TimedLines(start)
    with contextlib.redirect_stderr(lines):
        result = train(
            "ppo",
            spec["env_id"],
            out_dir,
            env_kwargs=spec["env_kwargs"],
            seed=int(spec["seed"]),
            total_timesteps=spec["timesteps"],
            backend=spec["backend"],
            eval_freq=int(spec["eval_freq"]),
            checkpoint_freq=int(spec["eval_freq"]),
            eval_episodes=int(spec["eval_episodes"]),
            eval_seed=int(spec["eval_seed"]),
            progress=f"train {spec['backend']}" if spec["backend"] == "jax" else False,
        )
    wall = time.perf_counter() - start
    at: dict[int, float] = {}
    for t, line in lines.lines:
        m = _PROGRESS.search(line)
        if m:
            at.setdefault(int(m.group(1)), t)
    with open(out_dir / "evaluations.csv", encoding="utf-8") as fh:
        evaluations = [
            {"timesteps": int(r["timesteps"]), "J_mean": float(r["J_mean"]), "wall_s": at.get(int(r["timesteps"]))}
            for r in csv.DictReader(fh)
        ]
    timing = [json.loads(ln) for ln in (out_dir / "timing.jsonl").read_text(encoding="utf-8").splitlines() if ln]
    return {
        "train_wall_s": wall,
        "timesteps": int(result.timesteps),
        "timing": timing,
        "compile_s": sum(float(t.get("compile_s", 0.0)) for t in timing) if spec["backend"] == "jax" else None,
        "evaluations": evaluations,
    }


def _score(task: Task, runs: list[dict[str, Any]]) -> dict[tuple[str, int], dict[str, Any]]:
    """(backend, seed) → the campaign leaderboard entry of its best snapshot on the task's cell
    episodes (J mean, ``J_over_J_star`` = ΣJ/ΣJ*); also the pooled entry per backend (seed -1)."""
    from experiments.campaign.episode import run_job
    from experiments.campaign.jobs import trained_model
    from experiments.report.leaderboards import leaderboards

    rows = []
    for run in runs:
        model = trained_model(Path(run["out_dir"]), "best")
        for job in task.jobs:
            j = copy.deepcopy(job)
            j["policy"]["model"] = str(model)
            j["key"] |= {"agent": f"{run['backend']}/{run['seed']}", "train_seed": run["seed"]}
            row = run_job(j) | {"j_star": task.j_star[int(job["key"]["seed"])]}
            rows.append(row)
            rows.append({**row, "agent": f"{run['backend']}/pooled"})
    board = next(iter(leaderboards(rows).values()))
    out = {}
    for entry in board:
        if entry.get("oracle"):
            continue
        backend, seed = entry["agent"].split("/")
        out[(backend, -1 if seed == "pooled" else int(seed))] = entry
    return out


def quality(
    task: Task,
    seeds: list[int],
    timesteps: int,
    eval_freq: int,
    workdir: Path,
    fast_compile: bool,
    all_cores: set[int] | None = None,
) -> dict[str, Any]:
    """The quality section (module docstring): each backend × training seed in a fresh pinned
    process, alternating by seed; scored on the task's cell episodes. The twin runs go once
    pinned and, with ``all_cores``, once more on those CPUs (the issue's "on 2 cores")."""
    backends = ("sb3", "sbx", "jax")
    runs, twins, twins_all = [], [], []
    n_cell = len(task.seeds)
    if task.seeds != list(range(task.seeds[0], task.seeds[0] + n_cell)):
        raise ValueError(f"the cell's seeds must be consecutive for the twin runs' evaluation, got {task.seeds}")
    base = {
        "kind": "train",
        "env_id": task.env_id,
        "env_kwargs": task.env_kwargs,
        "timesteps": int(timesteps),
        "eval_freq": int(eval_freq),
        "fast_compile": fast_compile,
    }

    def twin_spec(seed: int, out_dir: Path) -> dict[str, Any]:
        spec = {**base, "backend": "jax", "seed": seed, "out_dir": str(out_dir)}
        return spec | {"eval_episodes": n_cell, "eval_seed": task.seeds[0]}

    for seed in seeds:
        for backend in backends:
            out_dir = workdir / f"{backend}-seed{seed}"
            spec = {**base, "backend": backend, "seed": seed, "out_dir": str(out_dir)}
            spec |= {"eval_episodes": 5, "eval_seed": 10_000}  # train's defaults, as the campaign trains
            _say(f"quality: training {backend} seed {seed} ({timesteps} steps)")
            runs.append({**_run_child(spec), "backend": backend, "seed": seed, "out_dir": str(out_dir)})
            _say(f"  {runs[-1]['train_wall_s']:.1f} s")
        spec = twin_spec(seed, workdir / f"jax-seed{seed}-cell-eval")
        _say(f"quality: the fused run's twin, seed {seed}, evaluated on the cell's {n_cell} episodes")
        twins.append({**_run_child(spec), "seed": seed})
        if all_cores:
            spec["out_dir"] = str(workdir / f"jax-seed{seed}-cell-eval-all-cores")
            _say(f"quality: the twin again on CPUs {sorted(all_cores)}")
            twins_all.append({**_run_child(spec, cpus=all_cores), "seed": seed})
    # the command line's default: JAX's persistent compilation cache, filled by one run first
    # (the programs do not depend on the seed or the budget: one fill serves every seed)
    cache = workdir / "jax-compilation-cache"
    shutil.rmtree(cache, ignore_errors=True)
    fill = twin_spec(seeds[0], workdir / "jax-cache-fill") | {"timesteps": int(eval_freq), "eval_episodes": 2}
    _say("quality: one short fused run fills JAX's compilation cache (not timed)")
    _run_child(fill | {"compile_cache_dir": str(cache)}, cpus=all_cores)
    twins_warm = []
    for seed in seeds:
        spec = twin_spec(seed, workdir / f"jax-seed{seed}-cell-eval-warm-cache") | {"compile_cache_dir": str(cache)}
        _say(f"quality: the twin, seed {seed}, with the compilation cache filled")
        twins_warm.append({**_run_child(spec, cpus=all_cores), "seed": seed})
    scores = _score(task, runs)
    per_backend: dict[str, Any] = {}
    for backend in backends:
        mine = [r for r in runs if r["backend"] == backend]
        per_seed = []
        for r in mine:
            e = scores[(backend, r["seed"])]
            per_seed.append(
                {
                    "seed": r["seed"],
                    "J_over_J_star": e["J_over_J_star"],
                    "J_mean": e["J_mean"],
                    "terminated_rate": e["terminated_rate"],
                    "success_rate": e["success_rate"],
                    "train_wall_s": r["train_wall_s"],
                    "process_wall_s": r["process_wall_s"],
                    "compile_s": r["compile_s"],
                    "timesteps": r["timesteps"],
                    "best_snapshot_eval": min(r["evaluations"], key=lambda ev: ev["J_mean"]),
                    "evaluations": r["evaluations"],
                }
            )
        ratios = [p["J_over_J_star"] for p in per_seed]
        walls = [p["train_wall_s"] for p in per_seed]
        per_backend[backend] = {
            "seeds": per_seed,
            "J_over_J_star_mean": float(np.mean(ratios)),
            "J_over_J_star_range": [float(min(ratios)), float(max(ratios))],
            "J_over_J_star_pooled": scores[(backend, -1)]["J_over_J_star"],
            "train_wall_s_median": float(np.median(walls)),
            "train_wall_s_range": [float(min(walls)), float(max(walls))],
        }
    jax_mean = per_backend["jax"]["J_over_J_star_mean"]
    j_star_mean = float(np.mean([task.j_star[s] for s in task.seeds]))

    def time_to_target(twin_runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
        out = []
        for twin in twin_runs:
            evals = [{**ev, "J_over_J_star": ev["J_mean"] / j_star_mean} for ev in twin["evaluations"]]
            hit = next((ev for ev in evals if ev["J_over_J_star"] <= J_STAR_TARGET), None)
            out.append(
                {
                    "seed": twin["seed"],
                    "reached": hit is not None,
                    "first_wall_s": None if hit is None else hit["wall_s"],
                    "first_timesteps": None if hit is None else hit["timesteps"],
                    "best_J_over_J_star": min(ev["J_over_J_star"] for ev in evals),
                    "train_wall_s": twin["train_wall_s"],
                    "compile_s": twin["compile_s"],
                    "evaluations": evals,
                }
            )
        return out

    return {
        "env": task.env_id,
        "env_kwargs": task.env_kwargs,
        "campaign": task.campaign,
        "cell": list(task.cell),
        "cell_seeds": task.seeds,
        "training_seeds": list(seeds),
        "timesteps": int(timesteps),
        "eval_freq": int(eval_freq),
        "units": {
            "J_over_J_star": "ΣJ/ΣJ* over the cell's episodes (J* from experiments/optimum_table.json)",
            "train_wall_s": "s from the train() call to its return in a fresh process (compile, evaluations, "
            "checkpoints included)",
            "process_wall_s": "s of the whole child process (interpreter start, imports, train)",
            "evaluations": "the run's evaluations.csv: J on seeds 10000-10004 (validation); wall_s since the "
            "train() call where the run's status lines give it (fused trainer only)",
            "time_to_target": f"a twin fused run evaluated on the cell's {n_cell} episodes every {eval_freq} steps; "
            f"first_wall_s: s since the train() call (compile included) at its first evaluation with J/J* <= "
            f"{J_STAR_TARGET}",
            "time_to_target_warm_cache": "the twins again with JAX's persistent compilation cache (the command "
            "line's default) filled by one earlier run: compile_s is the cache's load; on the all-cores CPUs where "
            "they ran, else pinned",
        },
        "pinned": "one CPU per run (the child inherits this process's affinity); torch 1 thread",
        "backends": per_backend,
        "parity_jax_within_sbx_spread_or_better": bool(jax_mean <= per_backend["sbx"]["J_over_J_star_range"][1]),
        "parity_jax_within_sb3_spread_or_better": bool(jax_mean <= per_backend["sb3"]["J_over_J_star_range"][1]),
        "time_to_target": time_to_target(twins),
        **(
            {"time_to_target_all_cores": time_to_target(twins_all), "all_cores": sorted(all_cores)} if all_cores else {}
        ),
        "time_to_target_warm_cache": time_to_target(twins_warm),
    }


# --------------------------------------------------------------------------- population search


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
    _say(f"search: {settings} settings × {timesteps} steps")
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=_child_env(), capture_output=True, text=True, check=False)
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


# --------------------------------------------------------------------------- env stepping


def _scan_stepper(env, params, n: int, steps: int):
    """``run(key, state, action) -> (key, state, rewards)``: ``steps`` decisions of ``n`` envs
    (``jax.vmap`` of the plant's autoresetting ``step``) in one ``lax.scan``, the same action
    (one row per env) every decision."""
    import jax
    import jax.numpy as jnp

    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def run(key, state, action):
        def body(carry, _):
            k, st = carry
            k, sub = jax.random.split(k)
            _, st, reward, _, _, _ = step(jax.random.split(sub, n), st, action, params)
            return (k, st), jnp.sum(reward)

        (key, state), rewards = jax.lax.scan(body, (key, state), None, length=steps)
        return key, state, rewards

    return run


def env_stepping(
    env_ids: tuple[str, ...], sizes: tuple[int, ...], seconds: float, rounds: int, steps_per_call: int, pinned: str
) -> list[dict[str, Any]]:
    """Env steps/s of the JAX plants (``jax.vmap`` over N envs, ``lax.scan`` of ``steps_per_call``
    decisions per jitted call) vs the numba batched env at the same N, alternating rounds."""
    import gymnasium as gym
    import jax
    import jax.numpy as jnp

    from attitude_envs.jax import make
    from benchmarks.env_speed import _time_vector
    from experiments.machine_reference import seconds_per_call

    gpu = jax.devices()[0].platform == "gpu"
    cases = []
    for env_id in env_ids:
        kwargs = campaign_task(env_id).env_kwargs if env_id in CAMPAIGNS else {}
        env, params = make(env_id, **kwargs)
        ns = list(sizes) + ([GPU_STEPPING[1]] if gpu and env_id == GPU_STEPPING[0] else [])
        for n in ns:
            numba = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
            space = numba.single_action_space
            actions = np.random.default_rng(0).uniform(space.low, space.high, (n, *space.shape)).astype(np.float32)
            actions *= 0.5

            key = jax.random.PRNGKey(0)
            _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, n), params)
            action = jnp.asarray(actions)
            start = time.perf_counter()
            run = _scan_stepper(env, params, n, steps_per_call)
            compiled = jax.jit(run).lower(key, state, action).compile()
            compile_s = time.perf_counter() - start
            carry = {"key": key, "state": state}

            def call(compiled=compiled, carry=carry, action=action) -> None:
                carry["key"], carry["state"], rewards = compiled(carry["key"], carry["state"], action)
                jax.block_until_ready(rewards)

            call()
            cases.append((env_id, n, numba, actions, call, compile_s))
    rates: dict[tuple[str, int], dict[str, list[float]]] = {(c[0], c[1]): {"jax": [], "numba": []} for c in cases}
    for _ in range(int(rounds)):
        for env_id, n, numba, actions, call, _ in cases:
            rates[(env_id, n)]["numba"].append(_time_vector(numba, actions, seconds))
            rates[(env_id, n)]["jax"].append(n * steps_per_call / seconds_per_call(call, seconds))
    rows = []
    device = _jax_device()
    for env_id, n, numba, _, _, compile_s in cases:
        r = rates[(env_id, n)]
        base = {"benchmark": "env stepping", "env": env_id, "num_envs": n, "unit": "env steps/s, all envs together"}
        base["pinned"] = pinned
        row = {**base, "stack": f"jax vmap + lax.scan ({steps_per_call} decisions per call)", "device": device}
        row["compile_s"] = compile_s
        _with_spread(row, "steps_per_s", r["jax"])
        rows.append(_with_spread(row, "ratio_to_numba", [j / b for j, b in zip(r["jax"], r["numba"], strict=True)]))
        rows.append(_with_spread({**base, "stack": "numba batched (vector_entry_point)"}, "steps_per_s", r["numba"]))
        numba.close()
    return rows


# --------------------------------------------------------------------------- summary


def _fmt_spread(value: float | None, spread: list[float] | None, digits: str = ".3g") -> str:
    if value is None:
        return "n/a"
    text = format(value, digits)
    return text + (f" [{format(spread[0], digits)}, {format(spread[1], digits)}]" if spread else "")


def targets(result: dict[str, Any]) -> dict[str, Any]:
    """The issue's targets beside what was measured (``met``: the measured value meets it)."""
    out: dict[str, Any] = {}
    sp = result.get("speed")
    if sp:
        for key, low in (("ppo_per_seed_vs_sbx", 5.0), ("ppo_16_seeds_vs_sbx", 10.0)):
            out[key] = {"target": TARGETS[key], "measured": sp[key]["median"], "met": sp[key]["median"] >= low}
        jax1 = next(c for c in sp["compile"] if c["stack"] == "jax 1 seed")
        out["compile_s"] = {"target": TARGETS["compile_s"], "measured": jax1["compile_s"]}
        out["compile_s"]["met"] = jax1["compile_s"] <= 30.0
        out["compile_s"]["what"] = "the one-seed program train() compiles, in the speed section (pinned)"
    q = result.get("quality")
    if q:
        # the issue's condition is "on 2 cores": the all-cores twins where they ran
        all_cores = "time_to_target_all_cores" in q
        twins = q["time_to_target_all_cores"] if all_cores else q["time_to_target"]
        hits = [t["first_wall_s"] for t in twins]  # None where not reached (or reached at 0 steps)
        worst = None if any(not t["reached"] for t in twins) else max(h or 0.0 for h in hits)
        out["time_to_1.05_J_star_s"] = {
            "target": TARGETS["time_to_1.05_J_star_s"],
            "measured_per_seed": hits,
            "measured_per_seed_one_cpu": [t["first_wall_s"] for t in q["time_to_target"]],
            "met": worst is not None and worst <= 20.0,
            "what": "twin fused runs: wall s (compile included) to the first evaluation with J/J* <= 1.05 on the "
            "cell's episodes; every seed must meet it; "
            + (f"on CPUs {q['all_cores']} (one_cpu: the pinned twins)" if all_cores else "pinned to one CPU")
            + "; met: with every program compiled in the run (no persistent cache); met_warm_cache: the twins "
            "again with the compilation cache filled by an earlier run (the command line's default)",
        }
        if "time_to_target_warm_cache" in q:
            warm = q["time_to_target_warm_cache"]
            out["time_to_1.05_J_star_s"]["measured_per_seed_warm_cache"] = [t["first_wall_s"] for t in warm]
            out["time_to_1.05_J_star_s"]["met_warm_cache"] = all(
                t["reached"] and (t["first_wall_s"] or 0.0) <= 20.0 for t in warm
            )
        jax_q = q["backends"]["jax"]["seeds"]
        out["fused_run_within_1.05_in_20_s"] = {
            "measured_per_seed": [[s["J_over_J_star"], s["train_wall_s"]] for s in jax_q],
            "met": all(s["J_over_J_star"] <= J_STAR_TARGET and s["train_wall_s"] <= 20.0 for s in jax_q),
            "what": "the quality runs themselves: [best snapshot J/J*, train wall s] per seed",
        }
        out["parity"] = {"target": TARGETS["parity"], "met": q["parity_jax_within_sbx_spread_or_better"]}
    s = result.get("search")
    if s:
        out["search_64_wall_s"] = {"target": TARGETS["search_64_wall_s"], "measured": s["wall_s"]}
        out["search_64_wall_s"]["met"] = s["settings"] >= 64 and s["wall_s"] <= 600.0
    return out


def markdown(result: dict[str, Any]) -> str:
    """A short markdown summary of ``result``."""
    meta = result["meta"]
    lines = [
        f"## JAX training benchmark ({'--quick: a smoke run, not a measurement' if meta['quick'] else 'full run'})",
        f"{meta['machine']}, {meta['cores']} cores, jax {meta['versions'].get('jax')} on {meta['jax_device']}; "
        f"pinned: {meta['pinned']}; wall {meta['wall_s']:.0f} s",
        "",
    ]
    sp = result.get("speed")
    if sp:
        lines += [
            "| stack | env steps/s, median [min, max] | × SBX (per round) | compile / warm-up s |",
            "|---|---|---|---|",
        ]
        comp = {c["stack"]: c.get("compile_s", c.get("warmup_s")) for c in sp["compile"]}
        for r in sp["rows"]:
            lines.append(
                f"| {r['stack']} | {_fmt_spread(r['steps_per_s'], r['steps_per_s_range'], '.0f')} | "
                f"{_fmt_spread(r['ratio_to_sbx'], r['ratio_to_sbx_range'], '.2f')} | {comp[r['stack']]:.1f} |"
            )
        for r in sp.get("jax_all_cores", []):
            lines.append(
                f"| {r['stack']} (all cores) | {_fmt_spread(r['steps_per_s'], r['steps_per_s_range'], '.0f')} | "
                f"{r['ratio_to_pinned_sbx_median']:.2f} (to the pinned median) | {r['compile_s']:.1f} |"
            )
        lines.append(f"({sp['env']}, {sp['ppo_per_seed_vs_sbx']['rounds']} rounds, one CPU unless stated)")
        for other in result.get("speed_other_envs", []):
            a, b = other["ppo_per_seed_vs_sbx"], other["ppo_16_seeds_vs_sbx"]
            lines.append(
                f"{other['env']}: fused 1 seed / SBX {_fmt_spread(a['median'], a['range'], '.2f')}, "
                f"{VMAPPED_SEEDS} seeds / SBX {_fmt_spread(b['median'], b['range'], '.2f')}"
            )
        lines.append("")
    q = result.get("quality")
    if q:
        lines += ["| backend | J/J* per seed | mean [min, max] | train wall s per seed |", "|---|---|---|---|"]
        for b, e in q["backends"].items():
            per = ", ".join(f"{s['J_over_J_star']:.3f}" for s in e["seeds"])
            walls = ", ".join(f"{s['train_wall_s']:.0f}" for s in e["seeds"])
            lines.append(
                f"| {b} | {per} | {_fmt_spread(e['J_over_J_star_mean'], e['J_over_J_star_range'])} | {walls} |"
            )

        def hits(twins: list[dict[str, Any]]) -> str:
            return ", ".join(
                f"{t['first_wall_s']:.1f} s"
                if t["first_wall_s"] is not None
                else ("at 0 steps" if t["reached"] else "never")
                for t in twins
            )

        on_all = (
            f"; on CPUs {q['all_cores']}: {hits(q['time_to_target_all_cores'])}"
            if "time_to_target_all_cores" in q
            else ""
        )
        warm = (
            f"; compilation cache filled: {hits(q['time_to_target_warm_cache'])}"
            if "time_to_target_warm_cache" in q
            else ""
        )
        lines.append(
            f"({q['timesteps']} steps, parity fused ≤ worst SBX seed: {q['parity_jax_within_sbx_spread_or_better']}; "
            f"fused to J/J* ≤ {J_STAR_TARGET} on the cell, one CPU: {hits(q['time_to_target'])}{on_all}{warm})"
        )
        lines.append("")
    s = result.get("search")
    if s:
        lines.append(
            f"population search: {s['settings']} settings × {s['timesteps_per_setting']} steps in {s['wall_s']:.0f} s "
            f"({s['compile_s']:.0f} s compiling, {s['train_s']:.0f} s training, {s['eval_s']:.0f} s evaluating); "
            f"best eval J {s['best_value']:.4g}"
        )
        lines.append("")
    st = result.get("env_stepping")
    if st:
        lines += ["| env | N | jax steps/s | numba steps/s | jax / numba |", "|---|---:|---|---|---|"]
        numba = {(r["env"], r["num_envs"]): r for r in st if r["stack"].startswith("numba")}
        for r in st:
            if r["stack"].startswith("jax"):
                b = numba[(r["env"], r["num_envs"])]
                lines.append(
                    f"| {r['env'].split('/')[-1]} | {r['num_envs']} | {r['steps_per_s']:.3g} | {b['steps_per_s']:.3g} | "
                    f"{_fmt_spread(r['ratio_to_numba'], r['ratio_to_numba_range'], '.2f')} |"
                )
        lines.append("")
    t = result.get("targets") or {}
    if t:
        lines.append("targets (measured, not asserted): " + "; ".join(f"{k} met={v['met']}" for k, v in t.items()))
    return "\n".join(lines)


# --------------------------------------------------------------------------- main


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _versions() -> dict[str, str | None]:
    from importlib import metadata

    out: dict[str, str | None] = {}
    for name in ("jax", "jaxlib", "flax", "optax", "sbx-rl", "stable_baselines3", "torch", "numpy", "numba"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.jax_training", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="tiny budgets, fast compile (a smoke run)")
    parser.add_argument(
        "--rounds", type=int, default=None, help="alternating rounds of the timed comparisons (5; --quick 2)"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=None,
        help="training seeds 0..S-1 per backend in the quality section (3; --quick 1)",
    )
    parser.add_argument("--skip-quality", action="store_true", help="no quality section")
    parser.add_argument("--skip-search", action="store_true", help="no population search")
    parser.add_argument("--skip-stepping", action="store_true", help="no env-stepping section")
    parser.add_argument(
        "--no-all-cores", action="store_true", help="no all-cores fused rows (a child process that compiles again)"
    )
    parser.add_argument(
        "--speed-env",
        action="append",
        help=f"env id of the speed section (its ppo.yml recipe; default {ENV_ID}); repeat for more envs: the first "
        "gives the headline ratios, the others go to speed_other_envs (e.g. attitude_envs/LinearSystem-v1)",
    )
    parser.add_argument("--out", default="results/benchmarks", help="directory of jax_training.json")
    args = parser.parse_args(argv)
    args.seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    args.rounds = args.rounds if args.rounds is not None else (2 if args.quick else 5)
    if args.rounds < 1 or args.seeds < 1:
        parser.error(f"--rounds and --seeds must be >= 1, got {args.rounds} and {args.seeds}")
    out = Path(args.out) / "jax_training.json"
    for p in (out.parent, *out.parent.parents):
        if p.exists() and not p.is_dir():
            parser.error(f"--out {args.out!r} must be a directory; {str(p)!r} is a file")
    try:
        import sbx  # noqa: F401

        from experiments.training.algorithm import check_backend

        check_backend("jax", "ppo")
    except (ImportError, ValueError) as exc:
        print(f"error: this benchmark needs the sbx and jax extras ({exc})", file=sys.stderr)
        return 2

    saved = {
        k: os.environ.get(k) for k in (FAST_COMPILE_ENV, "JAX_COMPILATION_CACHE_DIR", "JAX_ENABLE_COMPILATION_CACHE")
    }
    try:
        return _run(args, out, list(sys.argv[1:] if argv is None else argv))
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run(args: argparse.Namespace, out: Path, argv: list[str]) -> int:
    start = time.perf_counter()
    _no_compile_cache()
    if args.quick:
        os.environ[FAST_COMPILE_ENV] = "1"
    cpus = set(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else set()
    cpu = pin_to_one_core(0)  # before JAX starts its CPU backend: its thread pool follows the affinity
    pinned = f"one CPU (cpu {cpu}), torch 1 thread" if cpu is not None else "not pinned (no affinity call)"
    import jax

    jax.config.update("jax_enable_compilation_cache", False)
    from experiments.report.provenance import git_revision

    result: dict[str, Any] = {}
    task = campaign_task(ENV_ID)
    key = {"command": argv, "git_revision": git_revision(ROOT)}
    done = _Checkpoint(out.with_name("jax_training.partial.json"), key)
    with tempfile.TemporaryDirectory(prefix="jax-training-benchmark-") as tmp:
        result |= _sections(args, task, Path(tmp), pinned, cpus, done)
    result["targets"] = targets(result)

    meta = {
        "machine": platform.platform(),
        "processor": platform.processor(),
        "python": platform.python_version(),
        "cores": os.cpu_count(),
        "cpus_available": sorted(cpus),
        "pinned": pinned,
        "jax_device": _jax_device(),
        "versions": _versions(),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git_revision": git_revision(ROOT),
        "quick": bool(args.quick),
        "fast_compile": bool(args.quick),
        "persistent_compilation_cache": False,
        "rounds": args.rounds,
        "command": " ".join(["python -m benchmarks.jax_training", *argv]),
        "wall_s": time.perf_counter() - start + sum(done.section_wall_s.get(name, 0.0) for name in done.reused),
        "sections_from_an_earlier_run": done.reused,
    }
    result = {"meta": meta, **result}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(_finite_or_none(result), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    done.path.unlink(missing_ok=True)
    print(markdown(result))
    print(f"\nwrote {out}")
    return 0


class _Checkpoint:
    """The finished sections of a run, kept in ``OUT/jax_training.partial.json`` as each one ends
    (a killed or failed run loses only the section it was in). A rerun of the same command on
    the same commit takes the finished sections from there; a finished run deletes the file."""

    def __init__(self, path: Path, key: dict[str, Any]) -> None:
        self.path, self.key = path, key
        self.sections: dict[str, Any] = {}
        self.section_wall_s: dict[str, float] = {}  # s per kept section
        self.reused: list[str] = []
        if path.is_file():
            saved = json.loads(path.read_text(encoding="utf-8"))
            if saved.get("key") == key:
                self.sections, self.section_wall_s = saved["sections"], saved["section_wall_s"]
                _say(f"{path}: sections {sorted(self.sections)} finished before (same command and commit)")
            else:
                _say(f"{path} is from another command or commit: starting over")

    def run(self, name: str, fn: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """The section ``name``: from the file when it finished before, else ``fn()`` (saved)."""
        if name in self.sections:
            _say(f"{name}: finished before, not run again")
            self.reused.append(name)
            return self.sections[name]
        start = time.perf_counter()
        self.sections[name] = _finite_or_none(fn())
        self.section_wall_s[name] = time.perf_counter() - start
        self.path.parent.mkdir(parents=True, exist_ok=True)
        payload = {"key": self.key, "section_wall_s": self.section_wall_s, "sections": self.sections}
        tmp = self.path.with_name(self.path.name + ".tmp")
        tmp.write_text(json.dumps(payload, allow_nan=False) + "\n", encoding="utf-8")
        os.replace(tmp, self.path)
        return self.sections[name]


def _sections(
    args: argparse.Namespace, task: Task, workdir: Path, pinned: str, cpus: set[int], done: _Checkpoint
) -> dict[str, Any]:
    """The sections the arguments ask for (run directories under ``workdir``), each through ``done``."""
    result: dict[str, Any] = {}

    rollouts = 2 if args.quick else 32
    for i, env_id in enumerate(args.speed_env or [ENV_ID]):
        speed_task = task if env_id == ENV_ID else campaign_task(env_id)
        all_cores = cpus if len(cpus) > 1 and i == 0 and not args.no_all_cores else None  # the first env's

        def run_speed(speed_task=speed_task, all_cores=all_cores) -> dict[str, Any]:
            _say(f"speed: {speed_task.env_id}, {args.rounds} rounds of {rollouts} rollouts per seed")
            return speed(speed_task.env_id, speed_task.env_kwargs, rollouts, args.rounds, pinned, all_cores)

        sp = done.run(f"speed {env_id}", run_speed)
        if i == 0:
            result["ppo_per_seed_vs_sbx"] = sp["ppo_per_seed_vs_sbx"]
            result["ppo_16_seeds_vs_sbx"] = sp["ppo_16_seeds_vs_sbx"]
            result["speed"] = sp
        else:
            result.setdefault("speed_other_envs", []).append(sp)
    if not args.skip_quality:
        recipe_steps = int(float(_recipe(ENV_ID)["n_timesteps"]))
        steps, eval_freq = (640, 320) if args.quick else (recipe_steps, 10_000)
        seeds = list(range(args.seeds))
        twin_cpus = cpus if len(cpus) > 1 and not args.no_all_cores else None
        result["quality"] = done.run(
            "quality",
            lambda: quality(task, seeds, steps, eval_freq, workdir / "quality", args.quick, twin_cpus),
        )
    if not args.skip_search:
        n, steps, evaluations, episodes = (
            (8, 640, 1, 2) if args.quick else (64, int(float(_recipe(ENV_ID)["n_timesteps"])), 3, 10)
        )
        result["search"] = done.run("search", lambda: search(task, n, steps, evaluations, episodes, workdir))
    if not args.skip_stepping:
        sizes = (1, 64) if args.quick else (1, 64, 4096)

        def run_stepping() -> dict[str, Any]:
            _say("env stepping")
            rows = env_stepping(STEPPING_ENV_IDS, sizes, 0.2 if args.quick else 1.0, args.rounds, 50, pinned)
            return {"rows": rows}

        result["env_stepping"] = done.run("env_stepping", run_stepping)["rows"]
    return result


def _finite_or_none(value: Any) -> Any:
    """``value`` as strict JSON: numpy scalars as Python numbers, NaN and ±inf as None."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


if __name__ == "__main__":
    raise SystemExit(main())
