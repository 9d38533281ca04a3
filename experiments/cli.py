"""Command line of attitude-envs (thin: parses arguments, calls the library).

Installed as ``attitude-envs <cmd>``; ``python train.py <cmd>`` at the repository root is the same:

attitude-envs benchmark --config quick --out DIR     # the README's main command: campaign → report
attitude-envs train --algo ppo --env ID --out DIR    # Stable-Baselines3 training (checkpoints, --resume)
attitude-envs evaluate --env ID --policy lqr --model RUN/final/model.zip --out DIR
attitude-envs demo [--seeds 5] [--preset NAME]       # LQR baselines table
attitude-envs reproduce <paper> --out DIR            # paper vs. ours, JSON + markdown
attitude-envs envs                                   # registered env ids and presets
attitude-envs tune-pid --env ID --out FILE            # GA-tune PID gains (Ahangarani Farahani et al.)
attitude-envs optimum --env ID --seeds 0-2 --out DIR  # the oracle optimum J* per seed (casadi)
attitude-envs optimum --write-table                  # regenerate the shipped J* table of the standard campaigns
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import re
import shlex
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

import attitude_envs  # registers the env ids
from attitude_envs import presets
from attitude_envs.evaluation import rollout
from attitude_envs.files import read_json
from attitude_envs.registration import LEARNING_TASKS, base_version, quiet_version_warnings, task_defaults
from attitude_envs.scenarios import list_scenarios, load_scenario
from baselines.base import ZeroPolicy
from baselines.lqr import LQRPolicy
from experiments import optimum_table, pid_tuning
from experiments.campaign import (
    ALL_CAMPAIGNS,
    PRESETS,
    SELECT,
    episode_jobs,
    load_campaign,
    make_executor,
    prepare_campaign,
    run_campaign,
)
from experiments.policies import POLICIES, check_policy_env, check_policy_name
from experiments.progress import Heartbeat
from experiments.reproduction import markdown_table
from experiments.reproductions import REPRODUCTIONS
from experiments.seeds import LIMITS, MAX_SEED, SYNTAX, seeds_arg
from experiments.training.algorithm import ALGORITHMS, BACKENDS
from experiments.training.hyperparams import load_yaml, parse_overrides, read_yaml

#: every registered id of the suite: the papers' problems (-v0) and the learning tasks (-v1)
ALL_IDS = (*attitude_envs.ENV_IDS, *LEARNING_TASKS)


def _demo(args: argparse.Namespace) -> int:
    env_id = "attitude_envs/ReactionWheel-v0"
    env = gym.make(env_id, preset=args.preset)
    policies = [ZeroPolicy(env), LQRPolicy(env, "zoh"), LQRPolicy(env, "continuous")]
    seeds = args.seeds
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
        v1 = next(k for k, (v0, _) in LEARNING_TASKS.items() if v0 == env_id)
        task = ", ".join(f"{k}={v!r}" for k, v in task_defaults(v1).items())
        print(f"  learning task {v1}: {task}")
        for p in presets.for_env(env_id):
            default = " (default)" if p.default else ""
            aliases = f" [alias: {', '.join(p.aliases)}]" if p.aliases else ""
            print(f"  preset {p.name}{default}{aliases}: {p.description}")
    return 0


#: typical wall time of each reproduction, s (full, quick), on this project's 2-core machines
REPRODUCTION_TIME_S = {
    "feedback-linearization": (60, 30),
    "fuel-slosh": (120, 15),
    "q-learning-lqr": (120, 10),
    "ga-pid": (900, 5),
    "fault-tolerant-smc": (240, 10),
}


def check_out_dir(out: str | Path, option: str = "--out") -> Path:
    """``out`` as a directory to write into: ``ValueError`` (before any work) when it, or a
    folder above it, is an existing file, or when it cannot be created or written. A folder
    this check creates to find out is removed again (the command creates it when it writes)."""
    if not str(out).strip():
        raise ValueError(
            f"{option} must name a directory, got {str(out)!r} (an empty path would write into the current directory)"
        )
    path = Path(out)
    for p in (path, *path.parents):
        if p.exists() and not p.is_dir():
            where = "is" if p == path else f"cannot be created: {str(p)!r} is"
            raise ValueError(f"{option} {str(path)!r} {where} an existing file; {option} names a directory")
    missing = [p for p in (path, *path.parents) if not p.exists()]
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".attitude-envs-write-probe-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise ValueError(f"{option} {str(path)!r} cannot be created or written: {exc.strerror or exc}") from None
    finally:
        for p in missing:  # deepest first
            with contextlib.suppress(OSError):
                p.rmdir()
    return path


def _reproduce(args: argparse.Namespace) -> int:
    if args.paper not in REPRODUCTIONS:
        raise ValueError(f"unknown reproduction {args.paper!r}; accepted: {sorted(REPRODUCTIONS)}")
    out = check_out_dir(args.out)  # before the work, not after it
    module, func = REPRODUCTIONS[args.paper].split(":")
    typical = REPRODUCTION_TIME_S.get(args.paper, (None, None))[1 if args.quick else 0]
    with Heartbeat(f"reproduce {args.paper}{' --quick' if args.quick else ''}", typical):
        rows = getattr(importlib.import_module(module), func)(out, quick=args.quick)
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
        return load_yaml(text)
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
    check_out_dir(args.out)
    from experiments.training.training import train  # optional: the sb3 extra (stable-baselines3, torch)

    if args.progress_bar:
        try:
            import rich  # noqa: F401  (optional: SB3's progress bar needs it; in the sb3 extra)
        except ImportError as exc:
            raise ValueError("--progress-bar needs the package 'rich' (pip install 'attitude-envs[sb3]')") from exc
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
        backend=args.backend,
        progress_bar=args.progress_bar,
        progress=not args.quiet,
        tensorboard=True if args.tensorboard else None,
        verbose=args.verbose,
    )
    if result.already_complete:
        print(f"run already complete at {result.timesteps} steps; model: {result.model_path}")
        return 0
    resumed = f" (resumed at {result.resumed_from} steps)" if result.resumed_from is not None else ""
    ev = result.last_eval or {}
    backend = read_json(Path(args.out) / "config.json", "the run's config")["backend"]
    print(
        f"trained {args.algo} ({backend}) on {args.env}: {result.timesteps} steps{resumed} in {result.wall_time_s:.1f} s"
    )
    print(
        f"eval J = {ev.get('J_mean', float('nan')):.3f} ± {ev.get('J_std', float('nan')):.3f}; model: {result.model_path}"
    )
    best = Path(args.out) / "best" / "best.json"
    if best.is_file():  # what `evaluate --model RUN` and campaigns load by default (--select best)
        b = read_json(best, "the best snapshot's record")
        print(
            f"best snapshot (evaluated by default): {best.parent / 'model.zip'}, eval J = {b['J_mean']:.3f} at {b['timesteps']} steps"
        )
    return 0


def _policy_specs(args: argparse.Namespace) -> list[dict]:
    specs = []
    for text in args.policy or []:
        name, _, params = text.partition(":")
        check_policy_name(name)
        check_policy_env(name, args.env)
        if name == "sb3":
            raise ValueError("use --model PATH for a saved Stable-Baselines3 model")
        label = re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-")  # e.g. pid:gains:/x/g.json → pid-gains-x-g.json
        specs.append({"name": label, "policy": name, "params": parse_overrides([p for p in params.split(",") if p])})
    models = [_model_snapshot(path, args.select) for path in args.model or []]
    labels = [_algo_label(m) for m in models]
    for i, (model, label) in enumerate(zip(models, labels, strict=True)):
        if labels.count(label) > 1:  # the same algorithm twice: ppo-1, ppo-2
            label = f"{label}-{labels[:i].count(label) + 1}"
        specs.append({"name": label, "policy": "sb3", "model": str(model)})
    if not specs:
        raise ValueError("evaluate needs at least one --policy NAME[:key:value,...] or --model PATH")
    return specs


def _model_snapshot(path: str, select: str) -> Path:
    """The model file ``evaluate --model PATH`` loads, chosen like a campaign chooses a trained
    agent's snapshot: a run directory gives ``best/model.zip`` (``--select best``, the default,
    when the run saved one) or ``final/model.zip``; a snapshot folder or a ``.zip`` is taken as is."""
    p = Path(path)
    if p.is_file():
        return p
    if not p.is_dir():
        raise ValueError(f"--model {path!r} does not exist (a run directory, a snapshot folder or a model .zip)")
    if (p / "model.zip").is_file():
        if select is not None and p.name in SELECT and p.name != select:  # RUN/best with --select final
            raise ValueError(
                f"--select {select} chooses a snapshot of a run directory, but --model {path!r} is the run's "
                f"{p.name!r} snapshot itself: pass the run directory {str(p.parent)!r} (or {str(p.parent / select)!r})"
            )
        return p / "model.zip"
    select = select or "best"
    best, final = p / "best" / "model.zip", p / "final" / "model.zip"
    if select == "best" and best.is_file():
        return best
    if final.is_file():
        return final
    if best.is_file():
        return best
    raise ValueError(f"--model {path!r} holds no final/model.zip or best/model.zip (is the run finished?)")


def _check_models(env_id: str, env_kwargs: dict, models: list[str]) -> None:
    """Each saved model fits the env (its env id and spaces: :func:`~experiments.training.training.load_trained`),
    checked here before any episode runs, not in a worker."""
    if not models:
        return
    from experiments.training.training import load_trained  # optional: the sb3 extra

    env = gym.make(env_id, **env_kwargs)
    try:
        for model in models:
            load_trained(model, env)
    finally:
        env.close()


def _algo_label(model: Path) -> str:
    """The agent's name in the tables: the run's algorithm (``config.json``; ``-sbx`` / ``-jax``
    appended for a model of those backends), else ``sb3``."""
    for config in (model.parent / "config.json", model.parent.parent / "config.json"):
        if config.is_file():
            try:
                saved = json.loads(config.read_text(encoding="utf-8"))
                backend = saved.get("backend", "sb3")
                return str(saved["algo"]) + (f"-{backend}" if backend in ("sbx", "jax") else "")
            except (ValueError, KeyError):
                break
    return "sb3"


#: a campaign with more leaderboards than this prints one line per leaderboard, not the tables
FULL_BOARDS = 2


def _print_campaign(result, report) -> None:
    """The leaderboards of a small campaign (``evaluate``: one cell), else one line per
    leaderboard (its best agent, J and J / J*) and where the tables are."""
    # scipy.stats: not at start-up (see _evaluate)
    from experiments.report.leaderboards import campaign_thresholds, leaderboards
    from experiments.report.markdown import leaderboard_markdown

    boards = leaderboards(result.rows, campaign_thresholds(result.campaign))
    if len(boards) <= FULL_BOARDS:
        print(leaderboard_markdown(boards, result.campaign.agent_notes))
    else:
        print(f"{len(boards)} leaderboards (best agent by mean J; every agent, CIs and figures in {report}):")
        for (env, scenario, fault), board in boards.items():
            best = next((e for e in board if not e.get("oracle")), None)
            if best is None:
                continue
            ratio = best.get("J_over_J_star", float("nan"))
            vs = f", J/J* {ratio:.3f}" if np.isfinite(ratio) else ""
            print(f"  {env}/{scenario}/{fault}: {best['agent']}, J {best['J_mean']:.4g}{vs}")
    print(
        f"{result.episodes_run} episodes run, {result.episodes_skipped} already done, {result.wall_time_s:.1f} s on "
        f"{result.executor}; report: {report}"
    )


def _evaluate(args: argparse.Namespace) -> int:
    # imported by the commands that write a report: it imports scipy.stats (~1 s of CPU at start-up,
    # spent by every `train` run before, each rerun of a killed run included)
    from experiments.report.writing import write_campaign_report

    check_out_dir(args.out)
    faults = _yaml_arg("--fault-grid", args.fault_grid) or {"none": []}
    scenarios = _yaml_arg("--scenarios", args.scenarios) or [{"name": "default"}]
    kwargs = _env_kwargs(args)
    if args.scenario:  # a packaged scenario preset: its env, env kwargs and faults (healthy run beside it)
        preset = load_scenario(args.scenario)
        if preset["env"] and args.env == ENV_DEFAULT:
            args.env = preset["env"]
        elif preset["env"] and base_version(args.env) != base_version(preset["env"]):
            fits = [n for n in list_scenarios() if load_scenario(n)["env"] in (None, base_version(args.env))]
            raise ValueError(
                f"--scenario {args.scenario} is a scenario of {preset['env']}, not of --env {args.env}: leave --env "
                f"out, or pick a scenario of {base_version(args.env)}: {', '.join(fits) or 'none is packaged'}"
            )
        kwargs = {**preset["env_kwargs"], **kwargs}
        faults = {"healthy": [], preset["name"]: preset["faults"]}
    agents = _policy_specs(args)
    _check_models(args.env, kwargs, [a["model"] for a in agents if a["policy"] == "sb3"])
    seeds = [args.seed_offset + s for s in args.seeds]
    if seeds and max(seeds) > MAX_SEED:
        raise ValueError(f"--seed-offset {args.seed_offset} puts seed {max(seeds)} above {MAX_SEED}, the largest seed")
    cell = {"name": "env", "id": args.env, "kwargs": kwargs, "scenarios": scenarios, "faults": faults}
    if args.env in LEARNING_TASKS:  # a learning task plays its -v0 cell's episodes, scored on that cell's J*
        cell, note = learning_task_cell(args.env, kwargs, faults, scenarios if args.scenarios else None)
        agents = [{**a, "env_id": args.env} for a in agents]
        print(note)
    config = {
        "name": "evaluate",
        "seeds": seeds,
        "envs": [cell],
        "agents": agents,
        "video": False,
        "optimum": {"solve": not args.no_solve},
    }
    result = run_campaign(config, args.out, ray_address=args.ray, workers=args.jobs, progress=print)
    _print_campaign(result, write_campaign_report(result, command=shlex.join(["attitude-envs", *args.argv])))
    return 0


def _same_task(env_id: str, a: dict, b: dict) -> bool:
    """Whether keyword sets ``a`` and ``b`` make the same ``env_id`` env, as far as the keywords
    tell: equal once the default preset and the learning task's own defaults are left out."""
    from experiments.jsonable import json_ready

    default_preset = next((p.name for p in presets.for_env(base_version(env_id)) if p.default), None)
    defaults = task_defaults(env_id)

    def plain(kw: dict) -> dict:
        return {
            k: v
            for k, v in json_ready(kw).items()
            if not (k == "preset" and v == default_preset) and not (k in defaults and json_ready(defaults[k]) == v)
        }

    return plain(a) == plain(b)


