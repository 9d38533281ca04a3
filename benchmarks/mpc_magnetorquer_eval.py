"""J / J* of the magnetorquer MPC (:mod:`baselines.mpc_magnetorquer`) on the magnetorquer campaign's cells.

Plays the campaign's episodes (``experiments/campaigns/magnetorquer.yml``: Magnetorquer-v0,
``preset: sadigh-2022``, 300 s, ``integrator_dt_s`` 0.5 s, scenario "slew", faults ``none`` and
``sadigh-eq40``) at the MPC's own control period and divides Σ J by Σ J* of the shipped table
(:mod:`experiments.optimum_table`, keyed by the cell's kwargs at ``control_dt_s`` 1.0).

    python -m benchmarks.mpc_magnetorquer_eval --seeds 0-19 --dt 3.0 --horizon 45 --hold 1000
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the envs)
from attitude_envs.evaluation.rollout import rollout
from baselines.mpc_magnetorquer import MagnetorquerMPCPolicy
from experiments.optimum_table import table_value
from experiments.seeds import SYNTAX, seeds_arg

ENV_ID = "attitude_envs/Magnetorquer-v0"
CELL_KWARGS: dict[str, Any] = {
    "preset": "sadigh-2022",
    "episode_duration_s": 300.0,
    "control_dt_s": 1.0,
    "integrator_dt_s": 0.5,
}
#: Sadigh et al. 2022, eq. 40: effectiveness diag(0.9, 0.7, 0.6) from 50 s
FAULTS: dict[str, list[dict[str, Any]]] = {
    "none": [],
    "sadigh-eq40": [
        {"kind": "loss_of_effectiveness", "target": "actuator", "index": 0, "value": 0.1, "onset_s": 50.0},
        {"kind": "loss_of_effectiveness", "target": "actuator", "index": 1, "value": 0.3, "onset_s": 50.0},
        {"kind": "loss_of_effectiveness", "target": "actuator", "index": 2, "value": 0.4, "onset_s": 50.0},
    ],
}


def cell_kwargs(fault: str) -> dict[str, Any]:
    """The cell's env kwargs as the campaign builds them (faults only when there are some)."""
    kwargs = copy.deepcopy(CELL_KWARGS)
    if FAULTS[fault]:
        kwargs["faults"] = copy.deepcopy(FAULTS[fault])
    return kwargs


def evaluate(fault: str, seeds: list[int], dt_s: float, policy_kwargs: dict[str, Any]) -> dict[str, Any]:
    """Σ J, Σ J*, their ratio and the solve times of the MPC at period ``dt_s`` (s) on ``seeds``."""
    cell = cell_kwargs(fault)
    env = gym.make(ENV_ID, **{**cell, "control_dt_s": dt_s})
    policy = MagnetorquerMPCPolicy(env, **policy_kwargs)
    rows = []
    for seed in seeds:
        start = time.perf_counter()
        n_solves = len(policy.solve_times_s)
        result = rollout(env, policy, seed=seed)
        j_star = table_value(ENV_ID, cell, seed, None)
        rows.append(
            {
                "seed": seed,
                "J": result["J"],
                "J_star": j_star,
                "ratio": result["J"] / j_star if j_star else float("nan"),
                "terminated": result["terminated"],
                "final_error_deg": result["final_error_deg"],
                "wall_s": time.perf_counter() - start,
                "solves": len(policy.solve_times_s) - n_solves,
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    times = np.asarray(policy.solve_times_s)
    sum_j = float(sum(r["J"] for r in rows))
    sum_star = float(sum(r["J_star"] for r in rows))
    return {
        "fault": fault,
        "dt_s": dt_s,
        "policy_kwargs": policy_kwargs,
        "seeds": seeds,
        "sum_J": sum_j,
        "sum_J_star": sum_star,
        "ratio": sum_j / sum_star,
        "median_solve_s": float(np.median(times)),
        "p95_solve_s": float(np.percentile(times, 95)),
        "max_solve_s": float(times.max()),
        "median_solve_fraction_of_period": float(np.median(times)) / dt_s,
        "median_iterations": float(np.median(policy.iterations)),
        "failures": policy.failures,
        "solves": int(times.size),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=seeds_arg, default="0-4", help=SYNTAX)
    parser.add_argument("--faults", default="none,sadigh-eq40")
    parser.add_argument("--dt", type=float, default=3.0, help="the MPC's control period (s)")
    parser.add_argument("--horizon", type=float, default=45.0, help="horizon (s)")
    parser.add_argument("--model-dt", type=float, default=None, help="the model's RK4 sub-step (s)")
    parser.add_argument("--hold", type=float, default=1000.0, help="terminal_hold_s (s)")
    parser.add_argument("--gain", type=float, default=0.5, help="disturbance_gain")
    parser.add_argument("--effectiveness", action="store_true", help="estimate_effectiveness")
    parser.add_argument("--forgetting", type=float, default=0.98)
    parser.add_argument("--max-iter", type=int, default=50)
    parser.add_argument("--out", default=None, help="write the summaries to this JSON file")
    args = parser.parse_args(argv)
    policy_kwargs = {
        "horizon_s": args.horizon,
        "model_integrator_dt_s": args.model_dt,
        "terminal_hold_s": args.hold,
        "disturbance_gain": args.gain,
        "estimate_effectiveness": args.effectiveness,
        "forgetting": args.forgetting,
        "max_iter": args.max_iter,
    }
    summaries = []
    for fault in args.faults.split(","):
        summary = evaluate(fault, args.seeds, args.dt, policy_kwargs)
        summaries.append(summary)
        print("SUMMARY", json.dumps(summary), flush=True)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            json.dump(summaries, fh, indent=2)


if __name__ == "__main__":
    main()
