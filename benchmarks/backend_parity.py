"""Backend parity: does SBX (JAX) learn as well as SB3 (PyTorch) at the full training budget?

Reads the episodes of the parity campaign (``benchmarks/backend_parity.yml``: PPO and SAC on
each backend, 3 training seeds, every model's best eval snapshot on the same 20 episodes) and
writes ``benchmarks/backend_parity.{json,md}``::

    attitude-envs benchmark --config benchmarks/backend_parity.yml --out results/backend-parity --workers 2
    python -m benchmarks.backend_parity results/backend-parity [--out benchmarks]

Per algorithm and backend: each training seed's mean J over the 20 episodes, the mean over
seeds and the seeds' spread [min, max]. **Decision rule** (the campaigns' choice of backend):
SBX is used for an algorithm when its mean J over seeds lies within SB3's seed spread or
below it (mean_sbx <= max over SB3's seeds) and exact resume holds for it (the chaos test);
otherwise SB3. The LQR's J on the same episodes is the reference.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np


def seed_means(rows: list[dict], agent: str) -> dict[int, float]:
    """Training seed → mean J over its episodes, for ``agent``."""
    by_seed: dict[int, list[float]] = {}
    for r in rows:
        if r["agent"] == agent:
            by_seed.setdefault(int(r["train_seed"]), []).append(float(r["J"]))
    return {seed: float(np.mean(js)) for seed, js in sorted(by_seed.items())}


def parity(rows: list[dict], algos=("ppo", "sac")) -> dict:
    lqr = [float(r["J"]) for r in rows if r["agent"] == "lqr"]
    out = {"lqr_J_mean": float(np.mean(lqr)) if lqr else None, "episodes": len(lqr), "algorithms": {}}
    for algo in algos:
        entry = {}
        for backend in ("sb3", "sbx"):
            means = seed_means(rows, f"{algo}-{backend}")
            values = list(means.values())
            entry[backend] = {
                "seed_J_means": means,
                "J_mean": float(np.mean(values)) if values else None,
                "J_range": [min(values), max(values)] if values else None,
            }
        sb3, sbx = entry["sb3"], entry["sbx"]
        complete = bool(sb3["seed_J_means"]) and bool(sbx["seed_J_means"])
        entry["sbx_within_sb3_spread_or_better"] = complete and sbx["J_mean"] <= sb3["J_range"][1]
        entry["ratio_sbx_to_sb3"] = sbx["J_mean"] / sb3["J_mean"] if complete else None
        out["algorithms"][algo] = entry
    return out


def markdown(result: dict) -> str:
    lines = [
        "| algorithm | backend | J per training seed (mean of 20 episodes) | mean over seeds | spread [min, max] | J / J_LQR |",
        "|---|---|---|---:|---|---:|",
    ]
    lqr = result["lqr_J_mean"]
    for algo, entry in result["algorithms"].items():
        for backend in ("sb3", "sbx"):
            e = entry[backend]
            if e["J_mean"] is None:
                lines.append(f"| {algo} | {backend} | (not run) | | | |")
                continue
            seeds = ", ".join(f"{s}: {j:.1f}" for s, j in e["seed_J_means"].items())
            lo, hi = e["J_range"]
            ratio = f"{e['J_mean'] / lqr:.3f}" if lqr else "—"
            lines.append(f"| {algo} | {backend} | {seeds} | {e['J_mean']:.1f} | [{lo:.1f}, {hi:.1f}] | {ratio} |")
    lines.append(f"| lqr (exact ZOH) | — | — | {lqr:.1f} | deterministic per episode | 1 |" if lqr else "")
    lines.append("")
    for algo, entry in result["algorithms"].items():
        verdict = (
            "SBX within SB3's seed spread or better"
            if entry["sbx_within_sb3_spread_or_better"]
            else "SBX worse than SB3's worst seed"
        )
        ratio = entry["ratio_sbx_to_sb3"]
        lines.append(f"* {algo}: {verdict}" + (f" (mean J ratio SBX / SB3 = {ratio:.3f})" if ratio else "") + ".")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.backend_parity", description=__doc__.split("\n\n")[0])
    parser.add_argument("results", help="the parity campaign's --out directory (its episodes.csv)")
    parser.add_argument("--out", default="results/benchmarks", help="directory of backend_parity.{json,md}")
    args = parser.parse_args(argv)
    episodes = Path(args.results) / "episodes.csv"
    if not episodes.is_file():
        parser.error(f"{str(episodes)!r} does not exist: run the parity campaign first (see --help)")
    with episodes.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    result = parity(rows)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "backend_parity.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    text = markdown(result)
    (out / "backend_parity.md").write_text(text, encoding="utf-8")
    print(text, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
