"""``train``: an agent on a registered env, with periodic J evaluation, checkpoints and resume, on
any backend (:mod:`experiments.training.algorithm`): SB3 and SBX here, the fused JAX trainer in
:mod:`experiments.training.jax_training`; the run directory is theirs alike
(:mod:`experiments.training.run_dir`). ``load_trained`` loads what any of them saved.

A SB3/SBX checkpoint holds ``state.pkl``, ``model.zip`` and ``vecnormalize.pkl``
(:mod:`experiments.training.checkpoint`); snapshots hold ``model.zip`` and ``vecnormalize.pkl``.
"""

from __future__ import annotations

import json
import pickle
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

from attitude_envs.files import read_json as read_json_file
from attitude_envs.make import check_env_id, make_checked
from experiments.training.algorithm import Algorithm
from experiments.training.callbacks import NormalizedPredictor, evaluate_cost, read_json
from experiments.training.checkpoint import BudgetSchedule, RunClock, read_checkpoint, restore_rng, write_checkpoint
from experiments.training.discount import warn_if_uncovered
from experiments.training.hyperparams import (
    import_dotted,
    jax_wrappers,
    load_hyperparams,
    split_hyperparams,
    zoo_objects,
)
from experiments.training.progress import ProgressCallback
from experiments.training.run_dir import RunDir, RunPlan, TrainResult, run_budget
from experiments.training.vec_envs import PicklableVecFrameStack, batched_supported, make_eval_env, make_training_env


def _tensorboard_dir(out_dir: Path, tensorboard: bool | None) -> str | None:
    if tensorboard is False:
        return None
    try:
        import tensorboard as _  # noqa: F401  (optional package: TensorBoard logs only when installed)
    except ImportError as exc:
        if tensorboard:
            raise ValueError(
                "tensorboard logging needs the optional package 'tensorboard' (pip install tensorboard)"
            ) from exc
        return None
    return str(out_dir / "tensorboard")


