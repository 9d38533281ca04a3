"""Does a fresh ``benchmark --config all`` repeat the committed campaign pages? Row by row (env,
scenario, fault, agent), each episode's J in the rerun against the page's, and ΣJ / ΣJ* both
ways; with how long each page of the rerun took (its ``runs.jsonl``).

A row is *learned* when its episodes carry a training seed. Analytic rows should repeat to
rounding; learned rows repeat bit for bit only when their models were trained by the same code
(the pages' models may come from earlier commits than the rerun's).

    attitude-envs benchmark --config all --out results/all             # ≈ 96 min on 2 cores
    python -m benchmarks.page_rerun --rerun results/all --out benchmarks/results/page_rerun.json  # ≈ 5 s
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

from benchmarks.results_file import write_results
from experiments.report.overview import read_episodes

ROOT = Path(__file__).resolve().parent.parent
PAGES = ROOT / "docs" / "campaigns"
#: a row whose episodes all agree to this relative |ΔJ| counts as repeated
REPEATED = 1e-9


def _episodes(path: Path) -> dict[tuple[str, ...], dict[tuple[Any, Any], tuple[float, float]]]:
    """``{(env, scenario, fault, agent): {(train_seed, seed): (J, J*)}}`` of an episodes.csv
    (:func:`~experiments.report.overview.read_episodes`; J* NaN where the row has none)."""
    rows: dict = defaultdict(dict)
    for r in read_episodes(path):
        key = (r["env"], r["scenario"], r["fault"], r["agent"])
        j_star = math.nan if r["j_star"] is None else float(r["j_star"])
        rows[key][(r["train_seed"], r["seed"])] = (float(r["J"]), j_star)
    return rows


def _ratio(episodes: dict, keys: list) -> float | None:
    """ΣJ / ΣJ* over ``keys`` (sorted, so that the sum repeats); None where it is not finite."""
    if not keys:
        return None
    ratio = sum(episodes[k][0] for k in keys) / sum(episodes[k][1] for k in keys)
    return ratio if math.isfinite(ratio) else None


def compare_page(page: Path, rerun: Path) -> dict[str, Any]:
    """The rows of one page (``page``/episodes.csv) against the rerun's (``rerun``/episodes.csv)
    and the rerun's minutes (the ``end`` events of its runs.jsonl; None without one)."""
    a, b = _episodes(page / "episodes.csv"), _episodes(rerun / "episodes.csv")
    rows = []
    for key in sorted(set(a) & set(b)):
        common = sorted(set(a[key]) & set(b[key]))
        rel = [abs(a[key][k][0] - b[key][k][0]) / max(abs(a[key][k][0]), 1e-300) for k in common]
        rows.append(
            {
                "env": key[0],
                "scenario": key[1],
                "fault": key[2],
                "agent": key[3],
                "learned": any(train_seed is not None for train_seed, _ in set(a[key]) | set(b[key])),
                "episodes": len(common),
                "episodes_only_page": len(set(a[key]) - set(b[key])),
                "episodes_only_rerun": len(set(b[key]) - set(a[key])),
                # None: no episode in common, or a J that is not finite on one side
                "max_relative_dj": max(rel) if rel and all(math.isfinite(r) for r in rel) else None,
                "page_j_over_j_star": _ratio(a[key], common),
                "rerun_j_over_j_star": _ratio(b[key], common),
            }
        )
    runs = rerun / "runs.jsonl"
    events = [json.loads(line) for line in runs.read_text().splitlines()] if runs.is_file() else []
    ends = [e for e in events if e.get("event") == "end"]
    return {
        "rows": rows,
        "only_page": ["/".join(k) for k in sorted(set(a) - set(b))],
        "only_rerun": ["/".join(k) for k in sorted(set(b) - set(a))],
        "wall_min": round(sum(e["wall_time_s"] for e in ends) / 60, 1) if ends else None,
    }


def repeated(row: dict[str, Any]) -> bool:
    """Every episode of ``row`` on both sides, each J within :data:`REPEATED` relative."""
    dj = row["max_relative_dj"]
    return dj is not None and dj <= REPEATED and not row["episodes_only_page"] and not row["episodes_only_rerun"]


def _worst_first(dj: float | None) -> float:
    """Orders relative differences, None (not comparable) above every number."""
    return math.inf if dj is None else dj


def summary(pages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Per page: its rerun's minutes and how many analytic and learned rows repeated; the worst
    relative ΔJ of an episode among the analytic rows that repeated, and among all of them."""
    out = []
    for name, p in pages.items():
        analytic = [r for r in p["rows"] if not r["learned"]]
        kept = [r for r in analytic if repeated(r)]
        learned = [r for r in p["rows"] if r["learned"]]
        out.append(
            {
                "page": name,
                "wall_min": p["wall_min"],
                "analytic_rows": len(analytic),
                "analytic_repeated": len(kept),
                "analytic_repeated_worst": max((r["max_relative_dj"] for r in kept), default=0.0),
                "analytic_worst": max((r["max_relative_dj"] for r in analytic), key=_worst_first, default=0.0),
                "learned_rows": len(learned),
                "learned_repeated": sum(repeated(r) for r in learned),
                "missing_rows": len(p["only_page"]) + len(p["only_rerun"]),
            }
        )
    return out


def _text(dj: float | None) -> str:
    return "not comparable" if dj is None else f"{dj:.1e}"


def _pages_in(folder: Path) -> set[str]:
    """The page folders of ``folder`` (those with an episodes.csv)."""
    return {p.name for p in folder.iterdir() if (p / "episodes.csv").is_file()} if folder.is_dir() else set()


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rerun", required=True, help="a `benchmark --config all` output folder")
    parser.add_argument("--pages", default=str(PAGES), help="the committed pages (default: docs/campaigns)")
    parser.add_argument("--out", default="results/benchmarks/page_rerun.json")
    args = parser.parse_args(argv)
    rerun, committed = Path(args.rerun), Path(args.pages)
    ran, shipped = _pages_in(rerun), _pages_in(committed)
    names = sorted(ran & shipped)
    if not names:
        raise SystemExit(f"error: no page of {str(committed)!r} has an episodes.csv in {str(rerun)!r}")
    pages = {name: compare_page(committed / name, rerun / name) for name in names}
    table = summary(pages)
    print(
        "| page | run (min) | analytic rows repeated (their worst ΔJ/J) | worst analytic ΔJ/J | learned rows repeated |"
    )
    print("|---|---|---|---|---|")
    for s in table:
        print(
            f"| {s['page']} | {s['wall_min']} | {s['analytic_repeated']} of {s['analytic_rows']} "
            f"({s['analytic_repeated_worst']:.1e}) | {_text(s['analytic_worst'])} | "
            f"{s['learned_repeated']} of {s['learned_rows']} |"
        )
    walls = [s["wall_min"] for s in table if s["wall_min"] is not None]
    print(f"the pages' runs: {sum(walls):.1f} min (their runs.jsonl: without the reports and the start-up)")
    unpaired = {"pages_only_rerun": sorted(ran - shipped), "pages_only_committed": sorted(shipped - ran)}
    for key, value in unpaired.items():
        if value:
            print(f"{key.replace('_', ' ')}: {', '.join(value)}")
    write_results(args.out, argv, summary=table, **unpaired, pages=pages)
    return {"summary": table, **unpaired, "pages": pages}


if __name__ == "__main__":
    main()
