"""How close to J* can a controller that does not know the fault in advance get?

    python -m benchmarks.onset_bound --cells wheel/two-wheel-failure,air-bearing/yaw-wheel-outage-2s \\
        --seeds 0-19 --out benchmarks/results/onset_bound.json        # 27 min (a search shared the cores)

J* (``experiments.optimum``) is an oracle: it knows the whole fault schedule from the first step,
so it can spend the seconds before a fault's onset preparing for it (with every actuator still
healthy). A causal controller sees the same measurements with and without the fault until the
onset, so whatever preparation it makes it also makes, and pays for, in the fault-free episode.
This script measures how much of a fault cell's J / J* that foreknowledge accounts for,
per episode of a campaign's fault cell:

- ``J*``: the oracle (the episode's optimum, fault schedule known from the start);
- ``J*_onset``: the nominal episode's optimum played until the first fault's onset (what the
  best controller for the fault-free cell does there), then the optimum from the onset on with
  the fault known at once — a controller that is optimal nominally and detects and identifies
  the fault instantly and perfectly. It lower-bounds every controller that plays the nominal
  optimum before the onset (any other prefix costs nominal J); controllers that hedge for
  faults before they happen are not bounded by it.

``J*_onset / J*`` (Σ over seeds, as the campaign pages' ratios) is then the part of a causal
controller's J / J* that no detection, identification or re-planning can remove without
preparing for the fault before it happens. What preparing costs is the **hedging front**: for a
blend ``w`` the first actions (until the onset) are ``w`` · J*'s + (1 − w) · the nominal
optimum's, the same in both episodes (a controller cannot tell them apart before the onset), and
each episode continues optimally from there; ``w`` = 0 gives (J*_onset, the nominal optimum),
``w`` = 1 (J*, the nominal episode after J*'s preparation). Each point is J / J* with and
without the fault, Σ over seeds.

Every solve is the env's own discrete problem (``experiments.optimum.problem_for``) with the
prefix's actions held fixed (``solve_problem(fixed_steps=)``), IPOPT from the rollout of the
prefix followed by the optimum's actions, scored by replaying the actions through the env (J*
and the nominal optimum from the solver's cache, solved where missing). IPOPT finds local
optima; the front's points are what it found. Needs the ``optimal`` extra (CasADi).

With ``--out``, each finished episode is appended to a journal next to it (``.journal.jsonl``);
``--resume`` reuses the episodes it holds for the same cell, seed, episode and blends after an
interrupted run (a line cut short by a kill is ignored).
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import tempfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the envs)
from benchmarks.results_file import write_results
from experiments import optimum
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.spec import load_campaign
from experiments.campaign.store import append_line, read_lines
from experiments.optimum_table import SOLVER, episode_specs
from experiments.seeds import SYNTAX, seeds_arg

CELLS = ("wheel/two-wheel-failure", "air-bearing/yaw-wheel-outage-2s")
#: the hedging front's prefixes: w · (J*'s first actions) + (1 − w) · (the nominal optimum's)
BLENDS = (0.0, 0.5, 1.0)


def cell_episodes(cell: str, seeds: list[int]) -> list[dict[str, Any]]:
    """``[{seed, env_id, fault: (env_kwargs, options), nominal: (env_kwargs, options), onset_s}]``
    for the campaign cell ``"<campaign>/<fault>"`` (its first env and scenario) and ``seeds``."""
    name, _, fault = cell.partition("/")
    campaign = load_campaign(name)
    env = campaign.envs[0]
    if fault not in env.faults or fault == "none":
        raise ValueError(f"cell {cell!r}: fault must be one of {sorted(f for f in env.faults if f != 'none')}")
    outside = sorted(set(seeds) - set(campaign.seeds))
    if outside:
        raise ValueError(f"seeds {outside} are not seeds of campaign {name!r}")
    if "none" not in env.faults:
        raise ValueError(f"cell {cell!r}: campaign {name!r} has no fault-free cell 'none' to pair it with")
    onsets = [float(f["onset_s"]) for f in env.faults[fault] if "onset_s" in f]
    if not onsets:
        raise ValueError(f"cell {cell!r}: its faults name no onset_s")
    scenario = env.scenarios[0]["name"]
    with tempfile.TemporaryDirectory() as tmp:
        # the episodes of one agent that needs no training (its jobs carry the cells' kwargs)
        keep = next((a.name for a in campaign.agents if a.train is None), None)
        if keep is None:
            raise ValueError(f"campaign {name!r} has no agent without training to take its episodes from")
        jobs = episode_jobs(campaign, Path(tmp), skip_agents=[a.name for a in campaign.agents if a.name != keep])
    # the cells' own episode keys (whatever env an agent plays them on), as the J* table keys them
    by_key = {}
    for spec in episode_specs(jobs):
        for env_name, cell_scenario, cell_fault, seed in spec["cells"]:
            if env_name == env.name and cell_scenario == scenario:
                by_key[(cell_fault, seed)] = (spec["env_id"], spec["env_kwargs"], spec["options"])
    return [
        {
            "seed": s,
            "env_id": by_key[(fault, s)][0],
            "fault": by_key[(fault, s)][1:],
            "nominal": by_key[("none", s)][1:],
            "onset_s": min(onsets),
        }
        for s in seeds
    ]


def _continuation(env, problem, prefix: np.ndarray, suffix_guess: np.ndarray, seed: int, options) -> dict[str, Any]:
    """The optimum of ``problem`` with its first ``len(prefix)`` actions held at ``prefix``
    (IPOPT from the rollout of ``prefix`` + ``suffix_guess``), scored by replay in ``env``."""
    k = len(prefix)
    start = np.vstack([prefix, suffix_guess[k:]])
    actions, _, status, iterations, solve_s = optimum.solve_problem(
        problem, start, SOLVER["max_iter"], SOLVER["tol"], fixed_steps=k
    )
    actions = np.clip(actions, problem.a_lb, problem.a_ub)
    j, terminated = optimum.replay(env, actions, seed, options)
    return {"J": j, "terminated": bool(terminated), "status": status, "iterations": iterations, "solve_s": solve_s}


def onset_bound(episode: dict[str, Any], blends: tuple[float, ...] = BLENDS) -> dict[str, Any]:
    """J*, J*_onset and the hedging front of one episode (see the module docstring)."""
    env_id, seed = episode["env_id"], episode["seed"]
    fault_kwargs, fault_options = episode["fault"]
    nominal_kwargs, nominal_options = episode["nominal"]
    oracle = optimum.solve_episode(env_id, copy.deepcopy(fault_kwargs), seed, fault_options, **SOLVER)
    nominal = optimum.solve_episode(env_id, copy.deepcopy(nominal_kwargs), seed, nominal_options, **SOLVER)
    fault_env = gym.make(optimum.full_id(env_id), **copy.deepcopy(fault_kwargs))
    nominal_env = gym.make(optimum.full_id(env_id), **copy.deepcopy(nominal_kwargs))
    try:
        dt = float(fault_env.unwrapped.control_dt_s)
        k = int(np.ceil(episode["onset_s"] / dt - 1e-9))  # decisions taken before the fault acts
        fault_problem = optimum.problem_for(fault_env, seed=seed, options=fault_options)
        nominal_problem = optimum.problem_for(nominal_env, seed=seed, options=nominal_options)
        front = []
        for w in blends:
            prefix = w * oracle.actions[:k] + (1.0 - w) * nominal.actions[:k]
            # the ends of the front are the two optima themselves (no solve)
            on_fault = (
                {"J": oracle.j_star, "status": "J*"}
                if w == 1.0
                else _continuation(fault_env, fault_problem, prefix, oracle.actions, seed, fault_options)
            )
            on_nominal = (
                {"J": nominal.j_star, "status": "J*"}
                if w == 0.0
                else _continuation(nominal_env, nominal_problem, prefix, nominal.actions, seed, nominal_options)
            )
            front.append({"blend": w, "fault": on_fault, "nominal": on_nominal})
    finally:
        fault_env.close()
        nominal_env.close()
    return {
        "seed": seed,
        "onset_s": episode["onset_s"],
        "fixed_decisions": k,
        "j_star": oracle.j_star,
        "j_star_nominal": nominal.j_star,
        "j_star_onset": front[0]["fault"]["J"] if blends[0] == 0.0 else float("nan"),
        "front": front,
    }


def episode_key(cell: str, episode: dict[str, Any], blends: tuple[float, ...]) -> str:
    """What decides an episode's row: its cell, its episode (env, faults, seed) and the blends."""
    what = {"cell": cell, "episode": episode, "blends": list(blends)}
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=repr).encode()).hexdigest()