def train(
    algo: str,
    env_id: str,
    out_dir: str | Path,
    env_kwargs: dict[str, Any] | None = None,
    seed: int = 0,
    hyperparams_file: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    total_timesteps: int | None = None,
    checkpoint_freq: int = 10_000,
    eval_freq: int = 10_000,
    eval_episodes: int = 5,
    eval_seed: int = 10_000,
    eval_env_kwargs: dict[str, Any] | None = None,
    resume: bool = False,
    backend: str | None = None,
    progress_bar: bool = False,
    tensorboard: bool | None = None,
    verbose: int = 0,
    progress: bool | str = False,
    schedule_timesteps: int | None = None,
    evaluate_initial: bool = True,
) -> TrainResult:
    """Train (or with ``resume`` continue) an agent; returns where the final model was saved.

    ``total_timesteps`` (env steps over all parallel envs) defaults to the hyperparameter
    file's ``n_timesteps``. Training runs in whole rollouts (PPO/A2C: ``n_steps × n_envs`` env
    steps; off-policy: ``train_freq × n_envs``), so it stops at the end of the first rollout at or
    after ``total_timesteps`` (a multiple of the rollout when the budget is one), and evaluations
    and checkpoints happen at the end of the first rollout at or after each multiple of
    ``eval_freq`` and ``checkpoint_freq`` (the final step is always evaluated and checkpointed).
    Every evaluation is followed by a checkpoint; a run killed at any moment and resumed
    (``resume``) continues from its last checkpoint bitwise like an uninterrupted one: same
    ``evaluations.csv``, best snapshot and final step (see :mod:`experiments.training.checkpoint`).
    Resuming a run whose checkpoint already reached the budget does no training
    (``TrainResult.already_complete``); a larger budget extends it. The eval env uses
    ``eval_env_kwargs`` (default: the training kwargs) and seeds ``eval_seed + i``.
    Training and evaluation run on the natively batched env of ``env_id``
    (:mod:`experiments.training.vec_envs`; evaluation plays its episodes as one batch); kwargs it
    does not support (sensors, ``fault_hint``) fall back to single envs.
    ``backend``: ``"sb3"`` (PyTorch), ``"sbx"`` (JAX, the ``sbx`` extra) or ``"jax"`` (PPO only:
    the fused trainer on the env's JAX plant, the ``jax`` extra; :mod:`experiments.training.jax_training`;
    :mod:`experiments.training.algorithm`); default: the entry's ``backend`` key, else ``"sb3"``.
    Checkpoints, resume, best/final snapshots and :func:`load_trained` work the same on all
    three (``progress_bar`` and ``tensorboard`` are SB3's: the jax backend ignores them).
    ``schedule_timesteps``: the budget the hyperparameter schedules (``lin_3e-4`` …) anneal over
    (default ``total_timesteps``). A search that trains a trial in segments passes its full budget
    here, so that each segment trains as the same part of one uninterrupted run would.
    ``evaluate_initial``: evaluate the untrained policy at 0 steps as the first candidate for
    the best snapshot (a run that never beats it keeps it, and its report says so).
    ``progress``: True a bar with ETA on a terminal, else a status line every 30 s; a string is
    its label and means status lines (campaign workers); ``progress_bar``: SB3's own bar instead
    (one per segment).
    """
    check_env_id(env_id)
    if int(seed) < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if int(checkpoint_freq) < 1 or int(eval_freq) < 1 or int(eval_episodes) < 1:
        raise ValueError(
            f"checkpoint_freq, eval_freq and eval_episodes must be >= 1, got {checkpoint_freq}, {eval_freq} and {eval_episodes}"
        )
    out_dir = Path(out_dir)
    env_kwargs = dict(env_kwargs or {})
    eval_kwargs = dict(eval_env_kwargs if eval_env_kwargs is not None else env_kwargs)
    saved = read_json(out_dir / "config.json")
    if backend is None and resume:  # a resumed run keeps the backend it was started with
        started = (saved or {}).get("hyperparams", {})
        backend = started.get("backend") if "backend" in started and "backend" not in (overrides or {}) else None
    if backend is not None:
        overrides = {**(overrides or {}), "backend": backend}
    entry = load_hyperparams(algo, env_id, hyperparams_file, overrides)
    algorithm = Algorithm(algo, entry.get("backend", "sb3")).trainable()
    # validates the env kwargs before anything is written; warns when γ is past what a limit charge covers
    n_actions, batched = _probe(env_id, env_kwargs, gamma=entry.get("gamma", 0.99))
    _, eval_batched = _probe(env_id, eval_kwargs)
    if algorithm.backend == "jax" and entry.get("callback"):
        raise ValueError(
            "the jax backend (the fused trainer) takes no callback: its envs are JAX twins; train with backend sb3 or sbx"
        )
    if algorithm.backend == "jax" and jax_wrappers(entry):  # an evaluation env wrapped as the twins are: single
        eval_batched = False
    hp = None if algorithm.backend == "jax" else split_hyperparams(entry, n_actions, algorithm)
    if hp is not None and hp["env_wrapper"]:  # per-env Gymnasium wrappers: single envs
        batched = eval_batched = False
    default = entry.get("n_timesteps", 1_000_000) if hp is None else hp["n_timesteps"]
    total, horizon = run_budget(total_timesteps, default, schedule_timesteps)
    plan = RunPlan(
        algorithm,
        env_id,
        env_kwargs,
        eval_kwargs,
        int(seed),
        entry,
        total,
        horizon,
        int(eval_freq),
        int(eval_episodes),
        int(eval_seed),
        int(checkpoint_freq),
    )
    run_dir = RunDir(out_dir, plan, saved, resume)
    if hp is None:  # the fused JAX trainer: its own loop, same run directory
        from experiments.training.jax_training import train_jax

        return train_jax(run_dir, eval_batched, progress, verbose, evaluate_initial)
    return _train_sb3(
        run_dir, hp, batched, eval_batched, progress, progress_bar, tensorboard, verbose, evaluate_initial
    )


def _probe(env_id: str, kwargs: dict[str, Any], gamma: Any = None) -> tuple[int, bool]:
    """``(action size, whether the natively batched env serves)`` of ``env_id`` built with
    ``kwargs`` (``ValueError`` for kwargs the env refuses); with ``gamma`` (the discount the
    learner trains with; SB3's default 0.99 when the entry names none) a
    :class:`~experiments.training.discount.LimitChargeWarning` when the env's limit charge does
    not cover it."""
    probe = make_checked(env_id, **kwargs)
    try:
        if gamma is not None:
            warn_if_uncovered(probe, gamma, env_id)
        return int(np.prod(probe.action_space.shape)), batched_supported(env_id, probe)
    finally:
        probe.close()


