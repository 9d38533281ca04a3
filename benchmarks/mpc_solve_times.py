"""Solve time of every plant's MPC row, as its campaign runs it: median, 90th percentile and
maximum wall time per decision (ms and % of the MPC's control period), one process on one core.

    python -m benchmarks.mpc_solve_times                      # seed 0 of each plant's nominal cell
    python -m benchmarks.mpc_solve_times --seeds 0-2 --campaigns slosh,wheel --out results.json

Each MPC agent (``policy: mpc`` or ``mpc-ft``) is built from its campaign YAML
(``experiments/campaigns/<name>.yml``: its parameters and decision period) and plays the
campaign's episodes of the first env's first scenario without faults, through the same job
list the campaign runs, reading ``policy_view(info)`` as the campaign's episodes do. Two times per
decision: the policies' own ``solve_times_s`` (the solver call alone) and the whole ``act`` (with
the initial guess, the estimators and, for ``mpc-ft``, the fault detector and any rebuild after
a fault). Needs the ``optimal`` extra (CasADi). Nothing else should run on
the machine while it measures: a second process on a sibling core slows the solves.
"""

from __future__ import annotations

import argparse
import copy
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the envs)
from attitude_envs.info import policy_view
from benchmarks.results_file import write_results
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.spec import load_campaign
from experiments.policies import build_policy
from experiments.seeds import SYNTAX, seeds_arg

CAMPAIGNS = ("wheel", "air-bearing", "magnetorquer", "slosh", "linear")
MPC_POLICIES = ("mpc", "mpc-ft")


def mpc_jobs(name: str, seeds: list[int]) -> list[dict[str, Any]]:
    """The campaign ``name``'s episode jobs of its MPC agents on its first env's first scenario
    without faults, for ``seeds``."""
    campaign = load_campaign(name)
    outside = sorted(set(seeds) - set(campaign.seeds))
    if outside:
        raise ValueError(
            f"seeds {outside} are not seeds of campaign {name!r} ({campaign.seeds[0]}-{campaign.seeds[-1]})"
        )
    others = [a.name for a in campaign.agents if a.spec.get("policy") not in MPC_POLICIES]
    env, scenario = campaign.envs[0], campaign.envs[0].scenarios[0]["name"]
    with tempfile.TemporaryDirectory() as tmp:
        jobs = episode_jobs(campaign, Path(tmp), skip_agents=others)
    return [
        j
        for j in jobs
        if j["key"]["env"] == env.name
        and j["key"]["scenario"] == scenario
        and j["key"]["fault"] == "none"
        and j["key"]["seed"] in seeds
    ]


def measure(job: dict[str, Any]) -> dict[str, Any]:
    """J, the decisions and the solve-time statistics of one episode job."""
    env = gym.make(job["env_id"], **job["env_kwargs"])
    try:
        policy = build_policy(job["policy"], env, name=job["key"]["agent"])
        seed = job["key"]["seed"]
        obs, info = env.reset(seed=seed, options=copy.deepcopy(job["options"]) or None)
        policy.reset(seed)
        total, act_s, start = 0.0, [], time.perf_counter()
        while True:
            t0 = time.perf_counter()
            action = policy.act(obs, policy_view(info))
            act_s.append(time.perf_counter() - t0)
            obs, _, terminated, truncated, info = env.step(action)
            total += float(info["cost"])
            if terminated or truncated:
                break
        wall = time.perf_counter() - start
        times_ms = np.asarray(policy.solve_times_s, dtype=float) * 1e3
        if times_ms.size == 0:
            raise RuntimeError(f"{job['key']['agent']} solved nothing in {job['key']} (every step fell back)")
        act_ms = np.asarray(act_s) * 1e3
        period_ms = float(env.unwrapped.control_dt_s) * 1e3
    finally:
        env.close()
    return {
        **job["key"],
        "env_id": job["env_id"],
        "control_dt_s": period_ms / 1e3,
        "J": total,
        "decisions": len(act_s),
        "solves": int(times_ms.size),
        "failures": int(getattr(policy, "failures", 0)),
        "fallbacks": getattr(policy, "fallbacks", None),  # the slosh MPC's SQP solves redone by IPOPT
        "episode_wall_s": wall,
        "solve_ms": {
            "median": float(np.median(times_ms)),
            "p90": float(np.percentile(times_ms, 90)),
            "max": float(times_ms.max()),
        },
        "act_ms": {"median": float(np.median(act_ms)), "max": float(act_ms.max())},
        "solve_percent_of_period": {
            "median": float(100 * np.median(times_ms) / period_ms),
            "max": float(100 * times_ms.max() / period_ms),
        },
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", default=",".join(CAMPAIGNS), help="comma-separated campaign names")
    parser.add_argument("--seeds", type=seeds_arg, default="0-0", help=SYNTAX)
    parser.add_argument("--out", default=None, help="write the rows as JSON here")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    rows = []
    for name in args.campaigns.split(","):
        for job in mpc_jobs(name, args.seeds):
            row = {"campaign": name, **measure(job)}
            rows.append(row)
            s, p = row["solve_ms"], row["solve_percent_of_period"]
            print(
                f"{name} {row['agent']} seed {row['seed']}: dt {row['control_dt_s']} s, {row['solves']} solves in "
                f"{row['decisions']} decisions, median {s['median']:.1f} ms ({p['median']:.1f} %), p90 {s['p90']:.1f} ms, "
                f"max {s['max']:.1f} ms ({p['max']:.1f} %), act median {row['act_ms']['median']:.1f} ms, "
                f"failures {row['failures']}, fallbacks {row['fallbacks']}, J {row['J']:.6g}",
                flush=True,
            )
    if args.out:
        write_results(args.out, argv, rows=rows)


if __name__ == "__main__":
    main()
