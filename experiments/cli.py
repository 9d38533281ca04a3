"""Command line of attitude-envs (thin: parses arguments, calls the library).

Installed as ``attitude-envs <cmd>``; ``python train.py <cmd>`` at the repository root is the same:

attitude-envs benchmark --config quick --out DIR     # the README's main command: campaign → report
attitude-envs train --algo ppo --env ID --out DIR    # Stable-Baselines3 training (checkpoints, --resume)
attitude-envs evaluate --env ID --policy lqr --model RUN/final/model.zip --out DIR
attitude-envs demo [--seeds N] [--preset NAME]       # LQR baselines table
attitude-envs reproduce <paper> --out DIR            # paper vs. ours, JSON + markdown
attitude-envs envs                                   # registered env ids and presets
attitude-envs tune-pid [--help]                      # GA-tune PID gains (Ahangarani Farahani et al.)
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

import attitude_envs  # registers the env ids
from agents.ga_tuning import tune_pid_main
from attitude_envs import presets
from attitude_envs.evaluation import rollout
from attitude_envs.scenarios import load_scenario
from baselines.base import ZeroPolicy
from baselines.lqr import LQRPolicy
from experiments.campaign import run_campaign
from experiments.policies import check_policy_name
from experiments.report import leaderboard_markdown, leaderboards, write_campaign_report
from experiments.reproduction import markdown_table
from experiments.reproductions import REPRODUCTIONS
from experiments.sb3.hyperparams import parse_overrides, read_yaml


def _demo(args: argparse.Namespace) -> int:
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
    for env_id in attitude_envs.ENV_IDS:
        print(env_id)
        for p in presets.for_env(env_id):
            default = " (default)" if p.default else ""
            aliases = f" [alias: {', '.join(p.aliases)}]" if p.aliases else ""
            print(f"  preset {p.name}{default}{aliases}: {p.description}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    if args.paper not in REPRODUCTIONS:
        raise ValueError(f"unknown reproduction {args.paper!r}; accepted: {sorted(REPRODUCTIONS)}")
    module, func = REPRODUCTIONS[args.paper].split(":")
    rows = getattr(importlib.import_module(module), func)(Path(args.out), quick=args.quick)
    print(markdown_table(rows))
    print(f"wrote {Path(args.out) / (args.paper + '.json')} and .md")
    return 0


def _yaml_arg(name: str, text: str | None):
    """A command-line YAML/JSON value, or ``@FILE`` to read it from a file."""
    if text is None:
        return None
    if text.startswith("@"):
        return read_yaml(text[1:])
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{name} is malformed YAML: {str(exc).splitlines()[0]}") from exc


def _env_kwargs(args: argparse.Namespace) -> dict:
    kwargs = _yaml_arg("--env-kwargs", args.env_kwargs) or {}
    if not isinstance(kwargs, dict):
        raise ValueError(f"--env-kwargs must be a YAML mapping, got {kwargs!r}")
    faults = _yaml_arg("--faults", args.faults)
    if faults is not None:
        if not isinstance(faults, list):
            raise ValueError(f"--faults must be a YAML list of fault dicts, got {faults!r}")
        kwargs["faults"] = faults
    return kwargs


def _train(args: argparse.Namespace) -> int:
    from experiments.sb3.training import train  # optional: the sb3 extra (stable-baselines3, torch)

    result = train(
        args.algo,
        args.env,
        args.out,
        env_kwargs=_env_kwargs(args),
        seed=args.seed,
        hyperparams_file=args.hyperparams,
        overrides=parse_overrides(args.params),
        total_timesteps=args.timesteps,
        checkpoint_freq=args.checkpoint_freq,
        eval_freq=args.eval_freq,
        eval_episodes=args.eval_episodes,
        resume=args.resume,
        progress_bar=args.progress_bar,
        tensorboard=True if args.tensorboard else None,
        verbose=args.verbose,
    )
    resumed = f" (resumed at {result.resumed_from} steps)" if result.resumed_from is not None else ""
    ev = result.last_eval or {}
    print(f"trained {args.algo} on {args.env}: {result.timesteps} steps{resumed} in {result.wall_time_s:.1f} s")
    print(
        f"eval J = {ev.get('J_mean', float('nan')):.3f} ± {ev.get('J_std', float('nan')):.3f}; model: {result.model_path}"
    )
    return 0


def _policy_specs(args: argparse.Namespace) -> list[dict]:
    specs = []
    for text in args.policy or []:
        name, _, params = text.partition(":")
        check_policy_name(name)
        if name == "sb3":
            raise ValueError("use --model PATH for a saved Stable-Baselines3 model")
        label = re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-")  # e.g. pid:gains:/x/g.json → pid-gains-x-g.json
        specs.append({"name": label, "policy": name, "params": parse_overrides([p for p in params.split(",") if p])})
    for i, path in enumerate(args.model or []):
        specs.append({"name": f"model{i}" if len(args.model) > 1 else "model", "policy": "sb3", "model": path})
    if not specs:
        raise ValueError("evaluate needs at least one --policy NAME[:key:value,...] or --model PATH")
    return specs


def _print_campaign(result, report) -> None:
    print(leaderboard_markdown(leaderboards(result.rows)))
    print(
        f"{result.episodes_run} episodes run, {result.episodes_skipped} already done, {result.wall_time_s:.1f} s on "
        f"{result.executor}; report: {report}"
    )


def _evaluate(args: argparse.Namespace) -> int:
    faults = _yaml_arg("--fault-grid", args.fault_grid) or {"none": []}
    scenarios = _yaml_arg("--scenarios", args.scenarios) or [{"name": "default"}]
    kwargs = _env_kwargs(args)
    if args.scenario:  # a packaged scenario preset: its env, env kwargs and faults (healthy run beside it)
        preset = load_scenario(args.scenario)
        if preset["env"] and args.env == ENV_DEFAULT:
            args.env = preset["env"]
        kwargs = {**preset["env_kwargs"], **kwargs}
        faults = {"healthy": [], preset["name"]: preset["faults"]}
    config = {
        "name": "evaluate",
        "seeds": list(range(args.seed_offset, args.seed_offset + args.seeds)),
        "envs": [{"name": "env", "id": args.env, "kwargs": kwargs, "scenarios": scenarios, "faults": faults}],
        "agents": _policy_specs(args),
        "video": False,
    }
    result = run_campaign(config, args.out, ray_address=args.ray, workers=args.workers, progress=print)
    _print_campaign(result, write_campaign_report(result))
    return 0


def _benchmark(args: argparse.Namespace) -> int:
    result = run_campaign(args.config, args.out, ray_address=args.ray, workers=args.workers, progress=print)
    report = write_campaign_report(result, video=False if args.no_video else None)
    _print_campaign(result, report)
    return 0


ENV_DEFAULT = "attitude_envs/ReactionWheel-v0"


def _add_env_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", default=ENV_DEFAULT, help="registered env id")
    p.add_argument(
        "--env-kwargs", help="env keyword arguments as YAML/JSON (or @FILE), e.g. '{preset: pyramid-4wheel}'"
    )
    p.add_argument("--faults", help="actuator faults as a YAML list (attitude_envs.faults), or @FILE")


def _tune_pid(args: argparse.Namespace) -> int:
    return tune_pid_main(args.rest)


def _add_executor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--ray", metavar="ADDRESS", help="run on Ray: 'local' or a cluster address (optional extra 'ray')")
    p.add_argument("--workers", type=int, help="local process-pool size (default: CPU count; 1 = inline)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="attitude-envs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser("demo", help="evaluate the LQR baselines on ReactionWheel-v0 and print a table")
    demo.add_argument("--seeds", type=int, default=5, help="episodes per policy (>= 1)")
    demo.add_argument(
        "--preset",
        default="pyramid-4wheel",
        help="ReactionWheel-v0 preset (pyramid-4wheel or heravi-2017; aliases spec-000, spec-001)",
    )
    demo.set_defaults(func=_demo)
    rep = sub.add_parser("reproduce", help="reproduce a paper's results: writes DIR/<paper>.json and .md")
    rep.add_argument("paper", help="reproduction id (see experiments.reproductions)")
    rep.add_argument("--out", default="results", help="output directory")
    rep.add_argument("--quick", action="store_true", help="a shortened run (for tests)")
    rep.set_defaults(func=_reproduce)
    envs = sub.add_parser("envs", help="list env ids and presets")
    envs.set_defaults(func=_envs)

    tr = sub.add_parser(
        "train", help="train a Stable-Baselines3 agent (Zoo-format hyperparameters, checkpoints, --resume)"
    )
    tr.add_argument("--algo", required=True, help="ppo, sac, td3, a2c, ddpg, tqc, recurrentppo")
    _add_env_options(tr)
    tr.add_argument("--out", required=True, help="run directory (checkpoints, evaluations.csv, final/model.zip)")
    tr.add_argument("--seed", type=int, default=0, help="training seed (>= 0)")
    tr.add_argument("--timesteps", type=int, help="total env steps (default: n_timesteps of the hyperparameter file)")
    tr.add_argument("--hyperparams", help="Zoo-format YAML (default: experiments/sb3/hyperparams/<algo>.yml)")
    tr.add_argument("--params", nargs="*", help="hyperparameter overrides key:value (Zoo syntax)")
    tr.add_argument("--checkpoint-freq", type=int, default=10_000, help="env steps between checkpoints")
    tr.add_argument("--eval-freq", type=int, default=10_000, help="env steps between evaluations of J")
    tr.add_argument("--eval-episodes", type=int, default=5, help="episodes per evaluation (seeds 10000+i)")
    tr.add_argument("--resume", action="store_true", help="continue a killed run from its last checkpoint")
    tr.add_argument("--progress-bar", action="store_true", help="show a progress bar (needs tqdm and rich)")
    tr.add_argument("--tensorboard", action="store_true", help="TensorBoard logs in DIR/tensorboard (optional package)")
    tr.add_argument("--verbose", type=int, default=0, help="SB3 verbosity (0, 1, 2)")
    tr.set_defaults(func=_train)

    ev = sub.add_parser("evaluate", help="evaluate policies on an env × scenario × fault × seed grid")
    _add_env_options(ev)
    ev.add_argument("--policy", action="append", help="baseline by name with parameters, e.g. lqr:discretization:zoh")
    ev.add_argument("--model", action="append", help="a saved SB3 model (.zip or run directory)")
    ev.add_argument("--scenarios", help="YAML list of {name, options, env_kwargs}, or @FILE")
    ev.add_argument("--fault-grid", help="YAML mapping fault-name → fault list, or @FILE")
    ev.add_argument(
        "--scenario", help="a packaged scenario preset (wheel-failure, stuck-wheel, ...): env, kwargs and faults"
    )
    ev.add_argument("--seeds", type=int, default=5, help="episodes per cell (>= 1)")
    ev.add_argument("--seed-offset", type=int, default=0, help="first episode seed")
    ev.add_argument("--out", required=True, help="output directory (episodes.csv/json, report.md, figures)")
    _add_executor_options(ev)
    ev.set_defaults(func=_evaluate)

    bm = sub.add_parser("benchmark", help="run a campaign (agents × envs × scenarios × faults × seeds) → report")
    bm.add_argument("--config", default="quick", help="quick, full or a campaign YAML path")
    bm.add_argument("--out", required=True, help="output directory (rerun to resume; completed episodes are skipped)")
    bm.add_argument("--no-video", action="store_true", help="skip the episode video even if the campaign asks for it")
    _add_executor_options(bm)
    bm.set_defaults(func=_benchmark)

    tp = sub.add_parser(
        "tune-pid",
        add_help=False,
        help="GA-tune PID gains (Ahangarani Farahani et al.'s pipeline); `tune-pid --help` for its options",
    )
    tp.add_argument("rest", nargs=argparse.REMAINDER)
    tp.set_defaults(func=_tune_pid)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["tune-pid"]:  # its own argument parser (agents.ga_tuning), options passed through
        return _tune_pid(argparse.Namespace(rest=argv[1:]))
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["demo", *(argv or [])])
    if getattr(args, "seeds", 1) < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    try:
        return args.func(args)
    except ValueError as exc:
        message = " ".join(str(exc).split())
        print(f"error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
