"""Re-solve a sample of the shipped J* table from today's code: the ``--per-env`` fastest
entries of every plant (different seeds, faults and kwargs), each against its committed value.

A change to a plant's equations, cost or limits that alters any episode's optimum shows here as
a relative difference; the plant definitions (one source for the numba, JAX and CasADi
executors) promise ≤ 1e-9. Each entry is written as it finishes, so an interrupted run resumes.

    python -m benchmarks.optimum_resolve --per-env 2 --out benchmarks/results/optimum_resolve.json
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

from benchmarks.results_file import write_results
from experiments import optimum, optimum_table


def sample(per_env: int) -> list[dict]:
    """The ``per_env`` fastest-to-solve shipped entries of each env id."""
    if per_env < 1:
        raise ValueError(f"per_env must be an integer >= 1, got {per_env!r}")
    entries = json.loads(optimum_table.shipped_table_path().read_text())["entries"]
    by_env: dict[str, list[dict]] = defaultdict(list)
    for entry in entries:
        by_env[entry["key"]["env_id"]].append(entry)
    return [e for env in sorted(by_env) for e in sorted(by_env[env], key=lambda e: e["solve_s"])[:per_env]]


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-env", type=int, default=2, help="entries per env id (fastest first)")
    parser.add_argument("--out", default="results/benchmarks/optimum_resolve.json")
    args = parser.parse_args(argv)
    out = Path(args.out)
    done = {}
    if out.is_file():
        done = {row["hash"]: row for row in json.loads(out.read_text()).get("rows", [])}
    rows = []
    for entry in sample(args.per_env):
        if entry["hash"] in done:
            rows.append(done[entry["hash"]])
            continue
        k = entry["key"]
        start = time.perf_counter()
        r = optimum.solve_episode(k["env_id"], k["env_kwargs"], k["seed"], k["options"], cache=False)
        rel = abs(r.j_star - entry["j_star"]) / abs(entry["j_star"])
        rows.append(
            {
                "hash": entry["hash"],
                "episode": entry["readable"],
                "solved": bool(r.solved),
                "j_star_shipped": entry["j_star"],
                "j_star_now": r.j_star,
                "relative_difference": rel,
                "solve_s": round(time.perf_counter() - start, 1),
            }
        )
        print(f"{entry['readable'][:90]}: rel diff {rel:.2e} ({rows[-1]['solve_s']} s)", flush=True)
        write_results(out, argv, rows=rows)
    worst = max(row["relative_difference"] for row in rows)
    summary = {"rows": rows, "worst_relative_difference": worst, "all_solved": all(r["solved"] for r in rows)}
    write_results(out, argv, **summary)
    print(f"worst relative difference {worst:.2e} over {len(rows)} entries")
    return summary


if __name__ == "__main__":
    main()
