"""Σ J / Σ J* and solve times of the MPC baselines of FuelSlosh-v0 and LinearSystem-v0 on
their campaign cells (J* from the shipped table, keyed by the CELL's kwargs, not the MPC's
control period).

    python -m benchmarks.mpc_plants_eval slosh --dt 0.1 --horizon 5 --seeds 0-4 --fault none
    python -m benchmarks.mpc_plants_eval slosh --fault actuator-faults-50s
    python -m benchmarks.mpc_plants_eval linear --seeds 0-0

Prints one line per episode (J in the env's cost units, J*, ratio, wall s) and a summary
(Σ J / Σ J*, median and max solve time in ms, failed solves).
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the envs)
from experiments.optimum_table import table_value
from experiments.seeds import SYNTAX, seeds_arg

SLOSH_ID = "attitude_envs/FuelSlosh-v0"
SLOSH_CELL = {"preset": "navabi-fill-i", "episode_duration_s": 100.0, "randomize_initial_state": True}
SLOSH_FAULTS = {
    "none": [],
    "actuator-faults-50s": [
        {"kind": "loss_of_effectiveness", "target": "actuator", "index": 0, "value": 0.5, "onset_s": 50.0},
        {"kind": "bias", "target": "actuator", "index": 1, "value": 200.0, "onset_s": 50.0},
    ],
}
LINEAR_ID = "attitude_envs/LinearSystem-v0"
LINEAR_CELL = {"preset": "heravi-2017", "episode_steps": 40000}


def run_episode(env, policy, seed: int) -> float:
    """J (the env's summed cost) of one episode of ``policy`` from ``reset(seed)``."""
    obs, info = env.reset(seed=seed)
    policy.reset(seed)
    total = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
        total -= float(reward)
        if terminated or truncated:
            return total


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("plant", choices=("slosh", "linear"))
    parser.add_argument("--seeds", type=seeds_arg, default="0-4", help=SYNTAX)
    parser.add_argument("--dt", type=float, default=None, help="the MPC's control period, s (slosh)")
    parser.add_argument("--horizon", type=int, default=None)
    parser.add_argument("--fault", default="none", choices=sorted(SLOSH_FAULTS))
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    if args.plant == "slosh":
        from baselines.mpc_slosh import SloshMPCPolicy

        env_id, cell = SLOSH_ID, dict(SLOSH_CELL)
        if SLOSH_FAULTS[args.fault]:
            cell["faults"] = SLOSH_FAULTS[args.fault]
        play = dict(cell) if args.dt is None else {**cell, "control_dt_s": args.dt}
        env = gym.make(env_id, **play)
        policy = SloshMPCPolicy(env, **({} if args.horizon is None else {"horizon_steps": args.horizon}))
    else:
        from baselines.mpc_linear import LinearMPCPolicy

        env_id, cell = LINEAR_ID, dict(LINEAR_CELL)
        env = gym.make(env_id, **cell)
        policy = LinearMPCPolicy(env, **({} if args.horizon is None else {"horizon_steps": args.horizon}))
    sum_j = sum_j_star = 0.0
    for seed in args.seeds:
        t0 = time.perf_counter()
        j = run_episode(env, policy, seed)
        j_star = table_value(env_id, cell, seed, None)
        ratio = float("nan") if j_star is None else j / j_star
        print(f"seed {seed}: J={j:.6g} J*={j_star} J/J*={ratio:.4f} wall={time.perf_counter() - t0:.1f}s", flush=True)
        if j_star is not None:
            sum_j, sum_j_star = sum_j + j, sum_j_star + j_star
    times = np.asarray(policy.solve_times_s)
    print(
        f"{args.plant} fault={args.fault} dt={env.unwrapped.control_dt_s if args.plant == 'slosh' else ''} "
        f"SumJ/SumJ*={sum_j / sum_j_star if sum_j_star else float('nan'):.4f} "
        f"solve median={np.median(times) * 1e3:.3f} ms max={times.max() * 1e3:.3f} ms "
        f"failures={policy.failures}/{len(times)}"
    )


if __name__ == "__main__":
    main()
