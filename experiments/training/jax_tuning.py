"""``attitude-envs tune --backend jax``: a population search with the fused JAX PPO trainer.

Where the optuna search (:mod:`experiments.training.tuning`) trains one trial after the other, this
one draws ``n_trials`` settings at random from the same search space
(:data:`experiments.training.tuning.PPO_SPACE`) and trains them side by side: the settings that
share the compiled program's shapes (rollout, minibatch, epochs, network) form a group,
trained by ``jax.vmap`` over their traced hyperparameters (learning rate, γ, GAE λ, clip
range, initial log-std) in one compiled program per group. By default every setting keeps
the entry's shapes (one group, one compilation) and only the traced hyperparameters are
drawn; ``shape_groups`` > 1 adds groups whose shapes are drawn too.

The budget is cut into ``n_evaluations`` segments; after each, every setting's policy is
evaluated on the numba env (the suite's evaluator, seeds ``eval_seed``+i, 10000+ by default:
the validation seeds, disjoint from the benchmark's 0–19). A setting's value is its best
evaluation J, as an optuna trial's; there is no pruning (all train together). Every setting
trains from the same seed (``seed``), as optuna trials do.

Writes ``OUT/trials.csv`` (number, state, value, last_step, group, param_* as optuna's),
``OUT/best.yml`` (the best setting's entry in the Zoo format) and ``OUT/population.json``
(groups with compile and training times, every setting's evaluations).

After each evaluation the search writes ``OUT/population-state.pkl`` (atomic): the group's
runner states and every evaluation so far. Run again with the same arguments, a killed search
resumes from its last evaluation and loses nothing already evaluated (on one machine the
result is the uninterrupted search's, bit for bit); another search's state in ``OUT`` is an
error that says so. A finished search run again writes its results without training.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import pickle
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from attitude_envs.files import atomic_write
from attitude_envs.make import make_checked
from experiments.training.algorithm import Algorithm
from experiments.training.callbacks import evaluate_cost
from experiments.training.hyperparams import jax_wrappers, load_hyperparams, zoo_objects
from experiments.training.jax_training import compiler_options, leaves_into, wrapped_plant
from experiments.training.tuning import PPO_SPACE, ppo_space, task_decisions
from experiments.training.vec_envs import batched_supported, make_eval_env

#: the search's state after its last evaluation, in its ``out_dir``
STATE_FILE = "population-state.pkl"
STATE_FORMAT = "population-search-state"

#: the search-space keys that fix the compiled program's shapes (drawn per group)
STATIC_KEYS = ("n_steps", "batch_size", "n_epochs", "width", "depth")


def _draw(rng: np.random.Generator, space: Any) -> Any:
    if isinstance(space, list):
        return space[int(rng.integers(len(space)))]
    kind, low, high = space
    if kind == "log":
        return float(math.exp(rng.uniform(math.log(low), math.log(high))))
    return float(rng.uniform(low, high))


def _policy_kwargs_text(pk: dict[str, Any]) -> str:
    """``policy_kwargs`` as the Zoo writes it: ``dict(key=value, …)`` (activations as ``nn.<Name>``)."""
    parts = []
    for k, v in pk.items():
        if k == "activation_fn":
            parts.append(f"{k}=nn.{getattr(v, '__name__', str(v)).rsplit('.', 1)[-1]}")
        elif isinstance(v, dict):
            parts.append(f"{k}={_policy_kwargs_text(v)}")
        else:
            parts.append(f"{k}={v!r}")
    return f"dict({', '.join(parts)})"


def draw_population(
    entry: dict[str, Any],
    n_trials: int,
    shape_groups: int,
    rng: np.random.Generator,
    space: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """``n_trials`` settings drawn from ``space`` (default :data:`~experiments.training.tuning.PPO_SPACE`;
    a task's: :func:`~experiments.training.tuning.ppo_space`): ``{"params": drawn values,
    "overrides": Zoo overrides}``. Setting ``i`` is in shape group ``i % shape_groups``; group 0
    keeps the entry's shapes, the others draw theirs (:data:`STATIC_KEYS`)."""
    from agents.fused_ppo.config import parse_literal

    space = space or PPO_SPACE
    base_pk = dict(parse_literal("policy_kwargs", entry.get("policy_kwargs")) or {})
    shapes = [{}] + [{k: _draw(rng, space[k]) for k in STATIC_KEYS} for _ in range(shape_groups - 1)]
    out = []
    for i in range(int(n_trials)):
        shape = shapes[i % shape_groups]
        params = {k: _draw(rng, values) for k, values in space.items() if k not in STATIC_KEYS}
        params |= shape
        pk = dict(base_pk)
        pk["log_std_init"] = float(f"{params['log_std_init']:.3g}")
        if shape:
            arch = [shape["width"]] * shape["depth"]
            pk["net_arch"] = {"pi": arch, "vf": arch}
        overrides = {k: shape[k] for k in ("n_steps", "batch_size", "n_epochs") if k in shape}
        overrides |= {
            "gamma": params["gamma"],
            "learning_rate": f"lin_{params['learning_rate']:.3g}",
            "gae_lambda": params["gae_lambda"],
            "clip_range": params["clip_range"],
            "policy_kwargs": _policy_kwargs_text(pk),
        }
        out.append({"params": params, "overrides": overrides})
    return out


