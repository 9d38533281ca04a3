"""Command line of attitude-envs (thin: parses arguments, calls the library).

python train.py demo [--seeds N] [--preset spec-000]   # the README's main command
python train.py reproduce <paper> --out DIR            # paper vs. ours, JSON + markdown
python train.py envs                                   # registered env ids and presets
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def _demo(args: argparse.Namespace) -> int:
    import gymnasium as gym

    import attitude_envs  # noqa: F401  (registers the ids)
    from attitude_envs.evaluation import rollout
    from baselines.base import ZeroPolicy
    from baselines.lqr import LQRPolicy

    env_id = "attitude_envs/ReactionWheel-v0"
    env = gym.make(env_id, preset=args.preset)
    policies = [ZeroPolicy(env), LQRPolicy(env, "zoh"), LQRPolicy(env, "continuous")]
    seeds = list(range(args.seeds))
    print(f"{env_id} preset={args.preset}: rest-to-rest maneuvers, {len(seeds)} seeds, cost J = ∫(xᵀQx + uᵀRu) dt")
    header = (
        f"{'policy':<16}{'J mean':>12}{'J std':>10}{'final err [deg]':>17}{'peak wheel [rpm]':>18}{'s/episode':>11}"
    )
    print(header)
    print("-" * len(header))
    for policy in policies:
        start = time.perf_counter()
        rows = [rollout(env, policy, seed=s) for s in seeds]
        wall = (time.perf_counter() - start) / len(seeds)
        costs = np.array([r["J"] for r in rows])
        err = np.mean([r["final_error_deg"] for r in rows])
        peak = np.max([r["peak_wheel_speed_rad_s"] for r in rows]) * 60 / (2 * np.pi)
        print(f"{policy.name:<16}{costs.mean():>12.2f}{costs.std():>10.2f}{err:>17.3f}{peak:>18.0f}{wall:>11.2f}")
    env.close()
    return 0


def _envs(args: argparse.Namespace) -> int:
    import attitude_envs
    from attitude_envs.presets import PRESETS

    for env_id in attitude_envs.ENV_IDS:
        print(env_id)
    for name, cfg in PRESETS.items():
        print(f"  ReactionWheel-v0 preset {name}: {cfg['description']}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    import importlib
    from pathlib import Path

    from attitude_envs.evaluation.reproduction import markdown_table
    from attitude_envs.reproductions import REPRODUCTIONS

    if args.paper not in REPRODUCTIONS:
        raise ValueError(f"unknown reproduction {args.paper!r}; accepted: {sorted(REPRODUCTIONS)}")
    module, func = REPRODUCTIONS[args.paper].split(":")
    rows = getattr(importlib.import_module(module), func)(Path(args.out), quick=args.quick)
    print(markdown_table(rows))
    print(f"wrote {Path(args.out) / (args.paper + '.json')} and .md")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="attitude-envs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser("demo", help="evaluate the LQR baselines on ReactionWheel-v0 and print a table")
    demo.add_argument("--seeds", type=int, default=5, help="episodes per policy (>= 1)")
    demo.add_argument("--preset", default="spec-000", help="ReactionWheel-v0 preset (spec-000, spec-001)")
    demo.set_defaults(func=_demo)
    rep = sub.add_parser("reproduce", help="reproduce a paper's results: writes DIR/<paper>.json and .md")
    rep.add_argument("paper", help="reproduction id (see attitude_envs.reproductions)")
    rep.add_argument("--out", default="results", help="output directory")
    rep.add_argument("--quick", action="store_true", help="a shortened run (for tests)")
    rep.set_defaults(func=_reproduce)
    envs = sub.add_parser("envs", help="list env ids and presets")
    envs.set_defaults(func=_envs)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["demo", *(argv or [])])
    if getattr(args, "seeds", 1) < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
