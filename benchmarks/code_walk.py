"""How far a reader walks through the code to follow one campaign job: the product functions
``experiments.campaign.episode.run_job`` reaches, in the order each is first called, grouped
into *stays* (consecutive functions in one module, the *room*). A *re-entry* is a stay in a
room already visited: ``re-entries = stays − rooms``.

Rooms are the product's modules (``attitude_envs``, ``baselines``, ``agents``,
``experiments``); library code, numba-compiled kernels and import-time code (module and class
bodies) are not on the walk. Each function counts once, at its first call (comprehensions and
lambdas count as functions, as Python 3.11 runs them). The jobs are the quick campaign's: its
training job (256 steps) and one episode of every analytic agent, each in a fresh interpreter
so that no job finds another's caches filled.

    python -m benchmarks.code_walk [--verbose]      # ≈ 1 min on 2 cores
"""

from __future__ import annotations

import argparse
import inspect
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("attitude_envs", "baselines", "agents", "experiments")
_FUNCTION = inspect.CO_OPTIMIZED | inspect.CO_NEWLOCALS


def walk(job: dict[str, Any]) -> list[tuple[str, list[str]]]:
    """The stays of ``run_job(job)``: ``(module path, functions first called there)`` in order."""
    from experiments.campaign.episode import run_job

    prefixes = tuple(f"{ROOT / p}/" for p in PACKAGES)
    seen: set = set()
    stays: list[tuple[str, list[str]]] = []

    def profile(frame, event, arg) -> None:
        code = frame.f_code
        if event != "call" or code in seen or not code.co_filename.startswith(prefixes):
            return
        seen.add(code)
        if code.co_flags & _FUNCTION != _FUNCTION:  # a module or class body: import time
            return
        room = str(Path(code.co_filename).relative_to(ROOT))
        if stays and stays[-1][0] == room:
            stays[-1][1].append(code.co_name)
        else:
            stays.append((room, [code.co_name]))

    sys.setprofile(profile)
    try:
        run_job(job)
    finally:
        sys.setprofile(None)
    return stays


def summary(stays: list[tuple[str, list[str]]]) -> dict[str, int]:
    """``functions``, ``stays``, ``rooms`` and ``re_entries`` of a walk."""
    rooms = len({room for room, _ in stays})
    return {
        "functions": sum(len(names) for _, names in stays),
        "stays": len(stays),
        "rooms": rooms,
        "re_entries": len(stays) - rooms,
    }


def quick_jobs(out_dir: Path) -> dict[str, dict[str, Any]]:
    """The quick campaign's training job (shortened to 256 steps) and each analytic agent's
    first episode job, by name."""
    from experiments.campaign.jobs import episode_jobs, training_jobs
    from experiments.campaign.spec import load_campaign

    campaign = load_campaign("quick")
    train = dict(training_jobs(campaign, out_dir)[0])
    train.update(timesteps=256, checkpoint_freq=128, eval_freq=128, eval_episodes=1)
    jobs = {f"train {train['algo']} on {train['env_id'].split('/')[-1]}": train}
    for job in episode_jobs(campaign, out_dir):
        key = job["key"]
        name = f"episode {key['agent']} on {job['env_id'].split('/')[-1]}"
        if key["train_seed"] is None and name not in jobs:
            jobs[name] = job
    return jobs


def _walk_alone(name: str) -> list[tuple[str, list[str]]]:
    """The walk of the quick job ``name`` in a fresh interpreter: nothing cached by another job."""
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.code_walk", "--job", name],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    ).stdout
    return [tuple(stay) for stay in json.loads(out.splitlines()[-1])]


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.code_walk", description=__doc__.split("\n\n")[0])
    parser.add_argument("--verbose", action="store_true", help="print the longest walk, stay by stay")
    parser.add_argument("--job", help="walk this one job here and print its stays as JSON (each job runs so, alone)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        jobs = quick_jobs(Path(tmp))
        if args.job is not None:
            if args.job not in jobs:
                parser.error(f"--job must be one of {sorted(jobs)}, got {args.job!r}")
            print(json.dumps(walk(jobs[args.job])))
            return []
    walks = {name: _walk_alone(name) for name in jobs}
    rows = sorted(({"job": name, **summary(stays)} for name, stays in walks.items()), key=lambda r: -r["stays"])
    print(f"{'job':42s} {'functions':>9s} {'stays':>6s} {'rooms':>6s} {'re-entries':>10s}")
    for r in rows:
        print(f"{r['job']:42s} {r['functions']:9d} {r['stays']:6d} {r['rooms']:6d} {r['re_entries']:10d}")
    if args.verbose:
        for room, names in walks[rows[0]["job"]]:
            print(f"  {room}: {', '.join(names)}")
    return rows


if __name__ == "__main__":
    main()