def read_journal(path: Path) -> dict[str, dict[str, Any]]:
    """Rows of an earlier run's journal by :func:`episode_key` (empty when there is none)."""
    return {entry["key"]: entry["row"] for entry in read_lines(path)}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", default=",".join(CELLS), help="comma-separated <campaign>/<fault cell>")
    parser.add_argument("--seeds", type=seeds_arg, default="0-2", help=SYNTAX)
    parser.add_argument(
        "--blends", default=",".join(f"{w:g}" for w in BLENDS), help="comma-separated prefix blends w in [0, 1], from 0"
    )
    parser.add_argument("--out", default=None, help="write the rows and the per-cell ratios as JSON here")
    parser.add_argument(
        "--resume", action="store_true", help="reuse the finished episodes of OUT's journal (.journal.jsonl)"
    )
    args = parser.parse_args(argv)
    if args.resume and not args.out:
        parser.error("--resume needs --out (the journal lies next to it)")
    try:
        blends = tuple(float(w) for w in args.blends.split(","))
    except ValueError:
        parser.error(f"--blends must be comma-separated numbers in [0, 1], got {args.blends!r}")
    if not blends or blends[0] != 0.0 or any(not 0.0 <= w <= 1.0 for w in blends):
        parser.error(f"--blends must start at 0 and lie in [0, 1], got {args.blends!r}")
    try:
        episodes = {cell: cell_episodes(cell, args.seeds) for cell in args.cells.split(",")}
    except ValueError as exc:
        parser.error(str(exc))
    journal = Path(args.out).with_suffix(".journal.jsonl") if args.out else None
    done = read_journal(journal) if args.resume else {}
    if journal is not None and not args.resume:
        journal.parent.mkdir(parents=True, exist_ok=True)
        journal.write_text("", encoding="utf-8")
    cells = {}
    for cell, cell_rows in episodes.items():
        rows = []
        for episode in cell_rows:
            key = episode_key(cell, episode, blends)
            row = done.get(key)
            if row is None:
                row = onset_bound(episode, blends)
                if journal is not None:
                    append_line(journal, {"key": key, "row": row}, default=float)
            else:
                print(f"[resume] {cell} seed {row['seed']} read from {journal}", flush=True)
            rows.append(row)
            points = ", ".join(
                f"w {p['blend']:g}: fault {p['fault']['J'] / row['j_star']:.4f} nominal "
                f"{p['nominal']['J'] / row['j_star_nominal']:.4f}"
                for p in row["front"]
            )
            print(
                f"{cell} seed {row['seed']}: J* {row['j_star']:.6g}, J*_nominal {row['j_star_nominal']:.6g}; {points}",
                flush=True,
            )
        sum_fault = sum(r["j_star"] for r in rows)
        sum_nominal = sum(r["j_star_nominal"] for r in rows)
        front = [
            {
                "blend": w,
                "fault_sum_j_over_sum_j_star": sum(r["front"][i]["fault"]["J"] for r in rows) / sum_fault,
                "nominal_sum_j_over_sum_j_star": sum(r["front"][i]["nominal"]["J"] for r in rows) / sum_nominal,
            }
            for i, w in enumerate(blends)
        ]
        cells[cell] = {
            "sum_j_star_onset_over_sum_j_star": front[0]["fault_sum_j_over_sum_j_star"],
            "front": front,
            "episodes": rows,
        }
        for p in front:
            print(
                f"{cell}: w {p['blend']:g}: ΣJ/ΣJ* {p['fault_sum_j_over_sum_j_star']:.4f} with the fault, "
                f"{p['nominal_sum_j_over_sum_j_star']:.4f} without, over {len(rows)} episodes",
                flush=True,
            )
    if args.out:
        write_results(args.out, argv, cells=cells)


if __name__ == "__main__":
    main()