def learning_task_cell(env_id: str, kwargs: dict, faults: dict, scenarios: list | None) -> tuple[dict, str]:
    """The ``-v0`` campaign cell a ``-v1`` evaluation plays (every agent on ``env_id``'s task,
    as a campaign's learned agents) and a line saying which: the cell of the plant campaign
    (``--config wheel|air-bearing|…``) whose learned agents train on these ``kwargs`` and play
    these faults, when there is one (its J* are in the shipped table: ``evaluate`` then gives the
    campaign page's J / J* on the same seeds), else the ``-v0`` env with ``env_id``'s
    episode keywords (its task keywords left out; J* solved unless ``--no-solve``).
    ``scenarios``: the evaluation's (None: the campaign cell's)."""
    from experiments.campaign.spec import task_keywords
    from experiments.jsonable import json_ready

    v0 = base_version(env_id)
    task = task_keywords(v0)
    user = {k: v for k, v in kwargs.items() if k != "faults"}
    user_faults = json_ready(kwargs.get("faults") or [])
    if faults == {"none": []}:
        for name in ALL_CAMPAIGNS:
            for cell in load_campaign(name).envs:
                played = {k: v for k, v in cell.kwargs.items() if k not in task}
                if cell.id != v0 or not _same_task(env_id, played, user):
                    continue
                for fault, entries in cell.faults.items():
                    if json_ready(entries) == user_faults:
                        spec = {
                            "name": cell.name,
                            "id": v0,
                            "kwargs": dict(cell.kwargs),
                            "scenarios": cell.scenarios if scenarios is None else scenarios,
                            "faults": {fault: entries},
                        }
                        return spec, (
                            f"{env_id} plays the {name} campaign's cell {cell.name}/{fault} ({v0} {cell.kwargs}): "
                            "J / J* against that cell's J*, as on its campaign page"
                        )
    cell_kwargs = {k: v for k, v in {**task_defaults(env_id), **kwargs}.items() if k not in task}
    spec = {
        "name": "env",
        "id": v0,
        "kwargs": cell_kwargs,
        "scenarios": scenarios or [{"name": "default"}],
        "faults": faults,
    }
    return spec, (
        f"{env_id} plays the episodes of {v0} {cell_kwargs} (no plant campaign's cell has these keywords and "
        "faults): J / J* against that cell's J*"
    )


