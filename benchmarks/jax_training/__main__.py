"""``python -m benchmarks.jax_training``: the command line (:mod:`benchmarks.jax_training`)."""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import attitude_envs  # noqa: F401  (registers the ids)
import benchmarks.jax_training
from attitude_envs.files import atomic_write
from benchmarks.jax_training.checkpoint import Checkpoint, finite_or_none
from benchmarks.jax_training.children import FAST_COMPILE_ENV, no_compile_cache
from benchmarks.jax_training.quality import quality
from benchmarks.jax_training.search import search
from benchmarks.jax_training.speed import jax_device, speed
from benchmarks.jax_training.stepping import STEPPING_ENV_IDS, env_stepping
from benchmarks.jax_training.summary import markdown, targets
from benchmarks.jax_training.task import ENV_ID, ROOT, Task, campaign_task, recipe, say
from experiments.processes import pin_to_one_core


def _versions() -> dict[str, str | None]:
    from importlib import metadata

    out: dict[str, str | None] = {}
    for name in ("jax", "jaxlib", "flax", "optax", "sbx-rl", "stable_baselines3", "torch", "numpy", "numba"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.jax_training", description=benchmarks.jax_training.__doc__.split("\n\n")[0]
    )
    parser.add_argument("--quick", action="store_true", help="tiny budgets, fast compile (a smoke run)")
    parser.add_argument(
        "--rounds", type=int, default=None, help="alternating rounds of the timed comparisons (5; --quick 2)"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=None,
        help="training seeds 0..S-1 per backend in the quality section (3; --quick 1)",
    )
    parser.add_argument("--skip-quality", action="store_true", help="no quality section")
    parser.add_argument("--skip-search", action="store_true", help="no population search")
    parser.add_argument("--skip-stepping", action="store_true", help="no env-stepping section")
    parser.add_argument(
        "--no-all-cores", action="store_true", help="no all-cores fused rows (a child process that compiles again)"
    )
    parser.add_argument(
        "--speed-env",
        action="append",
        help=f"env id of the speed section (its ppo.yml recipe; default {ENV_ID}); repeat for more envs: the first "
        "gives the headline ratios, the others go to speed_other_envs (e.g. attitude_envs/LinearSystem-v1)",
    )
    parser.add_argument("--out", default="results/benchmarks", help="directory of jax_training.json")
    args = parser.parse_args(argv)
    args.seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    args.rounds = args.rounds if args.rounds is not None else (2 if args.quick else 5)
    if args.rounds < 1 or args.seeds < 1:
        parser.error(f"--rounds and --seeds must be >= 1, got {args.rounds} and {args.seeds}")
    out = Path(args.out) / "jax_training.json"
    for p in (out.parent, *out.parent.parents):
        if p.exists() and not p.is_dir():
            parser.error(f"--out {args.out!r} must be a directory; {str(p)!r} is a file")
    try:
        import sbx  # noqa: F401

        from experiments.training.algorithm import check_backend

        check_backend("jax", "ppo")
    except (ImportError, ValueError) as exc:
        print(f"error: this benchmark needs the sbx and jax extras ({exc})", file=sys.stderr)
        return 2

    saved = {
        k: os.environ.get(k) for k in (FAST_COMPILE_ENV, "JAX_COMPILATION_CACHE_DIR", "JAX_ENABLE_COMPILATION_CACHE")
    }
    try:
        return _run(args, out, list(sys.argv[1:] if argv is None else argv))
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run(args: argparse.Namespace, out: Path, argv: list[str]) -> int:
    start = time.perf_counter()
    no_compile_cache()
    if args.quick:
        os.environ[FAST_COMPILE_ENV] = "1"
    cpus = set(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else set()
    cpu = pin_to_one_core(0)  # before JAX starts its CPU backend: its thread pool follows the affinity
    pinned = f"one CPU (cpu {cpu}), torch 1 thread" if cpu is not None else "not pinned (no affinity call)"
    import jax

    jax.config.update("jax_enable_compilation_cache", False)
    from experiments.report.provenance import git_revision

    result: dict[str, Any] = {}
    task = campaign_task(ENV_ID)
    key = {"command": argv, "git_revision": git_revision(ROOT)}
    done = Checkpoint(out.with_name("jax_training.partial.json"), key)
    with tempfile.TemporaryDirectory(prefix="jax-training-benchmark-") as tmp:
        result |= _sections(args, task, Path(tmp), pinned, cpus, done)
    result["targets"] = targets(result)

    meta = {
        "machine": platform.platform(),
        "processor": platform.processor(),
        "python": platform.python_version(),
        "cores": os.cpu_count(),
        "cpus_available": sorted(cpus),
        "pinned": pinned,
        "jax_device": jax_device(),
        "versions": _versions(),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git_revision": git_revision(ROOT),
        "quick": bool(args.quick),
        "fast_compile": bool(args.quick),
        "persistent_compilation_cache": False,
        "rounds": args.rounds,
        "command": " ".join(["python -m benchmarks.jax_training", *argv]),
        "wall_s": time.perf_counter() - start + sum(done.section_wall_s.get(name, 0.0) for name in done.reused),
        "sections_from_an_earlier_run": done.reused,
    }
    result = {"meta": meta, **result}
    atomic_write(out, json.dumps(finite_or_none(result), indent=2, allow_nan=False) + "\n")
    done.path.unlink(missing_ok=True)
    print(markdown(result))
    print(f"\nwrote {out}")
    return 0


def _sections(
    args: argparse.Namespace, task: Task, workdir: Path, pinned: str, cpus: set[int], done: Checkpoint
) -> dict[str, Any]:
    """The sections the arguments ask for (run directories under ``workdir``), each through ``done``."""
    result: dict[str, Any] = {}

    rollouts = 2 if args.quick else 32
    for i, env_id in enumerate(args.speed_env or [ENV_ID]):
        speed_task = task if env_id == ENV_ID else campaign_task(env_id)
        all_cores = cpus if len(cpus) > 1 and i == 0 and not args.no_all_cores else None  # the first env's

        def run_speed(speed_task=speed_task, all_cores=all_cores) -> dict[str, Any]:
            say(f"speed: {speed_task.env_id}, {args.rounds} rounds of {rollouts} rollouts per seed")
            return speed(speed_task.env_id, speed_task.env_kwargs, rollouts, args.rounds, pinned, all_cores)

        sp = done.run(f"speed {env_id}", run_speed)
        if i == 0:
            result["ppo_per_seed_vs_sbx"] = sp["ppo_per_seed_vs_sbx"]
            result["ppo_16_seeds_vs_sbx"] = sp["ppo_16_seeds_vs_sbx"]
            result["speed"] = sp
        else:
            result.setdefault("speed_other_envs", []).append(sp)
    if not args.skip_quality:
        recipe_steps = int(float(recipe(ENV_ID)["n_timesteps"]))
        steps, eval_freq = (640, 320) if args.quick else (recipe_steps, 10_000)
        seeds = list(range(args.seeds))
        twin_cpus = cpus if len(cpus) > 1 and not args.no_all_cores else None
        result["quality"] = done.run(
            "quality",
            lambda: quality(task, seeds, steps, eval_freq, workdir / "quality", args.quick, twin_cpus),
        )
    if not args.skip_search:
        n, steps, evaluations, episodes = (
            (8, 640, 1, 2) if args.quick else (64, int(float(recipe(ENV_ID)["n_timesteps"])), 3, 10)
        )
        result["search"] = done.run("search", lambda: search(task, n, steps, evaluations, episodes, workdir))
    if not args.skip_stepping:
        sizes = (1, 64) if args.quick else (1, 64, 4096)

        def run_stepping() -> dict[str, Any]:
            say("env stepping")
            rows = env_stepping(STEPPING_ENV_IDS, sizes, 0.2 if args.quick else 1.0, args.rounds, 50, pinned)
            return {"rows": rows}

        result["env_stepping"] = done.run("env_stepping", run_stepping)["rows"]
    return result


if __name__ == "__main__":
    raise SystemExit(main())
