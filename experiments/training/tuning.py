"""Hyperparameter search with Optuna, as the RL Baselines3 Zoo does it, on the suite's own
:func:`~experiments.training.training.train` (the ``tune`` extra: ``pip install 'attitude-envs[tune]'``).

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

from attitude_envs.make import check_env_id
from experiments.processes import die_with_parent, pin_to_one_core
from experiments.training.hyperparams import load_hyperparams
from experiments.training.training import train

INSTALL_HINT = "hyperparameter search needs optuna: pip install 'attitude-envs[tune]'"


def _optuna():
    try:
        import optuna
    except ImportError as exc:  # the tune extra
        raise ImportError(INSTALL_HINT) from exc
    return optuna


#: PPO's search space (the Zoo's ``sample_ppo_params`` ranges, without the ones the suite fixes:
#: gSDE stays as the entry sets it), in the order the sampler draws: a list is categorical,
#: ``("log", low, high)`` log-uniform, ``("uniform", low, high)`` uniform. The jax backend's
#: population search (:mod:`experiments.training.jax_tuning`) draws from the same space.
PPO_SPACE: dict[str, Any] = {
    "n_steps": [256, 512, 1000, 2000],
    "batch_size": [64, 128, 256, 512],
    "gamma": [0.98, 0.99, 0.995, 0.998, 0.999],
    "learning_rate": ("log", 1e-5, 1e-3),
    "n_epochs": [5, 10, 20],
    "gae_lambda": [0.9, 0.95, 0.98],
    "clip_range": [0.1, 0.2, 0.3],
    "log_std_init": ("uniform", -3.0, 0.0),
    "width": [64, 128, 256],
    "depth": [1, 2, 3],
}

#: SAC's search space (the Zoo's ``sample_sac_params`` ranges, in part; ``gradient_steps`` follows
#: ``train_freq`` as there), in :data:`PPO_SPACE`'s notation
SAC_SPACE: dict[str, Any] = {
    "gamma": [0.98, 0.99, 0.995, 0.998, 0.999],
    "learning_rate": ("log", 1e-5, 1e-2),
    "batch_size": [64, 128, 256, 512],
    "buffer_size": [10_000, 100_000, 1_000_000],
    "learning_starts": [0, 1000, 10_000],
    "train_freq": [1, 4, 8, 16, 32],
    "tau": [0.005, 0.01, 0.02, 0.05],
    "log_std_init": ("uniform", -4.0, 1.0),
    "width": [64, 256, 400],
    "depth": [2, 3],
}


def gamma_choices(decisions: int) -> list[float]:
    """The discounts a search may draw on a task of ``decisions`` decisions per episode: those of
    :data:`PPO_SPACE` whose horizon ``1/(1 − γ)`` decisions fits in the episode (the ``"episode"``
    termination charge prices a limit crossing above holding the state only for those: see
    :meth:`attitude_envs.envs.base.AttitudeEnv.batch_termination_cost`); where fewer than three
    fit (the ``-v1`` tasks of tens of decisions), horizons of 1/8, 1/4, 1/2 and the whole episode,
    γ rounded down to 4 decimals so that no horizon passes the episode."""
    decisions = int(decisions)
    if decisions < 1:
        raise ValueError(f"decisions must be >= 1, got {decisions}")
    fitting = [
        g for g in PPO_SPACE["gamma"] if 1.0 / (1.0 - g) <= decisions * (1 + 1e-9)
    ]  # 1e-9: rounding of 1/(1 − γ)
    if len(fitting) >= 3:
        return fitting
    horizons = [h for h in (decisions / 8, decisions / 4, decisions / 2, decisions) if h >= 2]
    return sorted({math.floor((1.0 - 1.0 / h) * 1e4) / 1e4 for h in horizons}) or [0.5]


def ppo_space(decisions: int | None = None) -> dict[str, Any]:
    """:data:`PPO_SPACE` for a task of ``decisions`` decisions per episode (its ``gamma`` from
    :func:`gamma_choices`; None: the Zoo's list unchanged)."""
    return search_space("ppo", decisions)


def search_space(algo: str, decisions: int | None = None) -> dict[str, Any]:
    """``algo``'s search space (:data:`PPO_SPACE`, :data:`SAC_SPACE`) for a task of ``decisions``
    decisions per episode (its ``gamma`` from :func:`gamma_choices`; None: the Zoo's list)."""
    space = dict(SAMPLERS[algo][0])
    if decisions is not None:
        space["gamma"] = gamma_choices(decisions)
    return space


def task_decisions(env_id: str, env_kwargs: dict[str, Any] | None = None) -> int:
    """Decisions per episode of ``env_id`` built with ``env_kwargs`` (validated as ``make`` does)."""
    from attitude_envs.make import make_checked

    env = make_checked(env_id, **dict(env_kwargs or {}))
    try:
        return int(env.unwrapped.decisions_per_episode)
    finally:
        env.close()


def ppo_overrides(params: dict[str, Any]) -> dict[str, Any]:
    """The Zoo overrides of drawn :data:`PPO_SPACE` values (``width`` × ``depth``: both nets)."""
    arch = [params["width"]] * params["depth"]
    out = {k: params[k] for k in ("n_steps", "batch_size", "gamma")}
    out["learning_rate"] = f"lin_{params['learning_rate']:.3g}"
    out |= {k: params[k] for k in ("n_epochs", "gae_lambda", "clip_range")}
    out["policy_kwargs"] = f"dict(log_std_init={params['log_std_init']:.3g}, net_arch=dict(pi={arch}, vf={arch}))"
    return out


def sac_overrides(params: dict[str, Any]) -> dict[str, Any]:
    """The Zoo overrides of drawn :data:`SAC_SPACE` values (constant learning rate and
    ``gradient_steps = train_freq``, as the Zoo's sampler; ``width`` × ``depth``: actor and critics)."""
    arch = [params["width"]] * params["depth"]
    out = {k: params[k] for k in ("gamma", "batch_size", "buffer_size", "learning_starts", "train_freq", "tau")}
    out["learning_rate"] = float(f"{params['learning_rate']:.3g}")
    out["gradient_steps"] = params["train_freq"]
    out["policy_kwargs"] = f"dict(log_std_init={params['log_std_init']:.3g}, net_arch={arch})"
    return out


def sample(trial, algo: str, space: dict[str, Any] | None = None) -> dict[str, Any]:
    """``algo``'s overrides in Zoo syntax drawn by an optuna ``trial`` from ``space`` (default
    its Zoo space; a task's: :func:`search_space`)."""
    default, to_overrides = SAMPLERS[algo]
    params = {}
    for name, values in (space or default).items():
        if isinstance(values, list):
            params[name] = trial.suggest_categorical(name, values)
        else:
            params[name] = trial.suggest_float(name, values[1], values[2], log=values[0] == "log")
    return to_overrides(params)


def sample_ppo(trial, space: dict[str, Any] | None = None) -> dict[str, Any]:
    """PPO overrides drawn by an optuna ``trial`` (:func:`sample`)."""
    return sample(trial, "ppo", space)


#: the search space and its Zoo overrides, by algorithm (the Zoo's hyperparams_opt.py, in part)
SAMPLERS: dict[str, tuple[dict[str, Any], Callable[[dict[str, Any]], dict[str, Any]]]] = {
    "ppo": (PPO_SPACE, ppo_overrides),
    "sac": (SAC_SPACE, sac_overrides),
}


def _objective(spec: dict[str, Any]):
    optuna = _optuna()
    out = Path(spec["out_dir"])
    budget, n_eval = int(spec["timesteps"]), int(spec["n_evaluations"])
    every = max(1, budget // n_eval)

    def objective(trial) -> float:
        drawn = sample(trial, spec["algo"], search_space(spec["algo"], spec["decisions"]))
        overrides = {**drawn, **spec["overrides"]}  # the fixed ones win
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
    failed_before = sum(t.state == TrialState.FAIL for t in study.trials)

    def stop_failing(study, trial) -> None:  # a drawn setting that cannot train is redrawn, not for ever
        if sum(t.state == TrialState.FAIL for t in study.trials) - failed_before >= n_trials:
            study.stop()

    study.optimize(_objective(spec), callbacks=[stop, stop_failing], catch=(ValueError,))
    failed = sum(t.state == TrialState.FAIL for t in study.trials) - failed_before
    if failed >= n_trials:
        raise ValueError(f"tune: {failed} trials failed (their errors are printed above); stopped the search")


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
    # the env id and the fixed overrides checked once, before any trial: a trial that fails on
    # them (a ValueError) would be caught by optuna, and a failed trial does not count to n_trials
    check_env_id(env_id)
    load_hyperparams(algo, env_id, None, {**dict(overrides or {}), **({"backend": backend} if backend else {})})
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
        "decisions": task_decisions(env_id, env_kwargs),  # γ is drawn within the episode (gamma_choices)
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
