"""Training throughput: env steps/s of SB3 vs SBX (JAX), each on the native batched env and on
SB3's ``make_vec_env`` (DummyVecEnv), with the shipped Zoo hyperparameters; and the evaluation
callback's episodes, one by one vs as one batch.

``python -m benchmarks.training_throughput [--quick] [--env ID] [--out DIR]`` prints a table and
writes ``DIR/training_throughput.json`` (default ``results/benchmarks/``, git-ignored; the
committed numbers: ``--out benchmarks``). Every model is warmed up first (SBX compiles its update
on first use), then the variants of an algorithm alternate in rounds of equal env steps, so that
machine noise hits all alike; rows give the median steps/s and, against today's stack (SB3 on
DummyVecEnv), the median of the per-round ratios with their [min, max]. Both backends run on
one CPU (``torch.set_num_threads(1)`` and the process pinned to one core, which is what limits
JAX's thread pool, :func:`experiments.processes.pin_to_one_core`), as campaign workers do;
``--all-cores`` lets JAX use its default pool.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

import attitude_envs  # noqa: F401
from benchmarks.env_speed import _with_spread
from experiments.processes import pin_to_one_core
from experiments.training.algorithm import Algorithm
from experiments.training.callbacks import NormalizedPredictor, episode_costs
from experiments.training.hyperparams import load_hyperparams, split_hyperparams
from experiments.training.training import log_without_folder
from experiments.training.vec_envs import make_eval_env, make_training_env

REFERENCE = "sb3 DummyVecEnv"  # today's stack: what train() ran before the native env and SBX


def _sbx_installed() -> bool:
    try:
        Algorithm("ppo", "sbx").model_class()
    except ValueError:
        return False
    return True


def _model(algo: str, env_id: str, env_kwargs: dict, backend: str, native: bool, seed: int = 0):
    algorithm = Algorithm(algo, backend)
    entry = load_hyperparams(algorithm, env_id)
    probe = gym.make(env_id, **env_kwargs)
    hp = split_hyperparams(entry, int(np.prod(probe.action_space.shape)), algorithm)
    probe.close()
    if native:
        venv = make_training_env(env_id, env_kwargs, hp["n_envs"], seed, batched=True)
    else:  # exactly how train() built its envs before: SB3's make_vec_env (a Monitor and DummyVecEnv)
        venv = make_vec_env(env_id, n_envs=hp["n_envs"], seed=seed, env_kwargs={"render_mode": None, **env_kwargs})
    if hp["normalize"] is not None:
        venv = VecNormalize(venv, gamma=float(entry.get("gamma", 0.99)), **hp["normalize"])
    model = algorithm.model_class()(hp["policy"], venv, seed=seed, verbose=0, **hp["kwargs"])
    log_without_folder(model)
    return model


def rollout_steps(model) -> int:
    """Env steps per rollout: the granularity learn() works in."""
    if hasattr(model, "n_steps") and not hasattr(model, "replay_buffer"):
        return int(model.n_steps) * int(model.n_envs)
    return int(model.train_freq.frequency) * int(model.n_envs)


def training(algo: str, env_id: str, env_kwargs: dict, steps: int, rounds: int) -> list[dict]:
    """Steps/s of ``algo`` for every backend × env variant, alternating rounds of ``steps``."""
    backends = ["sb3", "sbx"] if _sbx_installed() else ["sb3"]
    models = {
        f"{backend} {'native' if native else 'DummyVecEnv'}": _model(algo, env_id, env_kwargs, backend, native)
        for backend in backends
        for native in (False, True)
    }
    per_round = max(steps, max(rollout_steps(m) for m in models.values()))
    for model in models.values():  # warm-up: past learning_starts, first update (SBX compiles it)
        model.learn(per_round + int(getattr(model, "learning_starts", 0)))
    rates: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(rounds):
        for name, model in models.items():
            start, done = time.perf_counter(), model.num_timesteps
            model.learn(per_round, reset_num_timesteps=False)
            rates[name].append((model.num_timesteps - done) / (time.perf_counter() - start))
    rows = []
    for name, values in rates.items():
        row = _with_spread({"benchmark": f"train {algo}", "env": env_id, "stack": name}, "steps_per_s", values)
        ratios = [v / r for v, r in zip(values, rates[REFERENCE], strict=True)]
        rows.append(_with_spread(row, "ratio_to_today", ratios))
    return rows


def evaluation(env_id: str, env_kwargs: dict, episodes: int, rounds: int) -> list[dict]:
    """Episodes/s of the evaluation callback's J: one predict per step of one episode (today)
    vs one predict per step for all ``episodes`` (the native batched eval env)."""
    model = _model("ppo", env_id, env_kwargs, "sb3", native=True)
    predictor = NormalizedPredictor(model, model.get_vec_normalize_env())
    envs = {
        REFERENCE.replace("DummyVecEnv", "one by one"): make_eval_env(env_id, env_kwargs, episodes, batched=False),
        "sb3 batched": make_eval_env(env_id, env_kwargs, episodes, batched=True),
    }
    seeds = list(range(10_000, 10_000 + episodes))
    for env in envs.values():
        episode_costs(predictor, env, seeds)  # warm-up
    rates: dict[str, list[float]] = {name: [] for name in envs}
    for _ in range(rounds):
        for name, env in envs.items():
            start = time.perf_counter()
            episode_costs(predictor, env, seeds)
            rates[name].append(episodes / (time.perf_counter() - start))
    reference = next(iter(rates.values()))
    rows = []
    for name, values in rates.items():
        row = _with_spread({"benchmark": "evaluate J", "env": env_id, "stack": name}, "episodes_per_s", values)
        rows.append(_with_spread(row, "ratio_to_today", [v / r for v, r in zip(values, reference, strict=True)]))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.training_throughput", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--quick", action="store_true", help="short rounds (a smoke test, not a measurement)")
    parser.add_argument("--env", default="attitude_envs/ReactionWheel-v0", help="env id (its shipped Zoo entries)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds per comparison (>= 1)")
    parser.add_argument("--out", default="results/benchmarks", help="directory of training_throughput.json")
    parser.add_argument(
        "--all-cores", action="store_true", help="do not pin to one CPU (JAX then uses a thread per core)"
    )
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error(f"--rounds must be >= 1, got {args.rounds}")
    out = Path(args.out) / "training_throughput.json"
    if out.parent.exists() and not out.parent.is_dir():
        parser.error(f"--out {args.out!r} must be a directory")
    torch.set_num_threads(1)
    if not args.all_cores:
        pin_to_one_core(0)  # as a campaign worker: JAX's thread pool follows the affinity
    env_kwargs = {"action_frame": "body"} if "ReactionWheel" in args.env else {}
    start = time.perf_counter()
    rows = training("ppo", args.env, env_kwargs, 4800 if args.quick else 48_000, args.rounds)
    rows += training("sac", args.env, env_kwargs, 200 if args.quick else 2000, args.rounds)
    rows += evaluation(args.env, env_kwargs, 5, args.rounds)
    meta = {"machine": platform.platform(), "python": platform.python_version(), "cores": os.cpu_count()}
    meta.update(
        {"env_kwargs": env_kwargs, "rounds": args.rounds, "quick": args.quick, "wall_s": time.perf_counter() - start}
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=2) + "\n", encoding="utf-8")
    print(f"{'benchmark':<12}{'stack':<20}{'rate (median [min-max])':>34}{'x today (median [min-max])':>32}")
    for r in rows:
        key = "steps_per_s" if "steps_per_s" in r else "episodes_per_s"
        lo, hi = r[f"{key}_range"]
        rlo, rhi = r["ratio_to_today_range"]
        rate = f"{r[key]:.1f} [{lo:.1f}-{hi:.1f}] {key.split('_')[0]}/s"
        ratio = f"{r['ratio_to_today']:.2f} [{rlo:.2f}-{rhi:.2f}]"
        print(f"{r['benchmark']:<12}{r['stack']:<20}{rate:>34}{ratio:>32}")
    print(f"{args.env} {env_kwargs}, {args.rounds} rounds, wall {meta['wall_s']:.0f} s; wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