def _train_sb3(
    run_dir: RunDir,
    hp: dict[str, Any],
    batched: bool,
    eval_batched: bool,
    progress: bool | str,
    progress_bar: bool,
    tensorboard: bool | None,
    verbose: int,
    evaluate_initial: bool,
) -> TrainResult:
    """:func:`train`'s loop on Stable-Baselines3 or SBX: ``learn()`` in segments that end at the
    plan's evaluations and checkpoints."""
    plan, out_dir = run_dir.plan, run_dir.path
    algo = plan.algorithm.name
    torch.set_num_threads(1)  # one thread: bitwise repeatable (and small networks gain nothing from more)
    checkpoint = run_dir.checkpoint
    if checkpoint is None:  # a new run, or one killed before its first checkpoint: start (again) from scratch
        run = run_dir.start()
        set_random_seed(plan.seed)
        clock = RunClock(plan.horizon)
        model = _new_model(plan, hp, clock, out_dir, tensorboard, verbose, batched)
        rng = None
        resumed_from = None
    else:
        model, clock, run, rng = read_checkpoint(checkpoint["path"])
        clock.total = plan.horizon
        model.verbose = verbose
        run_dir.resume(run, int(model.num_timesteps), model)
        resumed_from = int(model.num_timesteps)
    total = plan.total
    already_complete = int(model.num_timesteps) >= total

    eval_env = make_eval_env(plan.env_id, plan.eval_kwargs, plan.eval_episodes, eval_batched, hp["env_wrapper"])
    seeds = plan.eval_seeds
    # the Zoo's callbacks, built once per run (their state, if any, is the env's: checkpointed with it)
    callbacks = [import_dotted(path)(**kwargs) for path, kwargs in hp["callback"]]
    callback = None
    label = progress if isinstance(progress, str) else f"train {algo} {plan.env_id.split('/')[-1]}"
    if progress and resumed_from is not None and not already_complete:
        print(f"{label}: resuming at {resumed_from} steps ({checkpoint['path']})", file=sys.stderr, flush=True)
    if progress and not progress_bar and not already_complete:
        callbacks.append(ProgressCallback(total, label, bar=None if progress is True else False))
    if callbacks:
        callback = callbacks[0] if len(callbacks) == 1 else CallbackList(callbacks)
    if progress and resumed_from is None:
        hint = " (--params n_steps:N or train_freq:N sets the rollout)"
        plan.note_whole_rollouts(plan.algorithm.rollout_steps(hp["kwargs"], hp["n_envs"]), hp["n_envs"], hint)
    start = time.perf_counter()
    if evaluate_initial and run["best"] is None and int(model.num_timesteps) == 0:
        # the initial policy is a candidate snapshot too: a run that never beats it says so
        # (its best snapshot is at 0 steps) instead of presenting its least bad trained policy.
        # Deterministic evaluation draws from no global generator, so training is unchanged.
        run_dir.record(run, {"timesteps": 0, **evaluate_cost(_predictor(model, hp["frame_stack"]), eval_env, seeds)})
        run_dir.save_best(run["best"], model)
    if model.tensorboard_log is None:
        log_without_folder(model)
    if rng is not None:
        restore_rng(rng)  # last: nothing may draw from the global generators between here and learn()
    try:
        while int(model.num_timesteps) < total:
            done = int(model.num_timesteps)
            target = plan.segment_end(done)
            clock.segment_end = target
            model.learn(
                target - done,
                callback=callback,
                reset_num_timesteps=done == 0,
                tb_log_name=algo,
                progress_bar=progress_bar,
            )
            steps = int(model.num_timesteps)
            if steps <= done:
                raise RuntimeError(f"{algo}.learn() made no progress at {done} steps")
            new_best = False
            if plan.evaluates(done, steps):
                row = {"timesteps": steps, **evaluate_cost(_predictor(model, hp["frame_stack"]), eval_env, seeds)}
                new_best = run_dir.record(run, row)  # fsynced before the checkpoint below moves the pointer
                model.logger.record("eval/J_mean", row["J_mean"])  # TensorBoard, when on
                model.logger.dump(step=steps)
                if verbose:
                    print(f"eval at {steps} steps: J = {row['J_mean']:.3f} ± {row['J_std']:.3f}")
            write_checkpoint(out_dir / "checkpoints", model, clock, run)
            if new_best:  # after the pointer: a resume from an older checkpoint never sees a newer best
                run_dir.save_best(run["best"], model)
    finally:
        for cb in callbacks:
            if isinstance(cb, ProgressCallback):
                cb.close()
    wall = time.perf_counter() - start
    steps = int(model.num_timesteps)
    segment = (
        None if already_complete else {"from_timesteps": resumed_from or 0, "to_timesteps": steps, "wall_time_s": wall}
    )
    model_path = run_dir.finish(segment, steps, lambda: model)
    eval_env.close()
    model.get_env().close()
    return TrainResult(out_dir, model_path, steps, resumed_from, wall, run["last_eval"], already_complete)