def _benchmark(args: argparse.Namespace) -> int:
    from experiments.report.writing import write_campaign_index, write_campaign_report  # see _evaluate

    check_out_dir(args.out)
    names = ALL_CAMPAIGNS if args.config == "all" else (args.config,)
    outs = [Path(args.out) / Path(name).stem for name in names] if args.config == "all" else [Path(args.out)]
    for out in outs:
        check_out_dir(out)
    if args.config == "all":  # every campaign checked before the first one runs for hours
        if (Path(args.out) / "campaign.json").is_file():
            raise ValueError(
                f"--out {args.out!r} holds a single campaign's results; --config all needs its own directory"
            )
        for config, out in zip(names, outs, strict=True):
            prepare_campaign(config, out, args.backend)
    results = []
    for config, out in zip(names, outs, strict=True):
        if len(outs) > 1:
            print(f"== campaign {config} → {out}")
        result = run_campaign(
            config, out, ray_address=args.ray, workers=args.jobs, progress=print, backend=args.backend
        )
        report = write_campaign_report(result, video=False if args.no_video else None)
        _print_campaign(result, report)
        results.append((Path(config).stem, result))
    if len(outs) > 1:
        index = write_campaign_index(Path(args.out), results)
        print(f"all campaigns: {index}")
    return 0