def trained_params(drawn: dict[str, Any], config, hp) -> dict[str, Any]:
    """``drawn`` with each value replaced by the one the setting trains with: a fixed override
    (``--params``) wins over the draw, and ``trials.csv`` must say what was trained."""
    out = dict(drawn)
    for k in ("learning_rate", "gamma", "gae_lambda", "clip_range", "log_std_init"):
        if k in out:
            out[k] = float(getattr(hp, k))
    for k in ("n_steps", "batch_size", "n_epochs"):
        if k in out:
            out[k] = int(getattr(config, k))
    if "width" in out or "depth" in out:
        arch = config.pi_arch
        out["width"], out["depth"] = (arch[0] if arch else 0), len(arch)
    return out


def tune_population(
    algo: str,
    env_id: str,
    out_dir: str | Path,
    env_kwargs: dict[str, Any] | None = None,
    n_trials: int = 64,
    timesteps: int = 300_000,
    n_evaluations: int = 3,
    eval_episodes: int = 10,
    overrides: dict[str, Any] | None = None,
    seed: int = 0,
    sampler_seed: int = 0,
    shape_groups: int = 1,
    eval_seed: int = 10_000,
    hyperparams_file: str | Path | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Train ``n_trials`` PPO settings of ``env_id`` side by side for ``timesteps`` env steps each
    (module docstring); returns ``{"best_value", "best_overrides", "best_trial", "n_complete",
    "n_pruned", "groups"}`` and writes ``trials.csv``, ``best.yml`` and ``population.json``."""
    algorithm = Algorithm(algo, "jax").trainable()
    algo = algorithm.name
    for name, value, low in (("n_trials", n_trials, 1), ("timesteps", timesteps, 1), ("shape_groups", shape_groups, 1)):
        if int(value) < low:
            raise ValueError(f"{name} must be >= {low}, got {value!r}")
    if not 1 <= int(n_evaluations) <= int(timesteps):
        raise ValueError(f"n_evaluations must be in [1, timesteps], got {n_evaluations!r}")
    if int(shape_groups) > int(n_trials):
        raise ValueError(f"shape_groups must be <= n_trials ({n_trials}), got {shape_groups}")
    import jax

    from agents.fused_ppo.config import from_zoo, stack_hparams
    from agents.fused_ppo.export import NumpyPPOPolicy
    from agents.fused_ppo.trainer import make_chunked, policy_arrays, select

    env_kwargs = dict(env_kwargs or {})
    fixed = {**dict(overrides or {}), "backend": "jax"}
    entry = load_hyperparams(algorithm, env_id, hyperparams_file, fixed)
    budget = int(timesteps)
    space = ppo_space(task_decisions(env_id, env_kwargs))  # γ within the task's episode
    trials = draw_population(entry, int(n_trials), int(shape_groups), np.random.default_rng(int(sampler_seed)), space)
    groups: dict[Any, list[int]] = {}
    for i, t in enumerate(trials):
        t["overrides"] = {**t["overrides"], **dict(overrides or {})}  # the fixed ones win
        config, hp = from_zoo({**entry, **t["overrides"]}, budget, wrapped=True)  # wrapped_plant below
        t["config"], t["hparams"] = config, hp._replace(schedule_timesteps=float(budget))
        t["params"] = trained_params(t["params"], config, hp)
        groups.setdefault(config, []).append(i)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    env, env_params = wrapped_plant(env_id, env_kwargs, jax_wrappers(entry))
    probe = make_checked(env_id, **env_kwargs)
    wrappers = zoo_objects("env_wrapper", entry.get("env_wrapper"))
    eval_env = make_eval_env(
        env_id, env_kwargs, int(eval_episodes), batched_supported(env_id, probe) and not wrappers, wrappers
    )
    probe.close()
    seeds = [int(eval_seed) + i for i in range(int(eval_episodes))]
    every = max(1, budget // int(n_evaluations))
    key = jax.random.PRNGKey(int(seed))
    identity = _search_identity(algo, env_id, env_kwargs, entry, trials, budget, n_evaluations, seeds, seed)
    saved = _read_state(out, identity)
    group_rows: list[dict[str, Any]] = list(saved["group_rows"]) if saved else []
    if saved:
        for t, kept in zip(trials, saved["trials"], strict=True):
            t["evaluations"], t["group"] = kept["evaluations"], kept["group"]
        if progress:
            print(
                f"tune (jax): resuming from {out / STATE_FILE} (group {saved['group'] + 1}, "
                f"{saved['segment']} of {n_evaluations} evaluations done)",
                file=sys.stderr,
                flush=True,
            )

    def save(g: int, segment: int, state, train_s: float, eval_s: float) -> None:
        leaves = None if state is None else [np.asarray(x) for x in jax.tree.leaves(state)]
        payload = {
            "format": STATE_FORMAT,
            "identity": identity,
            "group": g,
            "segment": segment,
            "leaves": leaves,
            "train_s": train_s,
            "eval_s": eval_s,
            "group_rows": group_rows,
            "trials": [{"evaluations": t["evaluations"], "group": t["group"]} for t in trials],
        }
        _write_state(out, payload)

    try:
        for g, (config, members) in enumerate(groups.items()):
            if g < len(group_rows):
                continue  # trained and evaluated before the search was resumed
            chunked = make_chunked(env, env_params, config)
            hps = stack_hparams([trials[i]["hparams"] for i in members])
            start = time.perf_counter()
            options = compiler_options()
            init = (
                jax.jit(jax.vmap(chunked.init, in_axes=(None, 0)), compiler_options=options).lower(key, hps).compile()
            )
            state = init(key, hps)
            n0 = jax.numpy.asarray(1, jax.numpy.int32)
            vchunk = jax.vmap(chunked.update_chunk, in_axes=(0, 0, None))
            chunk = jax.jit(vchunk, compiler_options=options).lower(state, hps, n0).compile()
            compile_s = time.perf_counter() - start
            if progress:
                print(
                    f"tune (jax) group {g + 1}/{len(groups)}: {len(members)} settings compiled in {compile_s:.1f} s, "
                    f"training {budget} steps each",
                    file=sys.stderr,
                    flush=True,
                )
            train_s = eval_s = 0.0
            first = 1
            if saved and saved["group"] == g and saved["leaves"] is not None:
                state = _restore(state, saved["leaves"], out)
                first, train_s, eval_s = int(saved["segment"]) + 1, float(saved["train_s"]), float(saved["eval_s"])
            else:
                for i in members:
                    trials[i]["evaluations"], trials[i]["group"] = [], g
            for k in range(first, int(n_evaluations) + 1):
                target = every * k if k < int(n_evaluations) else budget
                done = int(np.asarray(state.timesteps)[0])
                n_updates = -(-(target - done) // config.rollout_size)
                if n_updates > 0:
                    t0 = time.perf_counter()
                    state, _ = chunk(state, hps, jax.numpy.asarray(n_updates, jax.numpy.int32))
                    steps = int(np.asarray(state.timesteps)[0])  # waits for the chunk
                    train_s += time.perf_counter() - t0
                t0 = time.perf_counter()
                steps = int(np.asarray(state.timesteps)[0])
                for j, i in enumerate(members):
                    policy = NumpyPPOPolicy(policy_arrays(select(state, j), config, env, env_params))
                    row = evaluate_cost(policy, eval_env, seeds, name="ppo-jax")
                    trials[i]["evaluations"].append({"timesteps": steps, **row})
                eval_s += time.perf_counter() - t0
                save(g, k, state, train_s, eval_s)
                if progress:
                    best = min((_value(trials[i]) for i in members), default=math.inf)
                    print(
                        f"tune (jax) group {g + 1}/{len(groups)} ({len(members)} settings): {steps}/{budget} steps, "
                        f"best eval J so far {best:.4g}",
                        file=sys.stderr,
                        flush=True,
                    )
            steps = int(np.asarray(state.timesteps)[0])
            group_rows.append(
                {
                    "group": g,
                    "settings": len(members),
                    "n_steps": config.n_steps,
                    "batch_size": config.batch_size,
                    "n_epochs": config.n_epochs,
                    "pi_arch": list(config.pi_arch),
                    "vf_arch": list(config.vf_arch),
                    "timesteps_per_setting": steps,
                    "compile_s": compile_s,
                    "train_s": train_s,
                    "eval_s": eval_s,
                    "env_steps_per_s": steps * len(members) / train_s if train_s > 0 else None,
                }
            )
            save(g + 1, 0, None, 0.0, 0.0)  # the group is done: a resumed search skips it
    finally:
        eval_env.close()
    return _write_results(trials, group_rows, out, algo, env_id, budget, seed, seeds)


def _search_identity(algo, env_id, env_kwargs, entry, trials, budget, n_evaluations, seeds, seed) -> str:
    """A digest of everything that decides the search's results (its state belongs to it only)."""
    what = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "entry": entry,
        "settings": [t["overrides"] for t in trials],
        "timesteps": budget,
        "n_evaluations": int(n_evaluations),
        "eval_seeds": seeds,
        "seed": int(seed),
    }
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=repr).encode()).hexdigest()


