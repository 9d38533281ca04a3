"""``attitude-envs tune-pid``: the GA PID pipeline of :mod:`agents.ga_tuning` run in a process
pool, with progress, writing a JSON gains file (:func:`baselines.pid.load_gains` reads it)."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from pathlib import Path
from typing import Any

from agents.ga_tuning import (
    LAB_MANEUVER,
    OBJECTIVES,
    REGRESSORS,
    Evaluator,
    GAConfig,
    build_schedule,
    init_worker,
    sample_maneuvers,
    tune_gains,
)
from baselines.pid import GAIN_NAMES, UNITS
from experiments.jsonable import json_ready
from experiments.policies import GYROSTATS
from experiments.processes import die_with_parent, pool_context
from experiments.progress import Progress

#: the ids tune-pid tunes: the per-axis PID of the gyrostat plants (the GA evaluates the
#: wheel platform's error angles; :data:`experiments.policies.GYROSTATS`)
ENV_IDS = tuple(f"attitude_envs/{name}-v{v}" for name in GYROSTATS for v in (0, 1))


def check_env(env_id: str) -> str:
    """``env_id`` when tune-pid tunes it, else a ``ValueError`` naming the ids it does."""
    if env_id not in ENV_IDS:
        raise ValueError(
            f"tune-pid tunes the PID of the reaction-wheel plants only; --env must be one of {', '.join(ENV_IDS)}, "
            f"got {env_id!r}"
        )
    return env_id


def _pool_worker_init(parent_pid: int, env_id: str, env_kwargs: dict[str, Any]) -> None:
    die_with_parent(parent_pid)  # Ctrl-C is the parent's; the worker dies with it, also on SIGKILL
    init_worker(env_id, env_kwargs)


@contextlib.contextmanager
def evaluator(env_id: str, env_kwargs: dict[str, Any] | None = None, workers: int = 1) -> Iterator[Evaluator]:
    """An :class:`~agents.ga_tuning.Evaluator` on ``workers`` processes (1: in this process),
    whose pool is shut down on exit."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    kwargs = dict(env_kwargs or {})
    local = Evaluator(env_id, kwargs)  # validates the env before any worker starts
    if workers == 1:
        yield local
        return
    pool = ProcessPoolExecutor(
        workers, mp_context=pool_context(), initializer=_pool_worker_init, initargs=(os.getpid(), env_id, kwargs)
    )
    try:
        yield Evaluator(env_id, kwargs, executor=pool)
    finally:
        pool.shutdown()


def add_arguments(p: argparse.ArgumentParser, int_at_least: Callable[[int], Callable[[str], int]]) -> None:
    """The options of ``attitude-envs tune-pid`` (``--env``, ``--env-kwargs`` and ``--jobs`` come
    from the command line's shared options); ``int_at_least(low)``: the command line's argparse
    type of an integer >= low (one line naming the option otherwise)."""
    p.add_argument("--mode", choices=["fixed", "schedule"], default="fixed", help="constant gains or meta-model")
    p.add_argument("--objective", choices=OBJECTIVES, default="iae", help="IAE (deg·s) or the shared cost J")
    p.add_argument(
        "--maneuvers",
        type=int_at_least(0),
        default=0,
        help="random maneuvers from the env (>= 0; 0: the paper's lab test)",
    )
    p.add_argument("--maneuver-seed", type=int_at_least(0), default=0, help="first reset seed of the random maneuvers")
    p.add_argument("--population", type=int_at_least(2), default=GAConfig.population, help="GA population (>= 2)")
    p.add_argument("--generations", type=int_at_least(1), default=GAConfig.generations, help="GA generations (>= 1)")
    p.add_argument("--mutation-probability", type=float, default=GAConfig.mutation_probability)
    p.add_argument("--crossover-probability", type=float, default=GAConfig.crossover_probability)
    p.add_argument("--seed", type=int_at_least(0), default=0, help="GA seed (>= 0)")
    for g, b in zip(GAIN_NAMES, (GAConfig.kp_bounds, GAConfig.kd_bounds, GAConfig.ki_bounds), strict=True):
        p.add_argument(f"--{g}-bounds", type=float, nargs=2, default=list(b), metavar=("MIN", "MAX"))
    p.add_argument("--regressor", choices=REGRESSORS, default="initial", help="meta-model states (schedule mode)")
    p.add_argument("--units", choices=UNITS, default="rad", help="schedule argument units (schedule mode)")
    p.add_argument("--out", default="pid_gains.json", help="output JSON file")


def tune_pid(args: argparse.Namespace, env_kwargs: dict[str, Any], workers: int) -> Path:
    """Runs the GA (and the meta-model with ``--mode schedule``) and writes the gains file; returns its path.

    Raises ``ValueError`` for bad input."""
    check_env(args.env)
    config = GAConfig(
        population=args.population,
        generations=args.generations,
        mutation_probability=args.mutation_probability,
        crossover_probability=args.crossover_probability,
        seed=args.seed,
        kp_bounds=tuple(args.kp_bounds),
        kd_bounds=tuple(args.kd_bounds),
        ki_bounds=tuple(args.ki_bounds),
    )
    with evaluator(args.env, env_kwargs, workers) as ev:
        if args.maneuvers > 0:
            maneuvers = sample_maneuvers(ev.env, args.maneuvers, args.maneuver_seed)
        else:
            maneuvers = [{"seed": 0, "options": LAB_MANEUVER}]
        doc: dict[str, Any] = {
            "env": args.env,
            "env_kwargs": env_kwargs,
            "objective": args.objective,
            "config": asdict(config),
            "maneuvers": maneuvers,
        }
        if args.mode == "fixed":
            with Progress(config.generations, "GA generations", "gen") as bar:

                def progress(gen: int, best: float) -> None:
                    bar.update(1)
                    bar.set_postfix(f"best {best:.4g}")

                result = tune_gains(ev, maneuvers, config, args.objective, progress)
            doc.update(gains=result.gains.to_dict(), best_objective=result.objective, history=result.history)
        else:
            total = config.generations * len(maneuvers)
            with Progress(total, "GA generations (all maneuvers)", "gen") as bar:

                def progress(j: int, gen: int, best: float) -> None:
                    bar.update(1)
                    bar.set_postfix(f"maneuver {j}, best {best:.4g}")

                res = build_schedule(ev, maneuvers, config, args.objective, args.regressor, args.units, progress)
            doc.update(
                gains=res.schedule.to_dict(),
                regressor=args.regressor,
                data_bank={"genes": res.genes, "angles_rad": res.angles_rad, "rates_rad_s": res.rates_rad_s},
                residual_rms=res.residual_rms,
                rank=res.rank,
                best_objectives=[t.objective for t in res.tunings],
            )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(json_ready(doc), indent=2) + "\n", encoding="utf-8")
    return out
