"""Add J*'s own success-metric measurements to a J* table, keeping every ``j_star``.

``python -m experiments.optimum_measurements [--table PATH] [--env ENV ...] [--no-solve]``
runs :func:`experiments.optimum_table.add_measurements`: each entry without ``measurements``
gets them (and ``terminated``) by replaying its optimal actions from the solver's cache, else by
solving it again with the table's solver settings (deterministic: the same IPOPT run), and is
filled only when the J* it gets equals the table's to 1e-9 relative. The table is rewritten
atomically after every entry. Default envs: every one but FuelSlosh-v0 (its solves take
~100 s each), in :data:`~experiments.optimum_table.MEASURE_ORDER`. (The same as the flag
``attitude-envs optimum --add-measurements`` would run.)
"""

from __future__ import annotations

import argparse
import sys
import time

from experiments.optimum_table import MEASURE_ORDER, add_measurements


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv``, fill the table, print one line per entry and the counts per env."""
    parser = argparse.ArgumentParser(prog="python -m experiments.optimum_measurements", description=__doc__)
    parser.add_argument(
        "--table", default=None, help="the J* table (default: the shipped experiments/optimum_table.json)"
    )
    parser.add_argument("--env", action="append", choices=MEASURE_ORDER, help="env(s) to fill, in order (repeatable)")
    parser.add_argument("--no-solve", action="store_true", help="replay cached solutions only; solve nothing")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    counts = add_measurements(
        args.table,
        envs=args.env or MEASURE_ORDER[:-1],
        solve=not args.no_solve,
        progress=lambda msg: print(msg, flush=True),
    )
    for env, c in counts.items():
        print(f"{env}: " + ", ".join(f"{k} {v}" for k, v in c.items()), flush=True)
    print(f"done in {time.perf_counter() - start:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
