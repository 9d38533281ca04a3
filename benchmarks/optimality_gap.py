"""How far is each analytic controller from the optimum? J*/J per env, task and controller.

    python -m benchmarks.optimality_gap --out results/benchmarks/optimality_gap.json [--seeds 5]
        [--tasks rw-nominal two-wheel-failure ...] [--workers 2] [--mpc-budget-s 600]

For every task of :data:`TASKS` (an env's nominal episode and the packaged task scenarios that
apply to it) and every seed it solves the episode's optimum J* with
:func:`experiments.optimum.solve_episode` (cache on; warm start ``"best"``: the cheapest of
:data:`experiments.optimum.BASELINES` on that episode) and runs every analytic controller of
the task (built by name through :func:`experiments.policies.build_policy`) on the same episode
(the same env kwargs and faults, ``reset(seed=seed)``, no reset options) through
:func:`attitude_envs.evaluation.rollout`, which hands the policy :func:`attitude_envs.info.policy_view`
of each info (no ground truth). Per controller and seed it records J (sum of ``info["cost"]``),
``J*/J`` (≤ 1: the room left to any controller; J* is an **oracle's** optimum, the solver knows
the fault schedule and every episode draw) and, for the attitude envs, success (true final
error ≤ 2°). The optimal actions are replayed the same way (open loop), so J* has a final error
and a success too.

J* is IPOPT's local optimum from one warm start. When a controller ends an episode cheaper than
J* (a worse local optimum) the episode is solved again, warm-started from that controller's
actions (not cached), and J* is the better of the two (``refined`` in the output).

Episodes that do not depend on the seed (a preset with a fixed start state and no noise, e.g.
FuelSlosh-v0's paper start and LinearSystem-v0's heravi-2017) are detected — the first
controller's J equal for every seed — and solved and rolled out for the first seed only; the
output says ``"seed_independent": true`` and lists the seeds the episode stands for.

The nonlinear MPC (``mpc``, ReactionWheel-v0 and AirBearing-v0) is timed on a short probe first
(``--mpc-probe-steps`` steps of the first seed); it is left out of a task whose estimated serial
run time (seconds per step × steps × seeds) exceeds ``--mpc-budget-s`` (default 600 s), and the
output says so. Its solve time per step (median over the episode's steps) is recorded.

Jobs (one J* solve, or one controller on one seed) run on a process pool (``--workers``, default
2). Each finished job is appended to a journal next to the output (``.journal.jsonl``);
``--resume`` reuses it (and the J* cache) after an interrupted run. Writes the JSON to ``--out``
(default ``results/benchmarks/optimality_gap.json``, git-ignored) and a markdown summary next to
it (``.md``); the committed copies are ``benchmarks/optimality_gap.json`` and
``benchmarks/optimality_gap.md``.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import multiprocessing
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs
from attitude_envs.evaluation import rollout
from attitude_envs.info import policy_view
from attitude_envs.scenarios import load_scenario
from experiments.campaign.store import append_line, read_lines
from experiments.optimum import full_id, solve_episode
from experiments.policies import build_policy

DEFAULT_OUT = "results/benchmarks/optimality_gap.json"
SUCCESS_ERROR_DEG = 2.0
#: envs whose episodes end at an attitude (success: true final error ≤ SUCCESS_ERROR_DEG)
ATTITUDE_ENVS = ("ReactionWheel-v0", "AirBearing-v0", "Magnetorquer-v0")
#: FuelSlosh-v0's episodes here (both tasks; the preset's 1500 s is 15 000 steps, beyond an
#: affordable solve: 100 s takes IPOPT ≈ 120 iterations and 2–7 min on one core); the faults of
#: slosh-actuator-faults start at 50 s
SLOSH_EPISODE_S = 100.0
#: Magnetorquer-v0's episode here (the preset's two orbits are ≈ 12 000 s, 120 000 steps; 600 s
#: took IPOPT 71 iterations and 14 min on a loaded core); the faults of sadigh-2022-faults start at 50 s
MAGNETORQUER_EPISODE_S = 300.0

#: (label, registry name, parameters) of the analytic controllers of each env
GYROSTAT = [
    ("lqr-zoh", "lqr", {"discretization": "zoh"}),
    ("lqr-continuous", "lqr", {"discretization": "continuous"}),
    ("quaternion-lqr", "quaternion-lqr", {}),
    ("feedback-linearization", "feedback-linearization", {}),
    ("pid", "pid", {}),
    ("lqr-ft", "lqr-ft", {}),
    ("mpc", "mpc", {}),
]
#: free drift, a reference row in every task (not a controller)
ZERO = ("zero (reference)", "zero", {})
CONTROLLERS: dict[str, list[tuple[str, str, dict]]] = {
    "ReactionWheel-v0": GYROSTAT,
    "AirBearing-v0": GYROSTAT,
    "LinearSystem-v0": [("linear-lqr", "linear-lqr", {})],
    "FuelSlosh-v0": [
        ("slosh-lqr", "slosh-lqr", {}),
        ("slosh-pd", "slosh-pd", {}),
        ("slosh-lyapunov", "slosh-lyapunov", {}),
        ("slosh-fuzzy", "slosh-fuzzy", {}),
    ],
    "Magnetorquer-v0": [
        ("amnftsmc", "amnftsmc", {}),
        ("mnftsmc", "mnftsmc", {}),
        ("ftsmc-standin", "ftsmc-standin", {}),
        ("bdot", "bdot", {}),
    ],
}


@dataclass
class Task:
    """One env × task: ``env_kwargs`` include the scenario's faults."""

    key: str
    env_id: str
    task: str
    env_kwargs: dict
    note: str = ""
    controllers: list[tuple[str, str, dict]] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.controllers:
            self.controllers = [*CONTROLLERS[self.env_id], ZERO]