def _read_state(out: Path, identity: str) -> dict[str, Any] | None:
    """The saved state of this search in ``out``, None when there is none (``ValueError`` when
    ``out`` holds another search's, or a file that is not one)."""
    path = out / STATE_FILE
    if not path.is_file():
        return None
    try:
        with path.open("rb") as fh:
            payload = pickle.load(fh)
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise ValueError(
            f"{str(path)!r} cannot be read ({type(exc).__name__}: {exc}); remove it to start over"
        ) from exc
    if not isinstance(payload, dict) or payload.get("format") != STATE_FORMAT:
        raise ValueError(f"{str(path)!r} is not a population search's state; remove it to start over")
    if payload["identity"] != identity:
        raise ValueError(
            f"--out {str(out)!r} holds another search's state (other env, settings, budget, evaluations or "
            f"seeds): use another --out, or remove {STATE_FILE} to start over"
        )
    return payload


def _write_state(out: Path, payload: dict[str, Any]) -> None:
    atomic_write(out / STATE_FILE, pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL), durable=True)


def _restore(state, leaves: list[np.ndarray], out: Path):
    """``leaves`` put back into ``state``'s structure (``ValueError`` when they do not fit it)."""
    restored = leaves_into(state, leaves)
    if restored is None:
        raise ValueError(f"{str(out / STATE_FILE)!r} does not fit this search's programs; remove it to start over")
    return restored


