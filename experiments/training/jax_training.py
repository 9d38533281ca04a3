"""``train(..., backend="jax")``: PPO with the fused JAX trainer (:mod:`agents.fused_ppo`) on the
JAX plant of the env (:func:`attitude_envs.jax.make`), in the run layout of
:func:`experiments.training.training.train`::

    config.json            as train's, with "backend": "jax"
    checkpoints/           step_<n>/{state.pkl, model.zip}, latest.json (the 2 newest)
    evaluations.csv        timesteps, J_mean, J_std of the periodic evaluations (numba envs, seeds eval_seed+i)
    best/                  model.zip + best.json: the snapshot with the lowest evaluation J
    final/                 model.zip + final.json when training completed
    timing.jsonl           per segment: from/to timesteps, wall time (s), compile time (s)

``model.zip`` is the fused-PPO model file (:mod:`agents.fused_ppo.export`: the actor and the
frozen observation statistics as numpy arrays); :func:`~experiments.training.training.load_trained`
loads it as a numpy predictor with SB3's ``predict``, so ``attitude-envs evaluate`` and
campaigns play it on the numba envs as any trained model.

Training runs in chunks of whole PPO updates (``n_steps × n_envs`` env steps each), one
compiled ``update_chunk`` call per chunk (its length is a traced argument: no recompilation);
a chunk ends at the first update at or after each multiple of ``eval_freq`` and
``checkpoint_freq`` and at the budget, as train's segments do. The checkpoint holds the
whole runner state (parameters, Adam moments, env states, normalization statistics, PRNG key),
so a resumed run continues exactly as the uninterrupted one (same program, same numbers): it
redoes at most the chunk it was killed in. The compiled programs are cached per env,
env kwargs and static configuration for the life of the process.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pickle
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from attitude_envs.make import make_checked
from experiments.jsonable import json_ready
from experiments.training.backends import check_backend
from experiments.training.callbacks import (
    EvalLog,
    atomic_write_text,
    evaluate_cost,
    new_checkpoint_dir,
    publish_checkpoint,
    read_json,
    save_snapshot,
)
from experiments.training.run_config import check_resume
from experiments.training.run_config import run_config as make_run_config
from experiments.training.vec_envs import batched_supported, make_eval_env

STATE_FILE = "state.pkl"  # the name experiments.training.checkpoint.latest_checkpoint looks for
#: set to 1: compile with XLA's backend optimization off (about a third less compile time, slower
#: steps; for tests and very short runs)
FAST_COMPILE_ENV = "ATTITUDE_ENVS_JAX_FAST_COMPILE"
CHECKPOINT_FORMAT = "fused-ppo-runner-state"

_PROGRAMS: dict[tuple, Any] = {}


def _jax():
    """jax and the trainer (``ValueError`` naming the extra when they are not installed)."""
    check_backend("jax", "ppo")
    import jax

    from agents.fused_ppo import trainer

    return jax, trainer


class Program:
    """The JAX plant of an env and its fused PPO program (:func:`agents.fused_ppo.make_chunked`),
    compiled ahead of time on first use; ``compile_s`` the seconds compiling took (once per
    process: :func:`program` caches it)."""

    def __init__(self, env, env_params, config, chunked, compiler_options: dict[str, Any] | None = None) -> None:
        self.env, self.env_params, self.config = env, env_params, config
        self.compiler_options = compiler_options
        self.init_fn, self.chunk_fn = chunked.init, chunked.update_chunk
        self._init = self._chunk = None
        self.compile_s = 0.0

    def _build(self, fn, *args):
        """``fn`` compiled ahead of time for ``args`` (arrays or their shapes)."""
        import jax

        return jax.jit(fn, compiler_options=self.compiler_options).lower(*args).compile()

    def _compile(self, fn, *args):
        start = time.perf_counter()
        compiled = self._build(fn, *args)
        self.compile_s += time.perf_counter() - start
        return compiled

    def compile(self, key, hparams) -> None:
        """Compile both programs now, ``init``'s on a second thread while this one traces and
        compiles ``update_chunk`` against ``init``'s abstract output (XLA compiles outside the GIL:
        on 2 cores the two overlap; on one they take the sum as before). Same programs, same results."""
        import threading

        import jax
        import jax.numpy as jnp

        if self._init is not None and self._chunk is not None:
            return
        start = time.perf_counter()
        errors: list[BaseException] = []

        def compile_init() -> None:
            try:
                if self._init is None:
                    self._init = self._build(self.init_fn, key, hparams)
            except BaseException as exc:  # re-raised on the caller's thread
                errors.append(exc)

        worker = threading.Thread(target=compile_init, name="compile-init")
        worker.start()
        try:
            if self._chunk is None:
                state = jax.eval_shape(self.init_fn, key, hparams)
                self._chunk = self._build(self.chunk_fn, state, hparams, jax.ShapeDtypeStruct((), jnp.int32))
        finally:
            worker.join()
        self.compile_s += time.perf_counter() - start
        if errors:
            raise errors[0]

    def init(self, key, hparams):
        """A fresh runner state (``hparams``: float32 :class:`~agents.fused_ppo.Hparams`)."""
        if self._init is None:
            self._init = self._compile(self.init_fn, key, hparams)
        return self._init(key, hparams)

    def update_chunk(self, state, hparams, n_updates: int):
        """``n_updates`` PPO updates: ``(state, chunk metrics)``."""
        import jax.numpy as jnp

        n = jnp.asarray(int(n_updates), jnp.int32)
        if self._chunk is None:
            self._chunk = self._compile(self.chunk_fn, state, hparams, n)
        return self._chunk(state, hparams, n)


def compiler_options() -> dict[str, Any] | None:
    """XLA options of the programs compiled now (:data:`FAST_COMPILE_ENV`), None: XLA's defaults."""
    fast = os.environ.get(FAST_COMPILE_ENV, "") not in ("", "0")
    return {"xla_backend_optimization_level": 0} if fast else None


