"""``train(..., backend="jax")``: PPO with the fused JAX trainer (:mod:`agents.fused_ppo`) on the
JAX plant of the env (:func:`attitude_envs.jax.make`), in the run directory of every backend
(:mod:`experiments.training.run_dir`): ``config.json`` says ``"backend": "jax"``, a checkpoint
holds ``state.pkl`` and ``model.zip``, ``evaluations.csv`` is played on the numba envs (seeds
eval_seed+i) and ``timing.jsonl`` also records each segment's compile time (s).

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
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments.jsonable import json_ready
from experiments.training.algorithm import Algorithm
from experiments.training.callbacks import evaluate_cost, new_checkpoint_dir, publish_checkpoint
from experiments.training.hyperparams import import_dotted, jax_wrappers, zoo_objects
from experiments.training.run_dir import STATE_FILE, RunDir, TrainResult
from experiments.training.vec_envs import make_eval_env

#: set to 1: compile with XLA's backend optimization off (about a third less compile time, slower
#: steps; for tests and very short runs)
FAST_COMPILE_ENV = "ATTITUDE_ENVS_JAX_FAST_COMPILE"
CHECKPOINT_FORMAT = "fused-ppo-runner-state"

_PROGRAMS: dict[tuple, Any] = {}


def _jax():
    """jax and the trainer (``ValueError`` naming the extra when they are not installed)."""
    Algorithm("ppo", "jax").trainable()
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


def wrapped_plant(env_id: str, env_kwargs: dict[str, Any], wrappers=()):
    """``(env, env_params)``: the JAX plant of ``env_id`` with ``env_kwargs``, wrapped by
    ``wrappers`` (:func:`~experiments.training.hyperparams.jax_wrappers` of a Zoo entry, innermost
    first)."""
    try:
        from attitude_envs.jax import make
    except ImportError as exc:
        raise ValueError(f"backend 'jax': {exc}") from exc
    try:
        env, env_params = make(env_id, **env_kwargs)
    except ModuleNotFoundError as exc:
        raise ValueError(f"backend 'jax': {env_id} has no JAX plant yet ({exc})") from exc
    for path, kwargs in wrappers:
        twin, kw = import_dotted(path), json.loads(kwargs)
        # a twin that needs the plant's own model (baselines.residual_jax.LQRResidual) is built from its keywords
        env = twin.for_plant(env, env_id, env_kwargs, **kw) if hasattr(twin, "for_plant") else twin(env, **kw)
    return env, env_params


def program(env_id: str, env_kwargs: dict[str, Any], config, wrappers=()) -> Program:
    """The (cached) :class:`Program` of ``config`` on the JAX plant of ``env_id`` with
    ``env_kwargs``, wrapped by ``wrappers`` (:func:`wrapped_plant`)."""
    _, trainer = _jax()
    config = dataclasses.replace(config, total_timesteps=1)  # unused by the chunked form
    options = compiler_options()
    wrappers = tuple(wrappers)
    key = (env_id, json.dumps(json_ready(env_kwargs), sort_keys=True, default=repr), config, wrappers, options is None)
    if key not in _PROGRAMS:
        env, env_params = wrapped_plant(env_id, env_kwargs, wrappers)
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


def train_jax(
    run_dir: RunDir, eval_batched: bool, progress: bool | str, verbose: int, evaluate_initial: bool
) -> TrainResult:
    """:func:`experiments.training.training.train`'s loop on the fused JAX trainer (called by it,
    arguments checked there): chunks of whole PPO updates that end at the plan's evaluations and
    checkpoints (``eval_batched``: whether the evaluation plays its episodes as one batch)."""
    jax, _ = _jax()
    from agents.fused_ppo.config import as_float32, from_zoo

    plan, out_dir = run_dir.plan, run_dir.path
    algo, env_id, total = plan.algorithm.name, plan.env_id, plan.total
    config, hparams = from_zoo(plan.entry, total, wrapped=True)  # program() wraps the plant
    hparams = as_float32(hparams._replace(schedule_timesteps=float(plan.horizon)))
    wrappers = jax_wrappers(plan.entry)
    prog = program(env_id, plan.env_kwargs, config, wrappers)
    key = jax.random.PRNGKey(plan.seed)
    meta = {"env_id": env_id, "algo": algo, "backend": "jax"}
    compiled_before = prog.compile_s
    if run_dir.checkpoint is None:
        run = run_dir.start()
        prog.compile(key, hparams)
        state = prog.init(key, hparams)
        resumed_from = None
    else:
        state, run = read_checkpoint(run_dir.checkpoint["path"], prog, key, hparams)
        steps = int(state.timesteps)
        run_dir.resume(run, steps, _Model(export_policy(prog, state, {**meta, "timesteps": steps})))
        resumed_from = steps
    already_complete = int(state.timesteps) >= total

    eval_env = make_eval_env(
        env_id,
        plan.eval_kwargs,
        plan.eval_episodes,
        eval_batched,
        zoo_objects("env_wrapper", plan.entry.get("env_wrapper")),
    )
    seeds = plan.eval_seeds
    label = progress if isinstance(progress, str) else f"train {algo} (jax) {env_id.split('/')[-1]}"
    rollout = config.rollout_size
    if progress and resumed_from is None:
        plan.note_whole_rollouts(rollout, config.n_envs)

    def policy_of(st):
        return export_policy(prog, st, {**meta, "timesteps": int(st.timesteps)})

    start = time.perf_counter()
    if evaluate_initial and run["best"] is None and int(state.timesteps) == 0:
        run_dir.record(run, {"timesteps": 0, **evaluate_cost(policy_of(state), eval_env, seeds, name="ppo-jax")})
        run_dir.save_best(run["best"], _Model(policy_of(state)))
    try:
        while int(state.timesteps) < total:
            done = int(state.timesteps)
            n_updates = -(-(plan.segment_end(done) - done) // rollout)
            chunk_start = time.perf_counter()
            state, metrics = prog.update_chunk(state, hparams, n_updates)
            steps = int(state.timesteps)  # waits for the chunk
            if steps <= done:
                raise RuntimeError(f"fused PPO made no progress at {done} steps")
            new_best = False
            policy = policy_of(state)
            if plan.evaluates(done, steps):
                row = {"timesteps": steps, **evaluate_cost(policy, eval_env, seeds, name="ppo-jax")}
                new_best = run_dir.record(run, row)
                if verbose:
                    print(f"eval at {steps} steps: J = {row['J_mean']:.3f} ± {row['J_std']:.3f}")
            write_checkpoint(out_dir / "checkpoints", state, policy, run)
            if new_best:
                run_dir.save_best(run["best"], _Model(policy))
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
    steps = int(state.timesteps)
    segment = None
    if not already_complete:
        segment = {
            "from_timesteps": resumed_from or 0,
            "to_timesteps": steps,
            "wall_time_s": wall,
            "compile_s": prog.compile_s - compiled_before,
        }
    model_path = run_dir.finish(segment, steps, lambda: _Model(policy_of(state)))
    return TrainResult(out_dir, model_path, steps, resumed_from, wall, run["last_eval"], already_complete)