ENV_DEFAULT = "attitude_envs/ReactionWheel-v0"


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``error: argument --seeds: ...``,
    exit status 2) that names the subcommand's ``--help``, not the whole usage text."""

    def error(self, message: str):
        print(f"error: {message} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(2)


def int_at_least(low: int, high: int | None = None):
    """An argparse ``type``: an integer in [low, high] (high: no bound when None)."""
    accepted = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {accepted}, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"must be {accepted}, got {value}")
        return value

    parse.__name__ = accepted  # argparse names the type in some messages
    return parse


def _add_env_options(p: argparse.ArgumentParser, default: str = ENV_DEFAULT, ids: tuple[str, ...] = ALL_IDS) -> None:
    p.add_argument("--env", default=default, help=f"registered env id: {', '.join(ids)}")
    p.add_argument(
        "--env-kwargs", help="env keyword arguments as YAML/JSON (or @FILE), e.g. '{preset: pyramid-4wheel}'"
    )
    p.add_argument("--faults", help="actuator faults as a YAML list (attitude_envs.faults), or @FILE")


def _search_options(args: argparse.Namespace) -> dict:
    """The keywords both hyperparameter searches (optuna's and the population's) take from ``tune``."""
    return {
        "env_kwargs": _env_kwargs(args),
        "n_trials": args.trials,
        "timesteps": args.timesteps,
        "n_evaluations": args.evaluations,
        "eval_episodes": args.eval_episodes,
        "overrides": parse_overrides(args.params),
        "seed": args.seed,
        "sampler_seed": args.sampler_seed,
    }


