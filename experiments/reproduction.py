"""The shared output of every paper reproduction: JSON + markdown, paper value vs. ours.

Schema (one for all papers)::

    {"paper": id, "source": citation, "rows": [{"case": str, "controller": str,
     "metric": str, "paper": float|null, "ours": float, "tolerance": float|null}],
     "notes": str}

``source`` is the reproduced paper's citation (authors, year, title, journal as far as our
copy shows them; the paper pages under ``docs/papers/`` give the full entries).

``tolerance`` is the relative tolerance claimed (``null`` where the paper's figure cannot
be reproduced; the notes say why).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

from attitude_envs.files import atomic_write


@dataclass(frozen=True)
class Row:
    case: str
    controller: str
    metric: str
    paper: float | None
    ours: float
    tolerance: float | None

    @property
    def relative_error(self) -> float | None:
        if self.paper is None or self.paper == 0:
            return None
        return abs(self.ours - self.paper) / abs(self.paper)

    @property
    def within(self) -> bool | None:
        err = self.relative_error
        return None if err is None or self.tolerance is None else err <= self.tolerance


def _fmt(value: float | None) -> str:
    if value is None:
        return "—"
    if value != 0 and (abs(value) >= 1e5 or abs(value) < 1e-3):
        return f"{value:.4g}"
    return f"{value:.4f}".rstrip("0").rstrip(".") if not math.isnan(value) else "nan"


def markdown_table(rows: list[Row]) -> str:
    lines = [
        "| case | controller | metric | paper | ours | rel. error | tolerance | ok |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        err = r.relative_error
        ok = {None: "", True: "yes", False: "NO"}[r.within]
        lines.append(
            f"| {r.case} | {r.controller} | {r.metric} | {_fmt(r.paper)} | {_fmt(r.ours)} | "
            f"{'—' if err is None else f'{100 * err:.1f} %'} | "
            f"{'—' if r.tolerance is None else f'{100 * r.tolerance:.0f} %'} | {ok} |"
        )
    return "\n".join(lines)


def write_reproduction(out_dir: str | Path, paper: str, source: str, rows: list[Row], notes: str) -> dict:
    """Write ``<out>/<paper>.json`` and ``<out>/<paper>.md`` (atomically); return the JSON dict.

    ``source``: the citation of the reproduced paper, printed on the markdown's "Source:" line.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = {"paper": paper, "source": source, "rows": [asdict(r) for r in rows], "notes": notes}
    atomic_write(out / f"{paper}.json", json.dumps(doc, indent=2, allow_nan=True) + "\n")
    atomic_write(
        out / f"{paper}.md",
        f"# Reproduction: {paper}\n\nSource: {source}\n\n{markdown_table(rows)}\n\n## Notes\n\n{notes}\n",
    )
    return doc
