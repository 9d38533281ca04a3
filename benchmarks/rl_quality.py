"""Quality of the RL results: SB3 agents vs the LQR baseline on the shared cost J.

    PYTHONPATH=. python benchmarks/rl_quality.py --algo ppo --timesteps 3000000 --env-kwargs '{"action_frame": "body"}'
    PYTHONPATH=. python benchmarks/rl_quality.py --algo ppo --timesteps 3000000 --env-kwargs '{"action_frame": "body"}' \
        --fault-randomized --override '{"gamma": 0.998}'

Trains (or with ``--resume`` continues) one agent on ReactionWheel-v0 (pyramid-4wheel, random
targets within 60°) with the shipped hyperparameters, then evaluates the best snapshot and
the exact-ZOH LQR on the same 20 seeds, nominal and with wheel 0 out from t = 10 s, and
prints J mean per case and the agent/LQR ratio. ``--fault-randomized`` trains with a random
wheel outage at a random onset in every episode. A long run (hours on 2 cores): not a test.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from experiments.campaign import run_campaign
from experiments.training.training import train

ENV = "attitude_envs/ReactionWheel-v0"
OUTAGE = [{"kind": "outage", "target": "actuator", "index": 0, "onset_s": 10.0}]
RANDOM_OUTAGE = [{"kind": "outage", "target": "actuator", "index": "random", "onset_s": {"uniform": [0.0, 60.0]}}]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--algo", default="sac")
    parser.add_argument("--timesteps", type=int, default=300_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fault-randomized", action="store_true")
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--env-kwargs", default="{}", help="JSON dict added to the training and evaluation env kwargs")
    parser.add_argument("--override", default="{}", help="JSON dict of hyperparameter overrides")
    parser.add_argument("--tag", default=None, help="run name (default: algo-nominal|faults-seedN)")
    parser.add_argument("--out", default="results/quality")
    args = parser.parse_args()
    tag = args.tag or f"{args.algo}-{'faults' if args.fault_randomized else 'nominal'}-seed{args.seed}"
    run = Path(args.out) / tag
    extra = json.loads(args.env_kwargs)
    eval_kwargs = {"preset": "pyramid-4wheel", **extra}
    env_kwargs = {**eval_kwargs, **({"faults": RANDOM_OUTAGE} if args.fault_randomized else {})}
    if not (run / "final" / "model.zip").is_file() or args.resume:
        result = train(
            args.algo,
            ENV,
            run,
            env_kwargs=env_kwargs,
            seed=args.seed,
            total_timesteps=args.timesteps,
            overrides=json.loads(args.override) or None,
            eval_env_kwargs=eval_kwargs,
            resume=args.resume,
        )
        print(f"trained {result.timesteps} steps in {result.wall_time_s:.0f} s")
    campaign = {
        "name": f"quality-{tag}",
        "seeds": 20,
        "envs": [
            {
                "name": "rw",
                "id": ENV,
                "kwargs": eval_kwargs,
                "faults": {"none": [], "wheel0-outage-10s": OUTAGE},
            }
        ],
        "agents": [
            {"name": "lqr", "policy": "lqr", "params": {"discretization": "zoh"}},
            {"name": tag, "policy": "sb3", "model": str(run / "best" / "model.zip")},
        ],
    }
    result = run_campaign(campaign, Path(args.out) / f"eval-{tag}")
    for fault in ("none", "wheel0-outage-10s"):
        J = {a: sum(r["J"] for r in result.rows if r["agent"] == a and r["fault"] == fault) / 20 for a in ("lqr", tag)}
        print(f"{fault:>20}: LQR J = {J['lqr']:.2f}, {tag} J = {J[tag]:.2f}, ratio {J[tag] / J['lqr']:.3f}")


if __name__ == "__main__":
    main()