def _tune(args: argparse.Namespace) -> int:
    if args.backend == "jax":  # a population search with the fused JAX trainer (no optuna)
        return _tune_population(args)
    if args.shape_groups != 1:
        raise ValueError("--shape-groups is the population search's (--backend jax)")
    check_out_dir(args.out)
    try:  # optional: the tune extra (optuna) and the sb3 extra
        import optuna  # noqa: F401

        from experiments.training.tuning import tune
    except ImportError as exc:
        raise ValueError(
            f"tune needs the package {exc.name or 'optuna'!r}: pip install -c constraints.txt 'attitude-envs[tune,sb3]'"
        ) from None

    summary = tune(args.algo, args.env, args.out, **_search_options(args), backend=args.backend, jobs=args.jobs)
    print(
        f"tuned {args.algo} on {args.env}: {summary['n_complete']} trials complete, {summary['n_pruned']} pruned; "
        f"trials: {Path(args.out) / 'trials.csv'}"
    )
    if summary["best_value"] is not None:
        print(
            f"best eval J = {summary['best_value']:.6g} (trial {summary['best_trial']}): {Path(args.out) / 'best.yml'}"
        )
    return 0


def _tune_population(args: argparse.Namespace) -> int:
    from experiments.training.jax_tuning import tune_population  # optional: the jax and sb3 extras

    if args.jobs not in (None, 1):
        raise ValueError("--jobs: the population search (--backend jax) trains every setting in one process")
    check_out_dir(args.out)
    summary = tune_population(args.algo, args.env, args.out, **_search_options(args), shape_groups=args.shape_groups)
    groups = summary["groups"]
    print(
        f"tuned {args.algo} (jax) on {args.env}: {summary['n_complete']} of {args.trials} settings in "
        f"{len(groups)} compiled program(s) ({sum(g['compile_s'] for g in groups):.1f} s compiling, "
        f"{sum(g['train_s'] for g in groups):.1f} s training); trials: {Path(args.out) / 'trials.csv'}"
    )
    if summary["best_value"] is not None:
        print(
            f"best eval J = {summary['best_value']:.6g} (setting {summary['best_trial']}): {Path(args.out) / 'best.yml'}"
        )
    return 0


def _tune_pid(args: argparse.Namespace) -> int:
    pid_tuning.check_env(args.env)
    if not str(args.out).strip():
        raise ValueError("--out must name the gains file to write, got ''")
    check_out_dir(Path(args.out).parent)
    out = pid_tuning.tune_pid(args, _env_kwargs(args), args.jobs or 2)
    print(f"wrote {out} ({args.mode} gains, objective {args.objective})")
    return 0


def _table_specs(cells: list[str]) -> list[dict]:
    """J* specs of campaign cells ``NAME[:ENV,...[:FAULT,...]]`` (NAME: a preset or a campaign
    file; all envs and faults when not named)."""
    specs: dict[str, dict] = {}
    for item in cells:
        name, _, rest = item.partition(":")
        only_envs, _, only_faults = rest.partition(":")
        if name not in PRESETS and not Path(name).is_file():
            raise ValueError(
                f"--campaign {item!r}: NAME must be one of {list(PRESETS)} or a campaign YAML file, got {name!r}"
            )
        campaign = load_campaign(name)
        envs = {e.name for e in campaign.envs}
        faults = {f for e in campaign.envs for f in e.faults}
        wanted = set(only_envs.split(",")) if only_envs else envs
        wanted_faults = set(only_faults.split(",")) if only_faults else faults
        if wanted - envs or wanted_faults - faults:
            raise ValueError(
                f"--campaign {item!r}: unknown env(s) or fault(s) {sorted((wanted - envs) | (wanted_faults - faults))}; "
                f"envs: {sorted(envs)}, faults: {sorted(faults)}"
            )
        jobs = [
            j
            for j in episode_jobs(campaign, Path("unused"))
            if j["key"]["env"] in wanted and j["key"]["fault"] in wanted_faults
        ]
        for spec in optimum_table.episode_specs(jobs, label=campaign.name):
            if spec["hash"] in specs:
                specs[spec["hash"]]["labels"] += [c for c in spec["labels"] if c not in specs[spec["hash"]]["labels"]]
            else:
                specs[spec["hash"]] = spec
    return list(specs.values())


def _write_table(args: argparse.Namespace) -> int:
    cells = args.campaign or list(optimum_table.SHIPPED)
    if args.table and args.out is not None:
        raise ValueError("--table FILE and --out DIR both name where --write-table writes: give one")
    if args.out is not None:
        path = check_out_dir(args.out) / optimum_table.TABLE_FILE
    else:
        path = Path(args.table) if args.table else optimum_table.shipped_table_path()
        check_out_dir(path.parent, "--table")
    start = time.perf_counter()
    specs = _table_specs(cells)
    print(f"J* table ({optimum_table.COMMAND}): {len(specs)} episode key(s) of {', '.join(cells)} → {path}")
    executor = make_executor(None, args.jobs)
    try:
        keep = optimum_table.reusable_entries(path) if args.keep_table else None
        path, failed = optimum_table.write_table(
            specs, path, executor, cache=not args.no_cache, progress=print, keep=keep, keep_others=args.keep_table
        )
    finally:
        executor.close()
    data = json.loads(path.read_text())
    print(f"wrote {path}: {len(data['entries'])} entries ({time.perf_counter() - start:.0f} s)")
    for spec in failed:
        print(f"left out (no converged solve): {spec['labels'][0]}", file=sys.stderr)
    return 1 if failed else 0