def program(env_id: str, env_kwargs: dict[str, Any], config) -> Program:
    """The (cached) :class:`Program` of ``config`` on the JAX plant of ``env_id`` with ``env_kwargs``."""
    _, trainer = _jax()
    config = dataclasses.replace(config, total_timesteps=1)  # unused by the chunked form
    options = compiler_options()
    key = (env_id, json.dumps(json_ready(env_kwargs), sort_keys=True, default=repr), config, options is None)
    if key not in _PROGRAMS:
        try:
            from attitude_envs.jax import make
        except ImportError as exc:
            raise ValueError(f"backend 'jax': {exc}") from exc
        try:
            env, env_params = make(env_id, **env_kwargs)
        except ModuleNotFoundError as exc:
            raise ValueError(f"backend 'jax': {env_id} has no JAX plant yet ({exc})") from exc
        _PROGRAMS[key] = Program(env, env_params, config, trainer.make_chunked(env, env_params, config), options)
    return _PROGRAMS[key]


def export_policy(prog: Program, state, meta: dict[str, Any] | None = None):
    """The numpy predictor (:class:`agents.fused_ppo.NumpyPPOPolicy`) of an unbatched runner state."""
    from agents.fused_ppo.export import NumpyPPOPolicy
    from agents.fused_ppo.trainer import policy_arrays

    arrays = policy_arrays(state, prog.config, prog.env, prog.env_params)
    arrays.meta = dict(meta or {})
    return NumpyPPOPolicy(arrays)


class _Model:
    """What :func:`~experiments.training.callbacks.save_snapshot` writes: ``model.zip`` (no VecNormalize
    file: the statistics are inside the model file)."""

    def __init__(self, policy) -> None:
        self.policy = policy

    def save(self, path: Path) -> None:
        self.policy.save(path)

    def get_vec_normalize_env(self) -> None:
        return None