def scenario_task(key: str, name: str, note: str = "", **overrides: Any) -> Task:
    """A task from a packaged scenario (its env, kwargs and faults; ``overrides`` on top)."""
    sc = load_scenario(name)
    kwargs = dict(sc["env_kwargs"])
    if sc["faults"]:
        kwargs["faults"] = sc["faults"]
    kwargs.update(overrides)
    return Task(key, sc["env"].split("/")[-1], name, kwargs, note)


def tasks() -> list[Task]:
    """Every task of the benchmark, in report order."""
    slosh_note = f"episode shortened to {SLOSH_EPISODE_S:g} s (preset: 1500 s)"
    return [
        Task(
            "rw-nominal",
            "ReactionWheel-v0",
            "nominal",
            {"preset": "pyramid-4wheel", "action_frame": "body"},
            "body-torque actions, as in the campaigns",
        ),
        scenario_task("two-wheel-failure", "two-wheel-failure"),
        scenario_task("tight-torque", "tight-torque", "the scenario's wheel-torque actions"),
        Task("ab-nominal", "AirBearing-v0", "nominal", {"preset": "air-bearing-85kg"}),
        scenario_task("air-bearing-outage", "air-bearing-outage"),
        scenario_task("air-bearing-offset-change", "air-bearing-offset-change"),
        Task(
            "ls-nominal",
            "LinearSystem-v0",
            "nominal",
            {"preset": "heravi-2017", "episode_steps": 40000},
            "400 s, as in the full campaign",
        ),
        Task(
            "slosh-nominal",
            "FuelSlosh-v0",
            "nominal",
            {"preset": "navabi-fill-i", "episode_duration_s": SLOSH_EPISODE_S},
            slosh_note,
        ),
        scenario_task("slosh-actuator-faults", "slosh-actuator-faults", slosh_note, episode_duration_s=SLOSH_EPISODE_S),
        scenario_task(
            "sadigh-2022-faults",
            "sadigh-2022-faults",
            f"episode shortened to {MAGNETORQUER_EPISODE_S:g} s (preset: two orbits)",
            episode_duration_s=MAGNETORQUER_EPISODE_S,
        ),
    ]


class ReplayPolicy:
    """Open-loop replay of an action sequence (zeros after its end) through :func:`rollout`."""

    def __init__(self, actions: np.ndarray, name: str = "J*") -> None:
        self.actions = np.asarray(actions, dtype=float)
        self.name = name
        self._k = 0

    def reset(self, seed: int | None = None) -> None:
        self._k = 0

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        k, self._k = self._k, self._k + 1
        return self.actions[k] if k < len(self.actions) else np.zeros(self.actions.shape[1])