def _optimum(args: argparse.Namespace) -> int:
    if args.write_table or args.campaign or args.table or args.keep_table:
        if not args.write_table:
            raise ValueError("--campaign, --table and --keep-table go with --write-table")
        return _write_table(args)
    if args.out is None:
        raise ValueError("optimum needs --out DIR (or --write-table)")
    out = check_out_dir(args.out)
    seeds = args.seeds
    kwargs = _env_kwargs(args)
    if args.max_iter < 1:
        raise ValueError(f"--max-iter must be >= 1, got {args.max_iter}")
    try:
        from experiments import optimum  # optional: the 'optimal' extra (casadi)
    except ImportError as exc:
        raise ValueError(str(exc)) from exc
    optimum.check_env(args.env)
    out.mkdir(parents=True, exist_ok=True)
    warm = None if args.warm_start == "none" else args.warm_start
    print(f"J* of {args.env} (oracle: the solver knows the fault schedule), seeds {seeds}")
    results = optimum.solve_episodes(
        args.env,
        kwargs,
        seeds,
        progress=print,
        warm_start=warm,
        max_iter=args.max_iter,
        cache=not args.no_cache,
        jit=args.jit,
    )
    path = optimum.write_results(out, results)
    print(optimum.markdown_table(results))
    print(f"wrote {path} and optimum.md")
    return 0


def _add_jobs_option(p: argparse.ArgumentParser, help: str, default: int | None = None) -> None:
    """``--jobs``/``-j``, the one name of a command's process count (``--workers``: its old name, kept)."""
    p.add_argument("--jobs", "-j", type=int_at_least(1), default=default, help=help)
    p.add_argument("--workers", dest="jobs", type=int_at_least(1), help=argparse.SUPPRESS)