def _value(trial: dict[str, Any]) -> float:
    finite = [e["J_mean"] for e in trial.get("evaluations", []) if math.isfinite(e["J_mean"])]
    return min(finite) if finite else math.inf


def _write_results(trials, group_rows, out: Path, algo, env_id, budget, seed, seeds) -> dict[str, Any]:
    rows = []
    for i, t in enumerate(trials):
        last = t["evaluations"][-1]["timesteps"] if t["evaluations"] else None
        value = _value(t)
        rows.append(
            {
                "number": i,
                "state": "COMPLETE" if math.isfinite(value) else "FAIL",
                "value": value if math.isfinite(value) else None,
                "last_step": last,
                "group": t["group"],
                **{f"param_{k}": v for k, v in t["params"].items()},
            }
        )
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / "trials.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    ranking = sorted(range(len(trials)), key=lambda i: _value(trials[i]))
    report = {
        "algo": algo,
        "backend": "jax",
        "env_id": env_id,
        "timesteps": budget,
        "seed": int(seed),
        "eval_seeds": seeds,
        "groups": group_rows,
        "ranking": ranking,
        "trials": [
            {"number": i, "group": t["group"], "overrides": t["overrides"], "evaluations": t["evaluations"]}
            for i, t in enumerate(trials)
        ],
    }
    (out / "population.json").write_text(json.dumps(report, indent=2, default=float) + "\n", encoding="utf-8")
    complete = [i for i in ranking if math.isfinite(_value(trials[i]))]
    summary: dict[str, Any] = {
        "n_complete": len(complete),
        "n_pruned": 0,
        "best_value": None,
        "best_overrides": None,
        "groups": group_rows,
    }
    if complete:
        best = complete[0]
        summary.update(best_value=_value(trials[best]), best_overrides=trials[best]["overrides"], best_trial=best)
        entry = {env_id: {**trials[best]["overrides"], "backend": "jax"}}
        header = (
            f"# population search ({algo}, jax): setting {best} of {len(trials)}, best eval J "
            f"{_value(trials[best]):.6g}; see trials.csv\n"
        )
        (out / "best.yml").write_text(header + yaml.safe_dump(entry, sort_keys=False), encoding="utf-8")
    return summary