class RecordingPolicy:
    """A policy that keeps the actions it returns (for a refined J* warm start)."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.name = policy.name
        self.actions: list[np.ndarray] = []

    def reset(self, seed: int | None = None) -> None:
        self.actions = []
        self.policy.reset(seed)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        action = np.asarray(self.policy.act(obs, info), dtype=float)
        self.actions.append(np.clip(action, -1.0, 1.0))
        return action


def make_env(task: Task):
    return gym.make(full_id(task.env_id), **task.env_kwargs)


def episode_row(task: Task, result: dict) -> dict:
    """``J``, steps, termination, final error and success of a :func:`rollout` result."""
    error = float(result["final_error_deg"])
    attitude = task.env_id in ATTITUDE_ENVS
    return {
        "J": float(result["J"]),
        "steps": int(result["steps"]),
        "terminated": bool(result["terminated"]),
        "final_error_deg": error if attitude else None,
        "success": bool(error <= SUCCESS_ERROR_DEG) if attitude else None,
    }


# ---------------------------------------------------------------- jobs (run in the pool)
def job_optimum(task: Task, seed: int, warm_actions: np.ndarray | None = None) -> dict:
    """J* of one episode (cached; or warm-started from ``warm_actions``, not cached), with the
    replay of its actions through :func:`rollout`."""
    start = time.perf_counter()
    warm = "best" if warm_actions is None else warm_actions
    result = solve_episode(task.env_id, task.env_kwargs, seed, None, warm_start=warm)
    env = make_env(task)
    try:
        replayed = episode_row(task, rollout(env, ReplayPolicy(result.actions), seed=seed))
    finally:
        env.close()
    row = result.row()
    for key in ("env_kwargs", "options", "env_id", "seed", "oracle", "notes"):
        row.pop(key, None)
    row["replay"] = replayed
    row["wall_s"] = time.perf_counter() - start
    return row


def job_controller(task: Task, seed: int, label: str, name: str, params: dict, keep_actions: bool = False) -> dict:
    """One controller on one episode; the MPC's per-step solve times summarized; its actions
    (``"actions"``) with ``keep_actions``."""
    env = make_env(task)
    try:
        policy = RecordingPolicy(build_policy({"policy": name, "params": dict(params)}, env, name=label))
        start = time.perf_counter()
        row = episode_row(task, rollout(env, policy, seed=seed))
        row["wall_s"] = time.perf_counter() - start
    finally:
        env.close()
    times = getattr(policy.policy, "solve_times_s", None)
    if times:
        row["solve_ms_per_step_median"] = 1e3 * statistics.median(times)
        row["solve_ms_per_step_mean"] = 1e3 * statistics.fmean(times)
        row["solve_failures"] = int(getattr(policy.policy, "failures", 0))
    if keep_actions:
        row["actions"] = np.asarray(policy.actions)
    return row


def job_refine(task: Task, seed: int, label: str, name: str, params: dict) -> dict:
    """J* of one episode warm-started from the actions of controller ``label`` (not cached)."""
    actions = job_controller(task, seed, label, name, params, keep_actions=True)["actions"]
    return job_optimum(task, seed, actions)


def run_job(kind: str, args: tuple) -> dict:
    """Pool entry point; errors come back as ``{"error": ...}`` rows."""
    try:
        return {"optimum": job_optimum, "controller": job_controller, "refine": job_refine}[kind](*args)
    except Exception as exc:  # noqa: BLE001 - reported in the output, the benchmark goes on
        return {"error": f"{type(exc).__name__}: {exc}"}


# ---------------------------------------------------------------- planning (main process)
def distinct_seeds(task: Task, seeds: list[int]) -> tuple[list[int], bool]:
    """``(seeds to run, seed_independent)``: the first seed only when the first controller's J
    is the same for every seed (a deterministic episode)."""
    label, name, params = task.controllers[0]
    env = make_env(task)
    try:
        costs = set()
        for seed in seeds:
            policy = build_policy({"policy": name, "params": dict(params)}, env, name=label)
            costs.add(float(rollout(env, policy, seed=seed)["J"]))
    finally:
        env.close()
    if len(costs) == 1 and len(seeds) > 1:
        return seeds[:1], True
    return seeds, False


def mpc_probe(task: Task, seed: int, probe_steps: int) -> dict:
    """Seconds per MPC step on the first ``probe_steps`` steps of an episode (median solve)."""
    env = make_env(task)
    try:
        base = env.unwrapped
        n_steps = int(round(base.episode_duration_s / base.control_dt_s))
        policy = build_policy({"policy": "mpc", "params": {}}, env)
        obs, info = env.reset(seed=seed)
        policy.reset(seed)
        start = time.perf_counter()
        for _ in range(probe_steps):
            obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
            if terminated or truncated:
                break
        per_step = (time.perf_counter() - start) / max(1, len(policy.solve_times_s))
    finally:
        env.close()
    return {"probe_steps": probe_steps, "s_per_step": per_step, "episode_steps": n_steps}


def summarize(values: list[float]) -> dict:
    arr = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if arr.size == 0:
        return {"mean": None, "min": None, "max": None}
    return {"mean": float(arr.mean()), "min": float(arr.min()), "max": float(arr.max())}


def aggregate(task: Task, run_seeds: list[int], optimum: dict, controllers: dict) -> dict:
    """Per-controller means over seeds of J*/J, J and success."""
    rows = {}
    for label, per_seed in controllers.items():
        ratios, costs, successes, errors = [], [], [], []
        mpc_ms = []
        for seed in run_seeds:
            row, opt = per_seed.get(seed), optimum.get(seed)
            if row is None or "error" in row:
                continue
            costs.append(row["J"])
            if opt is not None and "error" not in opt:
                row["ratio"] = opt["j_star"] / row["J"] if row["J"] > 0 else None
                ratios.append(row["ratio"])
            if row["success"] is not None:
                successes.append(row["success"])
            if "solve_ms_per_step_median" in row:
                mpc_ms.append(row["solve_ms_per_step_median"])
            errors.append(row.get("final_error_deg"))
        failed = [f"seed {s}: {per_seed[s]['error']}" for s in run_seeds if "error" in per_seed.get(s, {})]
        rows[label] = {
            "ratio": summarize(ratios),
            "J": summarize(costs),
            "success": f"{sum(successes)}/{len(successes)}" if successes else None,
            "success_rate": float(np.mean(successes)) if successes else None,
            "final_error_deg": summarize(errors),
            "n": len(costs),
            "errors": failed,
            **({"solve_ms_per_step_median": statistics.median(mpc_ms)} if mpc_ms else {}),
            "per_seed": {str(s): per_seed[s] for s in run_seeds if s in per_seed},
        }
    opts = [optimum[s] for s in run_seeds if s in optimum and "error" not in optimum[s]]
    replay_success = [o["replay"]["success"] for o in opts if o["replay"]["success"] is not None]
    return {
        "optimum": {
            "j_star": summarize([o["j_star"] for o in opts]),
            "solve_s_median": statistics.median([o["solve_s"] for o in opts]) if opts else None,
            "total_s_median": statistics.median([o["total_s"] for o in opts]) if opts else None,
            "statuses": sorted({o["status"] for o in opts}),
            "refined": sum(bool(o.get("refined")) for o in opts),
            "success": f"{sum(replay_success)}/{len(replay_success)}" if replay_success else None,
            "errors": [f"seed {s}: {optimum[s]['error']}" for s in run_seeds if "error" in optimum.get(s, {})],
            "per_seed": {str(s): optimum[s] for s in run_seeds if s in optimum},
        },
        "controllers": rows,
    }


def markdown(report: dict) -> str:
    """The summary table: one row per env × task × controller."""
    meta = report["meta"]
    lines = [
        "# Optimality gap of the analytic controllers: J*/J",
        "",
        "Generated by `python -m benchmarks.optimality_gap` "
        f"({meta['seeds_requested']} seeds, {meta['workers']} workers, {meta['wall_s'] / 60:.0f} min wall on "
        f"{meta['cpu_count']} cores; {meta['date']}). J* is an **oracle's** optimum (IPOPT, multiple shooting, "
        "the fault schedule and every episode draw known; `experiments/optimum.py`); J is a controller's cost "
        "on the same episode (`rollout`, `policy_view` infos). J*/J ≤ 1, the fraction of J no controller can "
        f"avoid; 1 − J*/J is the room left. Success: true final error ≤ {SUCCESS_ERROR_DEG:g}° (attitude envs).",
        "",
        "| env | task | controller | J*/J mean [min, max] | success | mean J |",
        "|---|---|---|---|---:|---:|",
    ]
    for t in report["tasks"]:
        opt = t["optimum"]
        js = opt["j_star"]["mean"]
        lines.append(f"| {t['env']} | {t['task']} | **J\\*** | 1 | {opt['success'] or '—'} | {_g(js)} |")
        for label, c in t["controllers"].items():
            r = c["ratio"]
            ratio = "—" if r["mean"] is None else f"{r['mean']:.3f} [{r['min']:.3f}, {r['max']:.3f}]"
            if c["errors"]:
                ratio += f" ({len(c['errors'])} failed)"
            lines.append(f"| | | {label} | {ratio} | {c['success'] or '—'} | {_g(c['J']['mean'])} |")
    lines += [
        "",
        "## J* solves and tasks",
        "",
        "| env | task | episodes | J* solve s (median) | J* total s (median) | IPOPT status | refined | MPC ms/step | note |",
        "|---|---|---|---:|---:|---|---:|---:|---|",
    ]
    for t in report["tasks"]:
        opt = t["optimum"]
        seeds = t["seeds"]
        episodes = (
            f"{len(t['run_seeds'])} (seed-independent: stands for seeds {seeds})"
            if t["seed_independent"]
            else str(len(seeds))
        )
        note = "; ".join(x for x in (t["note"], t.get("mpc", {}).get("note", "")) if x)
        mpc_ms = t["controllers"].get("mpc", {}).get("solve_ms_per_step_median")
        lines.append(
            f"| {t['env']} | {t['task']} | {episodes} | {_g(opt['solve_s_median'])} | {_g(opt['total_s_median'])} | "
            f"{', '.join(opt['statuses']) or 'failed'} | {opt['refined']} | {_g(mpc_ms)} | {note} |"
        )
    failures = [
        f"- {t['env']} {t['task']} {who}: {e}"
        for t in report["tasks"]
        for who, errs in [("J*", t["optimum"]["errors"])] + [(k, c["errors"]) for k, c in t["controllers"].items()]
        for e in errs
    ]
    if failures:
        lines += ["", "## Failures", "", *failures]
    lines += [
        "",
        "## Notes",
        "",
        "- J* is the optimum of the episode as the env scores it: a finite horizon. It stops paying for the "
        "error at the episode's end, so its own final error can exceed the success band where a controller's "
        "does not (the J\\* row's success).",
        "- Seed-independent tasks (a fixed start state, no noise: the first controller's J is equal for every "
        "seed) are solved and rolled out once; their [min, max] is one episode.",
        "- `mpc` is the nonlinear MPC on the nominal model (no fault knowledge), 20-step horizon; `lqr-ft` is the "
        "LQR with IMM fault detection and redesign; `zero (reference)` is free drift, not a controller.",
        "- J* solve times are IPOPT wall times on one core of this machine (the cache keeps the time of the "
        "solve that filled it); J* total adds the problem build, the warm-start rollouts and the replay.",
    ]
    return "\n".join(lines) + "\n"


def _g(value) -> str:
    return "—" if value is None else f"{value:.4g}"


def read_journal(path: Path, seeds: list[int]) -> dict:
    """Finished work of an earlier run: ``{("plan", task): plan, (kind, task, seed, label): row}``;
    plans made for other seeds are dropped."""
    rows: dict = {}
    for entry in read_lines(path):
        if entry["type"] == "plan":
            if entry["seeds"] == seeds:
                rows[("plan", entry["task"])] = entry["row"]
        else:
            rows[(entry["type"], entry["task"], entry["seed"], entry["label"])] = entry["row"]
    return rows


def main(argv: list[str] | None = None) -> int:
    all_tasks = tasks()
    parser = argparse.ArgumentParser(prog="python -m benchmarks.optimality_gap", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=DEFAULT_OUT, help=f"JSON output (default {DEFAULT_OUT}); markdown next to it")
    parser.add_argument("--seeds", type=int, default=5, help="seeds 0 … N−1 per task (default 5)")
    parser.add_argument(
        "--tasks", nargs="+", default=None, help=f"task keys (default all): {[t.key for t in all_tasks]}"
    )
    parser.add_argument("--workers", type=int, default=2, help="process-pool size (default 2)")
    parser.add_argument("--mpc-budget-s", type=float, default=600.0, help="leave the MPC out above this (s per task)")
    parser.add_argument("--mpc-probe-steps", type=int, default=20, help="MPC steps timed to estimate its run time")
    parser.add_argument(
        "--resume", action="store_true", help="reuse the plans and finished jobs of OUT's journal (.journal.jsonl)"
    )
    args = parser.parse_args(argv)
    chosen = all_tasks
    if args.tasks:
        known = {t.key: t for t in all_tasks} | {t.task: t for t in all_tasks if t.task != "nominal"}
        unknown = [k for k in args.tasks if k not in known]
        if unknown:
            parser.error(f"unknown tasks {unknown}; accepted: {[t.key for t in all_tasks]}")
        chosen = [known[k] for k in args.tasks]
    seeds = list(range(args.seeds))
    wall = time.perf_counter()
    out_path = Path(args.out)

    journal = out_path.with_suffix(".journal.jsonl")
    done_rows = read_journal(journal, seeds) if args.resume else {}
    if not args.resume:
        journal.parent.mkdir(parents=True, exist_ok=True)
        journal.write_text("")

    def record(entry: dict) -> None:
        append_line(journal, entry, default=_json_default)

    plans = {}
    for task in chosen:
        plan = done_rows.get(("plan", task.key))
        if plan is None:
            run_seeds, independent = distinct_seeds(task, seeds)
            plan = {"run_seeds": run_seeds, "seed_independent": independent, "mpc": {}}
            if any(name == "mpc" for _, name, _ in task.controllers):
                probe = mpc_probe(task, seeds[0], args.mpc_probe_steps)
                estimate = probe["s_per_step"] * probe["episode_steps"] * len(run_seeds)
                probe["estimated_task_s"] = estimate
                probe["run"] = estimate <= args.mpc_budget_s
                if not probe["run"]:
                    probe["note"] = (
                        f"MPC left out: {probe['s_per_step'] * 1e3:.0f} ms/step × {probe['episode_steps']} steps × "
                        f"{len(run_seeds)} seeds ≈ {estimate / 60:.0f} min > {args.mpc_budget_s / 60:.0f} min"
                    )
                plan["mpc"] = probe
            record({"type": "plan", "task": task.key, "seeds": seeds, "row": plan})
        if plan["mpc"] and not plan["mpc"]["run"]:
            task.controllers = [c for c in task.controllers if c[1] != "mpc"]
        plans[task.key] = plan
        print(f"[plan] {task.key}: seeds {plan['run_seeds']} {plan['mpc']}", flush=True)

    # long jobs first: J* solves of the long episodes, then the MPC, then the rest
    jobs = []
    for task in chosen:
        for seed in plans[task.key]["run_seeds"]:
            jobs.append((0 if task.env_id in ("FuelSlosh-v0", "Magnetorquer-v0") else 2, "optimum", task, seed, None))
            for label, name, params in task.controllers:
                jobs.append((1 if name == "mpc" else 3, "controller", task, seed, (label, name, params)))
    jobs.sort(key=lambda j: j[0])
    optimum: dict[str, dict[int, dict]] = {t.key: {} for t in chosen}
    results: dict[str, dict[str, dict[int, dict]]] = {t.key: {c[0]: {} for c in t.controllers} for t in chosen}

    def store(kind: str, task: Task, seed: int, ctrl, row: dict) -> None:
        (optimum[task.key] if kind == "optimum" else results[task.key][ctrl[0]])[seed] = row

    todo = []
    for job in jobs:
        _, kind, task, seed, ctrl = job
        key = (kind, task.key, seed, None if ctrl is None else ctrl[0])
        if key in done_rows:
            store(kind, task, seed, ctrl, done_rows[key])
        else:
            todo.append(job)
    if len(todo) < len(jobs):
        print(f"[resume] {len(jobs) - len(todo)} of {len(jobs)} jobs read from {journal}", flush=True)

    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx) as pool:
        futures = {}
        for _, kind, task, seed, ctrl in todo:
            job_args = (task, seed) if kind == "optimum" else (task, seed, *ctrl)
            futures[pool.submit(run_job, kind, job_args)] = (kind, task, seed, ctrl)
        for done, fut in enumerate(cf.as_completed(futures), 1):
            kind, task, seed, ctrl = futures[fut]
            row = fut.result()
            store(kind, task, seed, ctrl, row)
            label = None if ctrl is None else ctrl[0]
            if "error" not in row:
                record({"type": kind, "task": task.key, "seed": seed, "label": label, "row": row})
            what = row.get("error") or (
                f"J* = {row['j_star']:.6g} {row['status']} {row['solve_s']:.1f} s"
                if kind == "optimum"
                else f"J = {row['J']:.6g}"
            )
            print(
                f"[{done}/{len(todo)} {time.perf_counter() - wall:.0f} s] {task.key} seed {seed} {label or 'J*'}: {what}",
                flush=True,
            )

        # a controller cheaper than J*: J* was a worse local optimum; solve again from its actions
        refine = []
        for task in chosen:
            for seed in plans[task.key]["run_seeds"]:
                opt = optimum[task.key].get(seed)
                if opt is None or "error" in opt:
                    continue
                rows = [
                    (label, r)
                    for label, per_seed in results[task.key].items()
                    if (r := per_seed.get(seed)) is not None and "error" not in r and not r["terminated"]
                ]
                cheaper = [(label, r) for label, r in rows if r["J"] < opt["j_star"] * (1 - 1e-9)]
                if cheaper:
                    label = min(cheaper, key=lambda lr: lr[1]["J"])[0]
                    ctrl = next(c for c in task.controllers if c[0] == label)
                    refine.append((task, seed, ctrl))
        refined = {
            pool.submit(run_job, "refine", (task, seed, *ctrl)): (task, seed, ctrl) for task, seed, ctrl in refine
        }
        for fut in cf.as_completed(refined):
            task, seed, ctrl = refined[fut]
            row, old = fut.result(), optimum[task.key][seed]
            if "error" not in row and row["j_star"] < old["j_star"]:
                row["refined"] = f"warm-started from {ctrl[0]}"
                row["solve_s"] += old["solve_s"]
                row["total_s"] += old["total_s"]
                row["unrefined_j_star"] = old["j_star"]
                optimum[task.key][seed] = row
            else:
                old["refine_attempt"] = row.get("error") or f"J* {row['j_star']:.6g} from {ctrl[0]}'s actions"
            print(f"[refine] {task.key} seed {seed}: {optimum[task.key][seed]['j_star']:.6g}", flush=True)

    report = {
        "meta": {
            "command": "python -m benchmarks.optimality_gap " + " ".join(argv if argv is not None else sys.argv[1:]),
            "date": time.strftime("%Y-%m-%d"),
            "seeds_requested": args.seeds,
            "workers": args.workers,
            "cpu_count": os.cpu_count(),
            "machine": platform.platform(),
            "python": platform.python_version(),
            "attitude_envs": attitude_envs.__version__,
            "wall_s": time.perf_counter() - wall,
            "oracle": True,
            "success_error_deg": SUCCESS_ERROR_DEG,
            "warm_start": "best",
        },
        "tasks": [],
    }
    for task in chosen:
        plan = plans[task.key]
        report["tasks"].append(
            {
                "key": task.key,
                "env": task.env_id,
                "task": task.task,
                "env_kwargs": task.env_kwargs,
                "note": task.note,
                "seeds": seeds,
                "run_seeds": plan["run_seeds"],
                "seed_independent": plan["seed_independent"],
                "mpc": plan["mpc"],
                **aggregate(task, plan["run_seeds"], optimum[task.key], results[task.key]),
            }
        )
    out = out_path
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1, default=_json_default) + "\n")
    out.with_suffix(".md").write_text(markdown(report))
    print(f"wrote {out} and {out.with_suffix('.md')} ({report['meta']['wall_s'] / 60:.1f} min)")
    return 0


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serializable: {type(value).__name__}")


if __name__ == "__main__":
    raise SystemExit(main())