def _next_multiple(steps: int, every: int) -> int:
    return (steps // int(every) + 1) * int(every)


def _latest(out_dir: Path) -> dict[str, Any] | None:
    pointer = out_dir / "checkpoints" / "latest.json"
    if not pointer.is_file():
        return None
    data = json.loads(pointer.read_text(encoding="utf-8"))
    path = pointer.parent / data["dir"]
    if not (path / STATE_FILE).is_file():
        raise ValueError(f"checkpoint {str(path)!r} has no {STATE_FILE}: start the run again in an empty --out")
    return {"timesteps": int(data["timesteps"]), "path": path}


def write_checkpoint(root: Path, state, policy, run: dict[str, Any], keep: int = 2) -> Path:
    """The runner state (its leaves as numpy arrays), ``run`` bookkeeping and the portable model
    in ``root/step_<n>/``, then ``root/latest.json`` pointing at it (atomic, fsynced)."""
    import jax

    steps = int(state.timesteps)
    directory, tmp = new_checkpoint_dir(root, steps)
    policy.save(tmp / "model.zip")
    leaves = [np.asarray(x) for x in jax.tree.leaves(state)]
    payload = {"format": CHECKPOINT_FORMAT, "timesteps": steps, "leaves": leaves, "run": run}
    with (tmp / STATE_FILE).open("wb") as fh:
        pickle.dump(payload, fh, protocol=pickle.HIGHEST_PROTOCOL)
        fh.flush()
        os.fsync(fh.fileno())
    return publish_checkpoint(root, tmp, directory, steps, keep)


def read_checkpoint(directory: Path, prog: Program, key, hparams) -> tuple[Any, dict[str, Any]]:
    """``(runner state, run)`` of a checkpoint, its leaves put back into the program's state
    structure (``ValueError`` when they do not fit it: another configuration)."""
    import jax

    path = Path(directory) / STATE_FILE
    try:
        with path.open("rb") as fh:
            payload = pickle.load(fh)
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise ValueError(f"checkpoint {str(path)!r} cannot be read ({type(exc).__name__}: {exc})") from exc
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"checkpoint {str(path)!r} is not a fused-PPO checkpoint (a run of another backend?)")
    reference = jax.eval_shape(prog.init_fn, key, hparams)
    state = leaves_into(reference, payload["leaves"])
    if state is None:
        raise ValueError(f"checkpoint {str(path)!r} does not fit this run's configuration (env or network changed)")
    return state, payload["run"]


def leaves_into(reference, leaves: list[np.ndarray]):
    """``leaves`` (saved numpy arrays) put back into ``reference``'s pytree structure as jax
    arrays; None when their number, shapes or dtypes do not fit it (``reference``: a state or
    its ``jax.eval_shape``)."""
    import jax
    import jax.numpy as jnp

    shapes = jax.tree.leaves(reference)
    if len(leaves) != len(shapes) or any(
        tuple(a.shape) != tuple(r.shape) or a.dtype != r.dtype for a, r in zip(leaves, shapes, strict=True)
    ):
        return None
    return jax.tree.unflatten(jax.tree.structure(reference), [jnp.asarray(x) for x in leaves])


def _discard_partial_run(out_dir: Path) -> None:
    for name in ("evaluations.csv", "evaluations.csv.tmp"):
        (out_dir / name).unlink(missing_ok=True)
    for name in ("best", "best.tmp", "best.old", "final", "final.tmp", "final.old", "checkpoints"):
        if (out_dir / name).is_dir():
            shutil.rmtree(out_dir / name)


