"""``python -m benchmarks [--quick] [--out FILE]``: one table, JSON result."""

from __future__ import annotations

import argparse
import json
import platform
import resource
import time

from benchmarks import env_speed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="shorter timing windows")
    parser.add_argument("--out", default="benchmarks/results.json", help="JSON output path")
    args = parser.parse_args(argv)
    seconds = 0.3 if args.quick else 1.5
    start = time.perf_counter()
    rows = (
        env_speed.single_env(seconds)
        + env_speed.batched(seconds=seconds)
        + env_speed.sb3_ppo(2048 if args.quick else 8192)
    )
    rows += env_speed.evaluator(2 if args.quick else 5)
    try:
        from benchmarks import q_learning_lqr  # added with the Q-learning LQR agent

        rows += q_learning_lqr.rows(quick=args.quick)
    except ImportError:
        pass
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    meta = {"machine": platform.platform(), "processor": platform.processor(), "python": platform.python_version()}
    meta.update({"peak_memory_mb": peak_mb, "wall_s": time.perf_counter() - start})
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump({"meta": meta, "rows": rows}, fh, indent=2)
    keys = [
        "us_per_step",
        "ratio_to_reference",
        "steps_per_s",
        "ratio_to_cartpole_4096",
        "native_speedup",
        "episodes_per_s",
        "samples_to_1e-6",
        "wall_s",
    ]
    print(f"{'benchmark':<16}{'env':<52}{'N':>6}  result")
    for r in rows:
        result = ", ".join(f"{k}={r[k]:.3g}" if isinstance(r[k], float) else f"{k}={r[k]}" for k in keys if k in r)
        print(f"{r['benchmark']:<16}{r['env']:<52}{r.get('num_envs', ''):>6}  {result}")
    print(f"peak memory {peak_mb:.0f} MB, wall {meta['wall_s']:.0f} s, {meta['machine']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
