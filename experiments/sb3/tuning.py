"""Hyperparameter search with Optuna, as the RL Baselines3 Zoo does it, on the suite's own
:func:`~experiments.sb3.training.train` (the ``tune`` extra: ``pip install 'attitude-envs[tune]'``).

Each trial trains one agent with Zoo-format overrides drawn by the algorithm's sampler
(:data:`SAMPLERS`, a subset of the Zoo's ``hyperparams_opt.py`` ranges) on top of the
hyperparameter file's entry and the caller's fixed ``overrides``. The budget is cut into
``n_evaluations`` segments; after each, the run's evaluation J (on the *training*
distribution, seeds 10000+: never a benchmark cell's episodes) is reported to the pruner,
which stops trials below the median of earlier ones at the same step (Optuna's
``MedianPruner``, the Zoo's default). A trial's value is its best evaluation J (the
snapshot campaigns evaluate). The sampler is TPE, seeded.

The study lives in ``OUT/study.log`` (Optuna's journal file), so ``jobs`` processes share it
and a killed search rerun with the same arguments goes on until ``n_trials`` trials have
finished or been pruned (a trial that was running when it was killed stays ``RUNNING`` in the
journal and in ``trials.csv``, and does not count). ``OUT/trials.csv`` lists every trial; ``OUT/best.yml`` is the best trial's entry in
the Zoo format, ready to paste into a hyperparameter file or a campaign's ``overrides``.
"""

from __future__ import annotations

import csv
import math
import multiprocessing
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from experiments.processes import die_with_parent, pin_to_one_core
from experiments.sb3.training import train

INSTALL_HINT = "hyperparameter search needs optuna: pip install 'attitude-envs[tune]'"


def _optuna():
    try:
        import optuna
    except ImportError as exc:  # the tune extra
        raise ImportError(INSTALL_HINT) from exc
    return optuna


def sample_ppo(trial) -> dict[str, Any]:
    """PPO overrides in Zoo syntax (the Zoo's ``sample_ppo_params`` ranges, without the
    ones the suite fixes: gSDE stays as the entry sets it)."""
    n_steps = trial.suggest_categorical("n_steps", [256, 512, 1000, 2000])
    batch_size = trial.suggest_categorical("batch_size", [64, 128, 256, 512])
    gamma = trial.suggest_categorical("gamma", [0.98, 0.99, 0.995, 0.998, 0.999])
    lr = trial.suggest_float("learning_rate", 1e-5, 1e-3, log=True)
    n_epochs = trial.suggest_categorical("n_epochs", [5, 10, 20])
    gae_lambda = trial.suggest_categorical("gae_lambda", [0.9, 0.95, 0.98])
    clip = trial.suggest_categorical("clip_range", [0.1, 0.2, 0.3])
    log_std = trial.suggest_float("log_std_init", -3.0, 0.0)
    width = trial.suggest_categorical("width", [64, 128, 256])
    depth = trial.suggest_categorical("depth", [1, 2, 3])
    arch = [width] * depth
    return {
        "n_steps": n_steps,
        "batch_size": batch_size,
        "gamma": gamma,
        "learning_rate": f"lin_{lr:.3g}",
        "n_epochs": n_epochs,
        "gae_lambda": gae_lambda,
        "clip_range": clip,
        "policy_kwargs": f"dict(log_std_init={log_std:.3g}, net_arch=dict(pi={arch}, vf={arch}))",
    }


#: the samplers by algorithm (the Zoo's hyperparams_opt.py, in part)
SAMPLERS: dict[str, Callable[[Any], dict[str, Any]]] = {"ppo": sample_ppo}


def _objective(spec: dict[str, Any]):
    optuna = _optuna()
    out = Path(spec["out_dir"])
    budget, n_eval = int(spec["timesteps"]), int(spec["n_evaluations"])
    every = max(1, budget // n_eval)

    def objective(trial) -> float:
        overrides = {**SAMPLERS[spec["algo"]](trial), **spec["overrides"]}  # the fixed ones win
        trial.set_user_attr("overrides", overrides)
        run = out / f"trial-{trial.number:03d}"
        for k in range(1, n_eval + 1):
            result = train(
                spec["algo"],
                spec["env_id"],
                run,
                env_kwargs=spec["env_kwargs"],
                seed=int(spec["seed"]),
                overrides=overrides,
                total_timesteps=every * k if k < n_eval else budget,
                schedule_timesteps=budget,  # the schedules anneal over the trial, not over the segment
                checkpoint_freq=every,
                eval_freq=every,
                eval_episodes=int(spec["eval_episodes"]),
                resume=k > 1,
                backend=spec["backend"],
                evaluate_initial=False,  # a trial is scored on what its recipe trains, not on its initial policy
            )
            best = _best_eval_j(run)
            trial.report(best, result.timesteps)
            if trial.should_prune():
                raise optuna.TrialPruned()
        return best

    return objective


def _best_eval_j(run: Path) -> float:
    """The lowest evaluation J of a run so far (``evaluations.csv``; non-finite: inf)."""
    with open(run / "evaluations.csv", newline="", encoding="utf-8") as fh:
        values = [float(row["J_mean"]) for row in csv.DictReader(fh)]
    finite = [v for v in values if math.isfinite(v)]
    return min(finite) if finite else math.inf


def _study(spec: dict[str, Any], worker: int = 0):
    """The shared study, with worker ``worker``'s own sampler seed (``sampler_seed + worker``): with
    one seed, the workers' random start-up trials were the same points, each trained twice."""
    optuna = _optuna()
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    storage = JournalStorage(JournalFileBackend(str(Path(spec["out_dir"]) / "study.log")))
    return optuna.create_study(
        study_name=spec["name"],
        storage=storage,
        load_if_exists=True,
        direction="minimize",
        sampler=optuna.samplers.TPESampler(seed=int(spec["sampler_seed"]) + int(worker), n_startup_trials=5),
        pruner=optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=1),
    )