def _add_executor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--ray", metavar="ADDRESS", help="run on Ray: 'local' or a cluster address (optional extra 'ray')")
    _add_jobs_option(p, "local process-pool size (>= 1; default: CPU count; 1 = inline)")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineErrorParser(prog="attitude-envs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser("demo", help="evaluate the LQR baselines on ReactionWheel-v0 and print a table")
    demo.add_argument("--seeds", type=seeds_arg, default="5", help=f"episode seeds: {SYNTAX} (default 5)")
    demo.add_argument(
        "--preset",
        default="pyramid-4wheel",
        help="ReactionWheel-v0 preset (pyramid-4wheel or heravi-2017)",
    )
    demo.set_defaults(func=_demo)
    rep = sub.add_parser(
        "reproduce",
        help="reproduce a paper's results: writes DIR/<paper>.json and .md",
        description=f"Reproduce a paper's results. Reproduction ids: {', '.join(sorted(REPRODUCTIONS))}.",
    )
    rep.add_argument("paper", metavar="ID", help=f"reproduction id: {', '.join(sorted(REPRODUCTIONS))}")
    rep.add_argument("--out", default="results", help="output directory")
    rep.add_argument("--quick", action="store_true", help="a shortened run (for tests)")
    rep.set_defaults(func=_reproduce)
    envs = sub.add_parser("envs", help="list env ids and presets")
    envs.set_defaults(func=_envs)

    tr = sub.add_parser(
        "train", help="train a Stable-Baselines3 agent (Zoo-format hyperparameters, checkpoints, --resume)"
    )
    tr.add_argument("--algo", required=True, help=f"algorithm: {', '.join(ALGORITHMS)}")
    _add_env_options(tr)
    tr.add_argument("--out", required=True, help="run directory (checkpoints, evaluations.csv, final/model.zip)")
    tr.add_argument("--seed", type=int_at_least(0), default=0, help="training seed (>= 0)")
    tr.add_argument(
        "--timesteps", type=int_at_least(1), help="total env steps (default: n_timesteps of the hyperparameter file)"
    )
    tr.add_argument("--hyperparams", help="Zoo-format YAML (default: experiments/training/hyperparams/<algo>.yml)")
    tr.add_argument("--params", nargs="*", help="hyperparameter overrides key:value (Zoo syntax)")
    tr.add_argument(
        "--backend",
        choices=BACKENDS,
        help="sb3 (PyTorch), sbx (JAX: pip install 'attitude-envs[sbx]') or jax (PPO: the fused JAX trainer on the "
        "env's JAX plant, pip install 'attitude-envs[jax]'); default: the hyperparameter entry's backend, else sb3",
    )
    tr.add_argument("--checkpoint-freq", type=int_at_least(1), default=10_000, help="env steps between checkpoints")
    tr.add_argument("--eval-freq", type=int_at_least(1), default=10_000, help="env steps between evaluations of J")
    tr.add_argument("--eval-episodes", type=int_at_least(1), default=5, help="episodes per evaluation (seeds 10000+i)")
    tr.add_argument("--resume", action="store_true", help="continue a killed run from its last checkpoint")
    tr.add_argument(
        "--progress-bar",
        action="store_true",
        help="Stable-Baselines3's own progress bar (needs rich, in the sb3 extra) instead of the default progress",
    )
    tr.add_argument(
        "--quiet",
        action="store_true",
        help="no progress (default: a bar with ETA on a terminal, else a line every 30 s)",
    )
    tr.add_argument("--tensorboard", action="store_true", help="TensorBoard logs in DIR/tensorboard (optional package)")
    tr.add_argument("--verbose", type=int_at_least(0, 2), default=0, help="SB3 verbosity (0, 1, 2)")
    tr.set_defaults(func=_train)

    ev = sub.add_parser(
        "evaluate",
        help="evaluate policies on an env × scenario × fault × seed grid",
        description=(
            "Evaluate policies on an env × scenario × fault × seed grid. "
            f"Policies: {', '.join(p for p in POLICIES if p != 'sb3')} (saved SB3 models: --model). "
            f"Env ids: {', '.join(ALL_IDS)}. Scenario presets: {', '.join(list_scenarios())}. "
            "On a learning task (-v1) every policy plays the episodes of its -v0 cell: the plant campaign's cell "
            "whose learned agents train on the same --env-kwargs and --faults, with J* from the shipped table (so "
            "train + evaluate gives the campaign page's J / J*), else the -v0 env with the task's episode keywords."
        ),
    )
    _add_env_options(ev)
    ev.add_argument(
        "--policy",
        action="append",
        metavar="NAME[:key:value,...]",
        help=f"a baseline with parameters, e.g. lqr:discretization:zoh; NAME one of: "
        f"{', '.join(p for p in POLICIES if p != 'sb3')}",
    )
    ev.add_argument(
        "--model",
        action="append",
        help="a saved SB3 model: a training run directory (snapshot chosen by --select), a snapshot folder or a .zip",
    )
    ev.add_argument(
        "--select",
        choices=SELECT,
        default=None,
        help="snapshot of a run directory, as campaigns choose: best (lowest eval J; the default) or final "
        "(a snapshot folder RUN/best or RUN/final is played as it is; --select naming the other one is refused)",
    )
    ev.add_argument("--scenarios", help="YAML list of {name, options, env_kwargs}, or @FILE")
    ev.add_argument("--fault-grid", help="YAML mapping fault-name → fault list, or @FILE")
    ev.add_argument(
        "--scenario",
        help=f"a packaged scenario preset (its env, kwargs and faults): {', '.join(list_scenarios())}",
    )
    ev.add_argument(
        "--seeds",
        type=seeds_arg,
        default="5",
        help=f"episode seeds of every cell: {SYNTAX}; {LIMITS}, so a huge count is refused at once (default 5)",
    )
    ev.add_argument(
        "--seed-offset", type=int_at_least(0, MAX_SEED), default=0, help=f"added to every seed (0 to {MAX_SEED})"
    )
    ev.add_argument(
        "--no-solve",
        action="store_true",
        help="J* only from the shipped table: no CasADi/IPOPT solve for other episodes (they cost seconds to "
        "minutes each; their J / J* is then left blank)",
    )
    ev.add_argument("--out", required=True, help="output directory (episodes.csv/json, report.md, figures)")
    _add_executor_options(ev)
    ev.set_defaults(func=_evaluate)

    bm = sub.add_parser("benchmark", help="run a campaign (agents × envs × scenarios × faults × seeds) → report")
    bm.add_argument(
        "--config",
        default="quick",
        help=f"{', '.join(PRESETS)}, all (the five plant campaigns and the slew task, each in OUT/<name>) or a campaign YAML path",
    )
    bm.add_argument(
        "--backend",
        choices=BACKENDS,
        help="training backend of every trained agent (default: each agent's train.backend, else its hyperparameters')",
    )
    bm.add_argument(
        "--out",
        required=True,
        help="output directory (rerun to resume; completed episodes are skipped, and agents may be added to or "
        "removed from the campaign in between)",
    )
    bm.add_argument("--no-video", action="store_true", help="skip the episode video even if the campaign asks for it")
    _add_executor_options(bm)
    bm.set_defaults(func=_benchmark)

    tu = sub.add_parser(
        "tune", help="search an agent's hyperparameters with Optuna (TPE, median pruning; the tune extra)"
    )
    tu.add_argument("--algo", required=True, help="algorithm with a sampler: ppo, sac (--backend jax: ppo only)")
    _add_env_options(tu)
    tu.add_argument("--out", required=True, help="study directory (study.log, trials.csv, best.yml, trial runs)")
    tu.add_argument(
        "--trials", type=int_at_least(1), default=20, help="trials in all (a resumed search counts the done ones)"
    )
    tu.add_argument("--timesteps", type=int_at_least(1), default=300_000, help="env steps per trial")
    tu.add_argument("--evaluations", type=int_at_least(1), default=3, help="evaluations per trial (pruning points)")
    tu.add_argument("--eval-episodes", type=int_at_least(1), default=10, help="episodes per evaluation (seeds 10000+i)")
    tu.add_argument("--params", nargs="*", help="fixed hyperparameter overrides key:value (Zoo syntax)")
    tu.add_argument(
        "--backend",
        choices=BACKENDS,
        help="sb3 or sbx (optuna, one trial after the other) or jax (a population search: --trials settings drawn "
        "from the same ranges, trained side by side by the fused JAX trainer); default: the hyperparameter entry's",
    )
    tu.add_argument(
        "--shape-groups",
        type=int_at_least(1),
        default=1,
        help="--backend jax: groups of settings with drawn shapes (n_steps, batch_size, n_epochs, network), one "
        "compiled program each (default 1: every setting keeps the entry's shapes, only its floats are drawn)",
    )
    tu.add_argument("--seed", type=int_at_least(0), default=0, help="training seed of every trial")
    tu.add_argument("--sampler-seed", type=int_at_least(0), default=0, help="seed of the TPE sampler")
    _add_jobs_option(tu, "worker processes sharing the study (>= 1)", default=1)
    tu.set_defaults(func=_tune)

    tp = sub.add_parser(
        "tune-pid",
        help="GA-tune PID gains (Ahangarani Farahani et al.'s pipeline): writes a JSON gains file",
        description="GA-tune per-axis PID gains (air-bearing PID paper) on an attitude env; writes a JSON gains file "
        "that `evaluate --policy pid:gains:FILE` and campaigns load.",
    )
    _add_env_options(tp, default="attitude_envs/AirBearing-v0", ids=pid_tuning.ENV_IDS)
    pid_tuning.add_arguments(tp, int_at_least)
    _add_jobs_option(tp, "parallel evaluation processes (>= 1; default 2)")
    tp.set_defaults(func=_tune_pid)

    op = sub.add_parser(
        "optimum", help="the optimal-control yardstick J* per seed (oracle: knows the faults): DIR/optimum.json"
    )
    _add_env_options(op)
    op.add_argument("--seeds", type=seeds_arg, default="1", help=f"episode seeds: {SYNTAX} (default 1: seed 0)")
    op.add_argument(
        "--out",
        help="output directory (optimum.json, optimum.md); with --write-table: the table is written to "
        f"DIR/{optimum_table.TABLE_FILE} instead of the shipped one",
    )
    op.add_argument(
        "--warm-start", default="lqr", choices=["lqr", "best", "none"], help="baseline rollout to start from"
    )
    op.add_argument("--max-iter", type=int_at_least(1), default=1000, help="IPOPT iterations (>= 1)")
    op.add_argument("--no-cache", action="store_true", help="neither read nor write the on-disk cache")
    op.add_argument("--jit", action="store_true", help="compile the step with the C compiler (long horizons)")
    op.add_argument(
        "--write-table",
        action="store_true",
        help="solve J* of every episode of the standard campaign cells and write the shipped table "
        "experiments/optimum_table.json (campaigns read it first)",
    )
    op.add_argument(
        "--campaign",
        action="append",
        metavar="NAME[:ENV,...[:FAULT,...]]",
        help="with --write-table: the cells to cover (a preset or campaign file, optionally only some envs "
        "and faults); default: " + " ".join(optimum_table.SHIPPED),
    )
    op.add_argument(
        "--table", help="with --write-table: the table file to write (default: the shipped one, or DIR/ of --out)"
    )
    op.add_argument(
        "--keep-table",
        action="store_true",
        help="with --write-table: keep the entries the table file already holds (solved with the same "
        "settings), those of other cells as they are, and solve only the named cells' other episode keys",
    )
    _add_jobs_option(op, "with --write-table: solves in parallel (>= 1; default: CPU count)")
    op.set_defaults(func=_optimum)
    return parser


def use_jax_compilation_cache() -> None:
    """Keep JAX's compiled programs across processes (JAX's persistent compilation cache) in
    ``cache_dir("jax")``, unless ``JAX_COMPILATION_CACHE_DIR`` names another folder or
    ``JAX_ENABLE_COMPILATION_CACHE`` is false: the fused trainer's and SBX's programs, compiled
    once per machine, load in the campaign's and tuning's later processes instead of compiling
    again (the same programs: the same numbers). Set as environment variables, which every
    subprocess inherits, and in ``jax.config`` when jax is imported already."""
    if os.environ.get("JAX_ENABLE_COMPILATION_CACHE", "").strip().lower() in ("0", "false", "no", "off"):
        return
    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return
    from attitude_envs.cache import cache_dir

    folder = str(cache_dir("jax"))
    os.environ["JAX_COMPILATION_CACHE_DIR"] = folder
    if "jax" in sys.modules:
        sys.modules["jax"].config.update("jax_compilation_cache_dir", folder)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    quiet_version_warnings()  # the -v0 ids are the papers' problems, not out of date
    use_jax_compilation_cache()
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:  # no subcommand: what there is to run
        parser.print_help()
        return 2
    args.argv = argv
    try:
        return args.func(args)
    except ValueError as exc:
        message = " ".join(str(exc).split())
        print(f"error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: the commands shut down cleanly; one line, no traceback
        print(f"interrupted: {_interrupted_hint(args)}", file=sys.stderr)
        return 130


def _interrupted_hint(args: argparse.Namespace) -> str:
    if args.command in ("benchmark", "evaluate"):
        return (
            f"finished episodes are kept and the run is logged in {str(Path(args.out) / 'runs.jsonl')!r}; "
            "rerun the same command to resume"
        )
    if args.command == "train":
        return f"rerun with --resume to continue {str(args.out)!r} from its last checkpoint"
    if args.command == "tune-pid":
        return "no gains were written; rerun the command"
    if args.command == "reproduce":
        return f"{args.paper} was not written (its files come at the end); rerun the command"
    return "stopped"


if __name__ == "__main__":
    sys.exit(main())
