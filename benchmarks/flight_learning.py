"""Do learned agents hold up in flight, and does domain randomization help? (AirBearing-v1)

Agents, each PPO with the shipped AirBearing-v1 recipe (``experiments/training/hyperparams/ppo.yml``,
its 1.2e5 timesteps, best snapshot on the recipe's validation episodes, seeds 10000+):

* ``A``: trained in the lab, as shipped;
* ``B``: trained under ``conditions="flight"``: domain randomization over the flight
  distribution (the plant, actuator gains, actuator dynamics, the one-period delay and the
  sensors), observing the measured state as the env gives it (no memory);
* ``C``: B with a frame stack of the last ``--frame-stack`` observations (the recipe's
  ``frame_stack`` key: SB3's ``VecFrameStack`` after normalization).

Every trained agent plays deterministically the AirBearing-v1 episodes of seeds 0-19 under
``"lab"`` and under ``"flight"``, as do the analytic ``lqr`` (on the measurements as given)
and ``lqr+mekf`` (``baselines.estimated.lqr_mekf``: the LQR on the MEKF's estimate; flight
only: the lab has no sensors, so the MEKF refuses and the lab reference is ``lqr`` on the exact
state), built on the same env. A flight episode of seed s starts and aims as the lab episode of seed s.

Training seeds are 1000+ (default 1000, 1001, 1002). The training env seeds its sub-envs
``seed + i`` (i < n_envs = 8; SB3's convention) once and then continues their generators, so
its episodes are those of env seeds 1000-1009 and their continuations: disjoint from the
evaluation episodes 0-19 (each a fresh ``reset(seed=s)``) and from the validation episodes
10000-10004 that choose the best snapshot (validated under the training conditions).

Results go to ``--out`` (default ``benchmarks/results/flight_learning.json``), rewritten after
every finished training run and every finished evaluation (agent × conditions, 20 episodes), so
an interrupted run resumes where it stopped; training runs resume from their checkpoints
(``--runs``, default ``runs/flight_learning``).

    python -m benchmarks.flight_learning --seeds 1000 1001 1002 --variants A B C
    python -m benchmarks.flight_learning --diagnostics   # + "delay-only" and "flight-no-delay"
    python -m benchmarks.flight_learning --report   # the table of what is recorded

J* of AirBearing-v1 flight episodes is not computed (minutes per episode); the lab J* of the
v0 cell's episodes (the shipped table, experiments/optimum_table.json) is reported where held.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401
from attitude_envs.files import atomic_write

ENV_ID = "attitude_envs/AirBearing-v1"
CONDITIONS = ("lab", "flight")
#: ``--diagnostics``: which flight feature the agents' differences come from (name → ``conditions=``)
DIAGNOSTICS = {
    "delay-only": {"delay_steps": 1},
    "flight-no-delay": {"base": "flight", "delay_steps": 0},
}
EVAL_SEEDS = tuple(range(20))
DEFAULT_OUT = Path("benchmarks/results/flight_learning.json")
DEFAULT_RUNS = Path("runs/flight_learning")
REFERENCE = "lqr+mekf"


def variant_spec(variant: str, frame_stack: int) -> dict[str, Any]:
    """The env kwargs and hyperparameter overrides of a variant."""
    if variant == "A":
        return {"env_kwargs": {}, "overrides": {}, "about": "PPO trained in the lab (as shipped)"}
    if variant == "B":
        return {
            "env_kwargs": {"conditions": "flight"},
            "overrides": {},
            "about": "PPO trained under flight conditions (domain randomization), measured obs, no memory",
        }
    if variant == "C":
        return {
            "env_kwargs": {"conditions": "flight"},
            "overrides": {"frame_stack": int(frame_stack)},
            "about": f"B with a frame stack of the last {int(frame_stack)} observations",
        }
    raise ValueError(f"unknown variant {variant!r} (A, B or C)")


# ------------------------------------------------------------------------------------------ results file
def load(path: Path) -> dict[str, Any]:
    if path.is_file():
        return json.loads(path.read_text(encoding="utf-8"))
    return {"meta": {}, "runs": [], "evaluations": []}


def save(path: Path, data: dict[str, Any]) -> None:
    """Atomic rewrite (the file always holds every finished run and evaluation)."""
    import platform

    from experiments.report.provenance import git_revision

    data["meta"] = {
        "about": __doc__.split("\n\n")[0],
        "env_id": ENV_ID,
        "eval_seeds": list(EVAL_SEEDS),
        "machine": platform.platform(),
        "date": time.strftime("%Y-%m-%d"),
        "git_revision": git_revision(),
        **{k: v for k, v in data.get("meta", {}).items() if k in ("argv",)},
    }
    atomic_write(path, json.dumps(data, indent=1) + "\n", durable=True)


def find(rows: list[dict], **key: Any) -> dict | None:
    return next((r for r in rows if all(r.get(k) == v for k, v in key.items())), None)


# ------------------------------------------------------------------------------------------ episodes
def episode_costs(policy, conditions: str, seeds=EVAL_SEEDS) -> list[float]:
    """J of each episode (sum of ``info["cost"]``) of ``policy`` on AirBearing-v1 under ``conditions``;
    the policy sees no ground truth (:func:`attitude_envs.evaluation.rollout.rollout`)."""
    from attitude_envs.evaluation.rollout import rollout

    env = gym.make(ENV_ID, conditions=DIAGNOSTICS.get(conditions, conditions))
    try:
        played = policy(env)  # one policy for all episodes: reset(seed) starts each
        return [float(rollout(env, played, seed=s)["J"]) for s in seeds]
    finally:
        env.close()


def has_sensors(conditions: str) -> bool:
    from attitude_envs.conditions import Conditions

    return Conditions.from_config(DIAGNOSTICS.get(conditions, conditions)).sensors > 0


def baseline(name: str):
    from baselines.estimated import lqr_mekf
    from baselines.lqr import LQRPolicy

    return {"lqr": LQRPolicy, "lqr+mekf": lqr_mekf}[name]


def trained_policy(model_path: Path, conditions: str):
    from experiments.policies import build_policy

    def build(env):  # behind the wrappers it trained behind, as campaigns play it
        return build_policy({"policy": "sb3", "model": str(model_path)}, env)

    return build


def evaluate(data, out: Path, agent: str, conditions: str, policy, extra: dict[str, Any]) -> None:
    if find(data["evaluations"], agent=agent, conditions=conditions) is not None:
        return
    start = time.perf_counter()
    js = episode_costs(policy, conditions)
    row = {
        "agent": agent,
        "conditions": conditions,
        **extra,
        "sum_J": float(np.sum(js)),
        "J": js,
        "wall_s": round(time.perf_counter() - start, 2),
    }
    data["evaluations"].append(row)
    save(out, data)
    print(f"  eval {agent:>14} {conditions:>6}: ΣJ = {row['sum_J']:.4f} ({row['wall_s']:.1f} s)", flush=True)


def train_run(data, out: Path, runs: Path, variant: str, seed: int, frame_stack: int, timesteps: int | None) -> Path:
    from experiments.training.training import train

    spec = variant_spec(variant, frame_stack)
    run_dir = runs / f"{variant}-seed{seed}"
    done = find(data["runs"], variant=variant, seed=seed)
    if done is None:
        print(f"train {variant} seed {seed} -> {run_dir}", flush=True)
        start = time.perf_counter()
        result = train(
            "ppo",
            ENV_ID,
            run_dir,
            env_kwargs=spec["env_kwargs"],
            seed=seed,
            overrides=spec["overrides"] or None,
            total_timesteps=timesteps,
            resume=(run_dir / "config.json").is_file(),
        )
        best = json.loads((run_dir / "best" / "best.json").read_text(encoding="utf-8"))
        data["runs"].append(
            {
                "variant": variant,
                "about": spec["about"],
                "seed": seed,
                "env_kwargs": spec["env_kwargs"],
                "overrides": spec["overrides"],
                "timesteps": result.timesteps,
                "train_wall_s": round(result.wall_time_s, 1),
                "wall_s_this_call": round(time.perf_counter() - start, 1),
                "resumed_from": result.resumed_from,
                "best": best,
                "last_eval": result.last_eval,
                "run_dir": str(run_dir),
            }
        )
        save(out, data)
        print(f"  trained in {result.wall_time_s:.0f} s; best validation J {best.get('J_mean')}", flush=True)
    return run_dir


# ------------------------------------------------------------------------------------------ report
def lab_j_star(seeds=EVAL_SEEDS) -> list[float] | None:
    """The shipped table's J* of the AirBearing-v0 cell's lab episodes (the v1 episode of seed s
    is the cell's episode s), or None when it does not hold them all."""
    from experiments.optimum_table import table_value

    vals = [table_value("attitude_envs/AirBearing-v0", {"preset": "air-bearing-85kg"}, s, None) for s in seeds]
    return None if any(v is None for v in vals) else [float(v) for v in vals]


def summarize(data: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per agent (a variant's seeds pooled) × conditions: ΣJ per training seed, its mean
    and spread, ΣJ / ΣJ[lqr+mekf] on the same episodes, the per-episode ratio's median and worst."""
    # the reference: lqr+mekf with sensors; without (the lab, delay-only) the LQR on the exact state
    ref = {r["conditions"]: np.array(r["J"]) for r in data["evaluations"] if r["agent"] == "lqr"}
    ref.update({r["conditions"]: np.array(r["J"]) for r in data["evaluations"] if r["agent"] == REFERENCE})
    jstar = lab_j_star()
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for r in data["evaluations"]:
        groups.setdefault((r.get("variant", r["agent"]), r.get("snapshot", "-"), r["conditions"]), []).append(r)
    rows = []
    for (agent, snapshot, cond), rs in sorted(groups.items()):
        sums = [r["sum_J"] for r in rs]
        row = {
            "agent": agent,
            "snapshot": snapshot,
            "conditions": cond,
            "n_seeds": len(rs),
            "train_seeds": [r.get("seed") for r in rs],
            "sum_J_per_seed": sums,
            "sum_J_mean": float(np.mean(sums)),
            "sum_J_min": float(np.min(sums)),
            "sum_J_max": float(np.max(sums)),
        }
        if cond in ref:
            ratios = [s / float(ref[cond].sum()) for s in sums]
            per_ep = np.concatenate([np.array(r["J"]) / ref[cond] for r in rs])
            row.update(
                ratio_vs_lqr_mekf_per_seed=ratios,
                ratio_vs_lqr_mekf_mean=float(np.mean(ratios)),
                episode_ratio_median=float(np.median(per_ep)),
                episode_ratio_max=float(np.max(per_ep)),
            )
        if cond == "lab" and jstar is not None:
            row["sum_J_over_sum_J_star"] = [s / float(np.sum(jstar)) for s in sums]
        rows.append(row)
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| agent | snapshot | conditions | seeds | ΣJ mean | ΣJ min–max | ΣJ/ΣJ[ref] (per seed) | episode J/J[ref] median, max |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ratios = ", ".join(f"{x:.3f}" for x in r.get("ratio_vs_lqr_mekf_per_seed", []))
        ep = f"{r['episode_ratio_median']:.3f}, {r['episode_ratio_max']:.3f}" if "episode_ratio_median" in r else "–"
        lines.append(
            f"| {r['agent']} | {r['snapshot']} | {r['conditions']} | {r['n_seeds']} | {r['sum_J_mean']:.4f} | "
            f"{r['sum_J_min']:.4f}–{r['sum_J_max']:.4f} | {ratios} | {ep} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001, 1002], help="training seeds (1000+)")
    parser.add_argument("--variants", nargs="+", default=["A", "B", "C"], choices=["A", "B", "C"])
    parser.add_argument("--frame-stack", type=int, default=3)
    parser.add_argument("--timesteps", type=int, default=None, help="default: the recipe's n_timesteps")
    parser.add_argument("--snapshots", nargs="+", default=["best", "final"], choices=["best", "final"])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--runs", type=Path, default=DEFAULT_RUNS)
    parser.add_argument("--report", action="store_true", help="print the table of what is recorded and stop")
    parser.add_argument(
        "--diagnostics",
        action="store_true",
        help=f"also evaluate every agent under {sorted(DIAGNOSTICS)} (one flight feature off or alone)",
    )
    args = parser.parse_args(argv)
    if any(s < 100 for s in args.seeds):
        parser.error("training seeds must stay far from the evaluation seeds 0-19 (use 1000+)")

    data = load(args.out)
    if not args.report:
        data.setdefault("meta", {})["argv"] = list(argv) if argv is not None else __import__("sys").argv[1:]
        conditions = CONDITIONS + (tuple(DIAGNOSTICS) if args.diagnostics else ())
        for name in ("lqr", "lqr+mekf"):
            for cond in conditions:
                if name == "lqr+mekf" and not has_sensors(cond):
                    continue  # no sensors (the lab): the MEKF refuses (the LQR sees the exact state)
                evaluate(data, args.out, name, cond, baseline(name), {"variant": name})
        for seed in args.seeds:
            for variant in args.variants:
                run_dir = train_run(data, args.out, args.runs, variant, seed, args.frame_stack, args.timesteps)
                for snapshot in args.snapshots:
                    model = run_dir / snapshot / "model.zip"
                    agent = f"{variant}-seed{seed}-{snapshot}"
                    extra = {"variant": f"ppo-{variant}", "seed": seed, "snapshot": snapshot}
                    for cond in conditions:
                        evaluate(data, args.out, agent, cond, trained_policy(model, cond), extra)
        data["summary"] = summarize(data)
        save(args.out, data)
    print(markdown(summarize(data)))
    jstar = lab_j_star()
    if jstar is not None:
        print(f"\nlab ΣJ* (v0 cell, shipped table) = {sum(jstar):.4f}")


if __name__ == "__main__":
    main()
