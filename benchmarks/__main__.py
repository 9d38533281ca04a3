"""``python -m benchmarks [--quick] [--out DIR]``: one table, JSON result in ``DIR/results.json``.

The default ``DIR`` is ``results/benchmarks/`` (git-ignored): a run never rewrites a tracked
file. The README's numbers come from ``benchmarks/results.json``, committed on purpose
(``python -m benchmarks --out benchmarks`` rewrites it). Rows are medians of alternating
rounds with their [min, max] spread (:mod:`benchmarks.env_speed`).
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import sys
import time
from pathlib import Path

from benchmarks import env_speed, q_learning_lqr
from experiments.progress import Progress

DEFAULT_OUT = "results/benchmarks"
KEYS = (
    "us_per_step",
    "ratio_to_reference",
    "steps_per_s",
    "ratio_to_cartpole_4096",
    "native_speedup",
    "episodes_per_s",
    "samples_to_1e-6",
    "wall_s",
)


def out_file(out: str | Path) -> Path:
    """``OUT/results.json``; ``ValueError`` when ``OUT`` (or a folder above it) is a file."""
    path = Path(out)
    for p in (path, *path.parents):
        if p.exists() and not p.is_dir():
            raise ValueError(f"--out {str(path)!r} must be a directory; {str(p)!r} is a file")
    return path / "results.json"


def _fmt(row: dict, key: str) -> str:
    value = row[key]
    text = f"{key}={value:.3g}" if isinstance(value, float) else f"{key}={value}"
    spread = row.get(f"{key}_range")
    if spread:
        text += f" [{spread[0]:.3g}–{spread[1]:.3g}]"
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter timing windows")
    parser.add_argument(
        "--out",
        default=DEFAULT_OUT,
        help=f"output directory (default {DEFAULT_OUT}/, git-ignored); writes results.json",
    )
    args = parser.parse_args(argv)
    try:
        path = out_file(args.out)  # before the work, not after it
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    seconds = 0.3 if args.quick else 1.5
    start = time.perf_counter()
    stages = [
        ("single envs", lambda: env_speed.single_env(seconds)),
        ("batched envs", lambda: env_speed.batched(seconds=seconds)),
        ("SB3 PPO", lambda: env_speed.sb3_ppo(2048 if args.quick else 8192)),
        ("evaluator", lambda: env_speed.evaluator(2 if args.quick else 5)),
        ("Q-learning LQR", lambda: q_learning_lqr.rows(quick=args.quick)),
    ]
    rows: list[dict] = []
    with Progress(len(stages), "benchmark stages", "stage") as bar:
        for name, stage in stages:
            bar.set_postfix(name)
            rows += stage()
            bar.update()
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    meta = {"machine": platform.platform(), "processor": platform.processor(), "python": platform.python_version()}
    meta.update({"peak_memory_mb": peak_mb, "wall_s": time.perf_counter() - start})
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"meta": meta, "rows": rows}, indent=2) + "\n", encoding="utf-8")
    print(f"{'benchmark':<16}{'env':<52}{'N':>6}  median [min–max] over rounds")
    for r in rows:
        result = ", ".join(_fmt(r, k) for k in KEYS if k in r)
        print(f"{r['benchmark']:<16}{r['env']:<52}{r.get('num_envs', ''):>6}  {result}")
    print(f"peak memory {peak_mb:.0f} MB, wall {meta['wall_s']:.0f} s, {meta['machine']}; wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