def _worker(spec: dict[str, Any], n_trials: int, index: int | None = None, parent: int | None = None) -> None:
    if parent is not None:  # a worker process: it dies with the search (also on SIGKILL)
        die_with_parent(parent)
    if index is not None:  # one CPU per worker: JAX sizes its thread pool from the affinity
        pin_to_one_core(index)
    optuna = _optuna()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = _study(spec, index or 0)
    from optuna.trial import TrialState

    # the study stops at n_trials finished or pruned trials, counted over every worker and
    # over earlier (killed) runs of the search; trials still running then finish too
    states = (TrialState.COMPLETE, TrialState.PRUNED)
    if sum(t.state in states for t in study.trials) >= n_trials:
        return
    stop = optuna.study.MaxTrialsCallback(n_trials, states=states)
    study.optimize(_objective(spec), callbacks=[stop], catch=(ValueError,))


def tune(
    algo: str,
    env_id: str,
    out_dir: str | Path,
    env_kwargs: dict[str, Any] | None = None,
    n_trials: int = 20,
    timesteps: int = 300_000,
    n_evaluations: int = 3,
    eval_episodes: int = 10,
    overrides: dict[str, Any] | None = None,
    backend: str | None = None,
    seed: int = 0,
    sampler_seed: int = 0,
    jobs: int = 1,
) -> dict[str, Any]:
    """Search ``algo``'s hyperparameters on ``env_id`` (with ``env_kwargs``: put the training
    distribution there, e.g. random faults) for ``n_trials`` trials of ``timesteps`` env steps
    each, ``jobs`` processes in parallel (each pinned to one CPU, as campaign workers are).
    Returns ``{"best_value", "best_overrides", "n_complete", "n_pruned"}`` and writes
    ``OUT/trials.csv`` and ``OUT/best.yml`` (module docstring)."""
    algo = str(algo).lower()
    if algo not in SAMPLERS:
        raise ValueError(f"tune: no sampler for algo {algo!r} (accepted: {sorted(SAMPLERS)})")
    for name, value, low in (("n_trials", n_trials, 1), ("timesteps", timesteps, 1), ("jobs", jobs, 1)):
        if int(value) < low:
            raise ValueError(f"{name} must be >= {low}, got {value!r}")
    if not 1 <= int(n_evaluations) <= int(timesteps):
        raise ValueError(f"n_evaluations must be in [1, timesteps], got {n_evaluations!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec = {
        "name": f"{algo}-{env_id.split('/')[-1]}",
        "algo": algo,
        "env_id": env_id,
        "out_dir": str(out),
        "env_kwargs": dict(env_kwargs or {}),
        "timesteps": int(timesteps),
        "n_evaluations": int(n_evaluations),
        "eval_episodes": int(eval_episodes),
        "overrides": dict(overrides or {}),
        "backend": backend,
        "seed": int(seed),
        "sampler_seed": int(sampler_seed),
    }
    _study(spec)  # created once, before the workers share it
    if int(jobs) == 1:
        _worker(spec, int(n_trials))
    else:
        ctx = multiprocessing.get_context("spawn")  # JAX and torch are not fork-safe
        parent = os.getpid()
        procs = [ctx.Process(target=_worker, args=(spec, int(n_trials), i, parent)) for i in range(int(jobs))]
        for p in procs:
            p.start()
        for p in procs:
            p.join()
        failed = [p.exitcode for p in procs if p.exitcode != 0]
        if failed:
            raise RuntimeError(f"tune: {len(failed)} worker(s) failed (exit codes {failed})")
    return _write_results(_study(spec), out, algo, env_id)


def _write_results(study, out: Path, algo: str, env_id: str) -> dict[str, Any]:
    from optuna.trial import TrialState

    rows = []
    for t in study.trials:
        rows.append(
            {
                "number": t.number,
                "state": t.state.name,
                "value": t.value,
                "last_step": t.last_step,
                **{f"param_{k}": v for k, v in t.params.items()},
            }
        )
    fields = sorted(
        {k for r in rows for k in r}, key=lambda k: (not k.startswith(("number", "state", "value", "last")), k)
    )
    with open(out / "trials.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    complete = [t for t in study.trials if t.state == TrialState.COMPLETE]
    summary: dict[str, Any] = {
        "n_complete": len(complete),
        "n_pruned": sum(t.state == TrialState.PRUNED for t in study.trials),
        "best_value": None,
        "best_overrides": None,
    }
    if complete:
        best = min(complete, key=lambda t: t.value)
        summary.update(best_value=best.value, best_overrides=best.user_attrs["overrides"], best_trial=best.number)
        entry = {env_id: best.user_attrs["overrides"]}  # the sampled values and the fixed ones
        header = f"# optuna search ({algo}): trial {best.number}, best eval J {best.value:.6g}; see trials.csv\n"
        (out / "best.yml").write_text(header + yaml.safe_dump(entry, sort_keys=False), encoding="utf-8")
    return summary