def _predictor(model, frame_stack: int = 1) -> NormalizedPredictor:
    return NormalizedPredictor(model, model.get_vec_normalize_env(), frame_stack)


def log_without_folder(model) -> None:
    """Give ``model`` a logger with no folder: without TensorBoard, SB3's ``learn()`` otherwise
    makes an empty ``$TMPDIR/SB3-<time>`` folder on every call (one per evaluation segment)."""
    from stable_baselines3.common.logger import HumanOutputFormat, Logger

    formats = [HumanOutputFormat(sys.stdout)] if model.verbose >= 1 else []
    model.set_logger(Logger(folder=None, output_formats=formats))


def _new_model(plan: RunPlan, hp: dict[str, Any], clock: RunClock, out_dir: Path, tensorboard, verbose, batched):
    kwargs = dict(hp["kwargs"])
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if callable(kwargs.get(key)):
            kwargs[key] = BudgetSchedule(kwargs[key], clock)  # progress over the whole run, not one segment
    venv = make_training_env(plan.env_id, plan.env_kwargs, hp["n_envs"], plan.seed, batched, hp["env_wrapper"])
    if hp["normalize"] is not None:
        venv = VecNormalize(venv, gamma=float(plan.entry.get("gamma", 0.99)), **hp["normalize"])
    if hp["frame_stack"] > 1:  # after normalization, as the Zoo stacks
        venv = PicklableVecFrameStack(venv, hp["frame_stack"])
    try:
        return plan.algorithm.model_class()(
            hp["policy"],
            venv,
            seed=plan.seed,
            verbose=verbose,
            tensorboard_log=_tensorboard_dir(out_dir, tensorboard),
            **kwargs,
        )
    except (TypeError, AssertionError, KeyError) as exc:  # SB3 reports bad hyperparameters this way
        venv.close()
        raise ValueError(f"bad hyperparameters for {plan.algorithm.name} ({sorted(hp['kwargs'])}): {exc}") from exc


def load_trained(model_path: str | Path, env: gym.Env | None = None):
    """A saved model (``.../model.zip``; its ``vecnormalize.pkl`` beside it is applied) as a
    predictor with ``predict(obs, ...)``. With ``env``, checks that it is the env the model was
    trained on (the env id in its run's ``config.json``) and that the observation and action
    spaces match the model's (``ValueError`` naming both otherwise)."""
    model_path = _model_file(model_path)
    saved = _run_config(model_path)
    algorithm = _algo_of(model_path, saved)
    frame_stack = int(((saved or {}).get("hyperparams") or {}).get("frame_stack") or 1)
    if env is not None and saved is not None and getattr(env, "spec", None) is not None:
        if saved.get("env_id") not in (None, env.spec.id):
            raise ValueError(
                f"model {str(model_path)!r} was trained on {saved['env_id']} (its run's config.json), "
                f"not on {env.spec.id}: evaluate it on {saved['env_id']}"
            )
    try:
        if algorithm.backend == "jax":  # a fused-PPO model file plays on numpy: no jax needed to load it
            model = algorithm.model_class().load(model_path)
        else:
            model = algorithm.model_class().load(model_path, device="cpu", custom_objects=_PLAYING_ONLY)
    except (zipfile.BadZipFile, EOFError, pickle.UnpicklingError, KeyError, OSError, ValueError) as exc:
        raise ValueError(
            f"model file {str(model_path)!r} cannot be loaded ({exc}): it is cut or not a model file"
        ) from None
    if env is not None:
        seen = {"observation_space": env.observation_space, "action_space": env.action_space}
        for path, _ in zoo_objects("env_wrapper", ((saved or {}).get("hyperparams") or {}).get("env_wrapper")):
            space_of = getattr(import_dotted(path), "observation_space_of", None)  # a wrapper that adds to it
            if space_of is not None:
                seen["observation_space"] = space_of(seen["observation_space"], env.action_space)
        for what in ("observation_space", "action_space"):
            ours, theirs = seen[what], getattr(model, what)
            if what == "observation_space" and frame_stack > 1:  # VecFrameStack's stacked space
                ours = gym.spaces.Box(np.repeat(ours.low, frame_stack, -1), np.repeat(ours.high, frame_stack, -1))
            # a fused-PPO model file (backend jax) keeps the observation's shape only
            bounds_known = not (algorithm.backend == "jax" and what == "observation_space")
            if ours.shape != theirs.shape or not (
                not bounds_known
                or (
                    np.allclose(getattr(ours, "low", 0), getattr(theirs, "low", 0))
                    and np.allclose(getattr(ours, "high", 0), getattr(theirs, "high", 0))
                )
            ):
                raise ValueError(
                    f"model {str(model_path)!r} was trained for a different env: its {what} is {theirs}, the env's is {ours}"
                )
    vecnorm = None
    stats = model_path.parent / "vecnormalize.pkl"
    if stats.is_file():
        try:
            with stats.open("rb") as fh:
                vecnorm = pickle.load(fh)
            vecnorm.training = False
        except (EOFError, pickle.UnpicklingError, AttributeError, ImportError, ValueError) as exc:
            raise ValueError(
                f"normalization statistics {str(stats)!r} cannot be loaded ({exc}): the file is cut; "
                "the model cannot play without them"
            ) from None
    return NormalizedPredictor(model, vecnorm, frame_stack)