def _reconcile_best(best_dir: Path, best: dict[str, Any] | None, steps: int, policy) -> None:
    """``best/`` made the snapshot the checkpoint records (see training._reconcile_best)."""
    if best is None:
        if best_dir.exists():
            shutil.rmtree(best_dir)
        return
    if read_json(best_dir / "best.json") == best and (best_dir / "model.zip").is_file():
        return
    if int(best["timesteps"]) != steps:
        raise ValueError(
            f"{str(best_dir)!r} does not hold the best snapshot its checkpoint records ({best}); "
            "the run directory was changed by hand: start it again in an empty --out"
        )
    save_snapshot(_Model(policy), best_dir, meta={"best.json": json.dumps(best) + "\n"})


def train_jax(
    algo: str,
    env_id: str,
    out_dir: Path,
    entry: dict[str, Any],
    env_kwargs: dict[str, Any],
    eval_kwargs: dict[str, Any],
    seed: int,
    total_timesteps: int | None,
    schedule_timesteps: int | None,
    checkpoint_freq: int,
    eval_freq: int,
    eval_episodes: int,
    eval_seed: int,
    resume: bool,
    progress: bool | str,
    verbose: int,
    evaluate_initial: bool,
) -> dict[str, Any]:
    """:func:`experiments.training.training.train` for ``backend="jax"`` (called by it, arguments
    checked there; ``entry`` the Zoo entry with overrides). Returns the fields of its
    ``TrainResult``."""
    check_backend("jax", algo)
    jax, _ = _jax()
    from agents.fused_ppo.config import as_float32, from_zoo

    out_dir = Path(out_dir)
    for kwargs in (env_kwargs, eval_kwargs):  # validates the env kwargs before anything is written
        make_checked(env_id, **kwargs).close()
    total = int(total_timesteps if total_timesteps is not None else float(entry.get("n_timesteps", 1_000_000)))
    if total < 1:
        raise ValueError(f"total_timesteps must be >= 1, got {total}")
    horizon = total if schedule_timesteps is None else int(schedule_timesteps)
    if horizon < total:
        raise ValueError(f"schedule_timesteps must be >= total_timesteps ({total}), got {schedule_timesteps}")
    config, hparams = from_zoo(entry, total)
    hparams = as_float32(hparams._replace(schedule_timesteps=float(horizon)))
    saved = read_json(out_dir / "config.json")
    run_config = make_run_config(
        algo,
        "jax",
        env_id,
        env_kwargs,
        seed,
        entry,
        total,
        eval_freq,
        eval_episodes,
        eval_seed,
        eval_kwargs,
        checkpoint_freq,
    )
    checkpoint = _latest(out_dir)
    check_resume(out_dir, run_config, saved, checkpoint, resume)

    prog = program(env_id, env_kwargs, config)
    key = jax.random.PRNGKey(int(seed))
    meta = {"env_id": env_id, "algo": algo, "backend": "jax"}
    evaluations = EvalLog(out_dir)
    compiled_before = prog.compile_s
    if checkpoint is None:
        _discard_partial_run(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out_dir / "config.json", json.dumps(run_config, indent=2) + "\n")
        prog.compile(key, hparams)
        state = prog.init(key, hparams)
        run: dict[str, Any] = {"eval_log": "", "best": None, "last_eval": None}
        resumed_from = None
    else:
        state, run = read_checkpoint(checkpoint["path"], prog, key, hparams)
        evaluations.restore(run["eval_log"])
        steps = int(state.timesteps)
        _reconcile_best(out_dir / "best", run["best"], steps, export_policy(prog, state, {**meta, "timesteps": steps}))
        atomic_write_text(out_dir / "config.json", json.dumps(run_config, indent=2) + "\n")
        resumed_from = steps
    already_complete = int(state.timesteps) >= total

    eval_batched = batched_supported(env_id, probe := make_checked(env_id, **eval_kwargs))
    probe.close()
    eval_env = make_eval_env(env_id, eval_kwargs, int(eval_episodes), eval_batched)
    seeds = [int(eval_seed) + i for i in range(int(eval_episodes))]
    label = progress if isinstance(progress, str) else f"train {algo} (jax) {env_id.split('/')[-1]}"
    rollout = config.rollout_size
    planned = -(-total // rollout) * rollout
    if progress and resumed_from is None and planned != total:
        print(
            f"note: {algo} trains in whole rollouts of {rollout} env steps ({config.n_envs} envs): "
            f"a budget of {total} steps trains {planned}",
            file=sys.stderr,
            flush=True,
        )

    def policy_of(st):
        return export_policy(prog, st, {**meta, "timesteps": int(st.timesteps)})

    start = time.perf_counter()
    if evaluate_initial and run["best"] is None and int(state.timesteps) == 0:
        row = {"timesteps": 0, **evaluate_cost(policy_of(state), eval_env, seeds, name="ppo-jax")}
        text = evaluations.row_text(row, header=True)
        evaluations.append(text)
        run["eval_log"] += text
        run["best"], run["last_eval"] = row, row
        save_snapshot(_Model(policy_of(state)), out_dir / "best", meta={"best.json": json.dumps(row) + "\n"})
    try:
        while int(state.timesteps) < total:
            done = int(state.timesteps)
            target = min(_next_multiple(done, eval_freq), _next_multiple(done, checkpoint_freq), total)
            n_updates = -(-(target - done) // rollout)
            chunk_start = time.perf_counter()
            state, metrics = prog.update_chunk(state, hparams, n_updates)
            steps = int(state.timesteps)  # waits for the chunk
            if steps <= done:
                raise RuntimeError(f"fused PPO made no progress at {done} steps")
            new_best = False
            policy = policy_of(state)
            if steps // eval_freq > done // eval_freq or steps >= total:
                row = {"timesteps": steps, **evaluate_cost(policy, eval_env, seeds, name="ppo-jax")}
                text = evaluations.row_text(row, header=not run["eval_log"])
                evaluations.append(text)
                run["eval_log"] += text
                run["last_eval"] = row
                if run["best"] is None or row["J_mean"] < run["best"]["J_mean"]:
                    run["best"], new_best = row, True
                if verbose:
                    print(f"eval at {steps} steps: J = {row['J_mean']:.3f} ± {row['J_std']:.3f}")
            write_checkpoint(out_dir / "checkpoints", state, policy, run)
            if new_best:
                save_snapshot(_Model(policy), out_dir / "best", meta={"best.json": json.dumps(run["best"]) + "\n"})
            if progress:
                ret = float(metrics["episode_return"])
                rate = (steps - done) / max(time.perf_counter() - chunk_start, 1e-9)
                last = run["last_eval"] or {}
                print(
                    f"{label}: {steps}/{total} steps, {rate:.0f} steps/s, episode return "
                    f"{'n/a' if math.isnan(ret) else f'{ret:.4g}'}, eval J {last.get('J_mean', float('nan')):.4g}",
                    file=sys.stderr,
                    flush=True,
                )
    finally:
        eval_env.close()
    wall = time.perf_counter() - start
    if not already_complete:
        segment = {
            "from_timesteps": resumed_from or 0,
            "to_timesteps": int(state.timesteps),
            "wall_time_s": wall,
            "compile_s": prog.compile_s - compiled_before,
        }
        with (out_dir / "timing.jsonl").open("a", encoding="utf-8") as fh:
            fh.write(json.dumps(segment) + "\n")
    final = out_dir / "final"
    marker = {"timesteps": int(state.timesteps)}
    if read_json(final / "final.json") != marker or not (final / "model.zip").is_file():
        save_snapshot(_Model(policy_of(state)), final, meta={"final.json": json.dumps(marker) + "\n"})
    return {
        "out_dir": out_dir,
        "model_path": final / "model.zip",
        "timesteps": int(state.timesteps),
        "resumed_from": resumed_from,
        "wall_time_s": wall,
        "last_eval": run["last_eval"],
        "already_complete": already_complete,
    }