#: what a model file holds for training only, replaced on loading: a model that plays needs no
#: schedules, and a file whose pickled schedules name a module since moved (experiments.sb3) still loads
_PLAYING_ONLY = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}

_POLICY_MODULES = {
    "sbx.ppo": "ppo",
    "sbx.sac": "sac",
    "sbx.td3": "td3",  # SBX's DDPG saves TD3's policy too: without config.json it loads as TD3 (same network)
    "sbx.tqc": "tqc",
    "stable_baselines3.sac": "sac",
    "stable_baselines3.td3": "td3",
    "sb3_contrib.tqc": "tqc",
    "sb3_contrib.ppo_recurrent": "recurrentppo",
    "sb3_contrib.common.recurrent": "recurrentppo",
    "stable_baselines3.common.policies": "ppo",  # PPO and A2C share the actor-critic policy
    "agents.fused_ppo": "ppo",  # the jax backend's model file (agents.fused_ppo.export)
}


def _model_file(model_path: str | Path) -> Path:
    """The model file a path names: the file, or ``model.zip`` / ``final/model.zip`` inside a
    run directory; ``ValueError`` when there is none."""
    model_path = Path(model_path)
    if model_path.is_dir():
        inside = [model_path / "model.zip", model_path / "final" / "model.zip"]
        model_path = next((p for p in inside if p.is_file()), inside[0])
    if not model_path.is_file():
        raise ValueError(f"model file {str(model_path)!r} does not exist")
    return model_path


def trained_env_wrappers(model_path: str | Path) -> list[tuple[str, dict[str, Any]]]:
    """The Zoo ``env_wrapper`` list a saved model was trained behind (its run's ``config.json``;
    ``[]`` without one): a player applies those that change what the env receives (a safety
    shield's ``wrap_policy``) so that the model plays as it was trained."""
    saved = _run_config(_model_file(model_path))
    return zoo_objects("env_wrapper", ((saved or {}).get("hyperparams") or {}).get("env_wrapper"))


def _run_config(model_path: Path) -> dict[str, Any] | None:
    """The ``config.json`` of the run a saved model belongs to (beside it, or one level up for
    a ``best``/``final`` snapshot), or None."""
    for config in (model_path.parent / "config.json", model_path.parent.parent / "config.json"):
        if config.is_file():
            return read_json_file(config, "the run's config")
    return None


def _algo_of(model_path: Path, saved: dict[str, Any] | None) -> Algorithm:
    """The algorithm and backend of a saved model: from its run's config.json (``saved``, :func:`_run_config`), else from its policy's module."""
    if saved is not None:
        return Algorithm(saved["algo"], saved.get("backend", "sb3"))
    try:
        with zipfile.ZipFile(model_path) as zf:
            data = json.loads(zf.read("data").decode("utf-8"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{str(model_path)!r} is not a Stable-Baselines3 model file") from exc
    module = str(data.get("policy_class", {}).get("__module__", ""))
    for prefix, algo in _POLICY_MODULES.items():
        if module.startswith(prefix):
            return Algorithm(
                algo, "sbx" if prefix.startswith("sbx.") else "jax" if prefix.startswith("agents.") else "sb3"
            )
    raise ValueError(f"cannot tell the algorithm of {str(model_path)!r}; keep its config.json beside it")
