"""What a campaign writes, crash-safe: ``episodes.jsonl`` and ``episodes.csv``
(:class:`ResultStore`, with the J* log ``optimum.jsonl``), ``runs.jsonl`` (:class:`RunLog`,
:func:`read_runs`), and :class:`CampaignResult`, what a run returns."""

from __future__ import annotations

import json
import os
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from attitude_envs.evaluation.runner import write_csv
from attitude_envs.evaluation.success import metric_of
from attitude_envs.files import atomic_write
from experiments.campaign.jobs import key_of, sort_key
from experiments.campaign.spec import Campaign
from experiments.machine_reference import reference_steps_per_s
from experiments.progress import status_interval_s


def append_line(path: str | Path, record: dict[str, Any], default: Any = None) -> None:
    """Append one JSON line and fsync it (a crash can cut at most this line; a line a crash
    cut before is ended first, so this one stays readable); ``default``: ``json.dumps``'s, for
    values JSON has no type for."""
    path = Path(path)
    with path.open("a+b") as fh:
        size = fh.seek(0, os.SEEK_END)
        cut = False
        if size:
            fh.seek(size - 1)
            cut = fh.read(1) != b"\n"
        fh.write((("\n" if cut else "") + json.dumps(record, allow_nan=True, default=default) + "\n").encode("utf-8"))
        fh.flush()
        os.fsync(fh.fileno())


def read_lines(path: str | Path) -> list[dict[str, Any]]:
    """The JSON lines of an append log in order (empty when there is none), skipping a line cut
    by a crash."""
    path = Path(path)
    if not path.is_file():
        return []
    records = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return records


RUN_STATUSES = ("completed", "interrupted", "failed", "killed")


class RunLog:
    """One run of a campaign in ``runs.jsonl``: an fsynced ``start`` line before any work,
    ``progress`` lines at most every ``ATTITUDE_ENVS_PROGRESS_S`` seconds (default 30) and an
    ``end`` line with the status (``completed``, ``interrupted`` by Ctrl-C, ``failed``). A run
    killed with SIGKILL leaves its start line (and progress lines) without an end:
    :func:`read_runs` counts it as ``killed``. The start and end lines carry the machine's speed
    then (``reference_steps_per_s``, ``reference_steps_per_s_end``:
    :func:`~experiments.machine_reference.reference_steps_per_s`, 0.2 s each)."""

    def __init__(self, path: Path, executor: str) -> None:
        self.path = Path(path)
        self.run = uuid.uuid4().hex[:12]
        reference = reference_steps_per_s()  # before the clock starts: not part of the run's wall time
        self.start = self.last = time.perf_counter()
        self.interval_s = status_interval_s()
        record = {"event": "start", "run": self.run, "started_at": round(time.time(), 3), "executor": executor}
        append_line(self.path, record | {"pid": os.getpid(), "reference_steps_per_s": round(reference, 1)})

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.start

    def progress(self) -> None:
        """A progress line (the wall time so far) if the last one is an interval old."""
        now = time.perf_counter()
        if now - self.last >= self.interval_s:
            self.last = now
            append_line(self.path, {"event": "progress", "run": self.run, "wall_time_s": round(now - self.start, 3)})

    def end(self, status: str, **counts: Any) -> float:
        """The end line; returns the run's wall time, s."""
        elapsed = self.elapsed_s()
        reference = round(reference_steps_per_s(), 1)
        append_line(
            self.path,
            {"event": "end", "run": self.run, "status": status, "wall_time_s": round(elapsed, 3)}
            | counts
            | {"reference_steps_per_s_end": reference},
        )
        return elapsed


def read_runs(path: str | Path) -> list[dict[str, Any]]:
    """The runs of ``runs.jsonl`` (start, progress and end lines paired by run id), in start
    order: ``run``, ``status`` (one of :data:`RUN_STATUSES`; ``killed``: a start line without
    an end), ``wall_time_s`` (of a killed run: up to its last progress line, a lower bound)
    and the end line's counts. A line of the older one-line-per-run format is one run."""
    runs: dict[str, dict[str, Any]] = {}
    for i, rec in enumerate(read_lines(Path(path))):
        event = rec.pop("event", None)
        rid = str(rec.get("run", f"line-{i}"))
        run = runs.setdefault(rid, {"run": rid, "status": "killed", "wall_time_s": 0.0})
        if event == "progress":
            run["wall_time_s"] = max(run["wall_time_s"], float(rec.get("wall_time_s", 0.0)))
        elif event == "end" or event is None:
            if event is None:  # the older format: one line per finished or interrupted run
                rec.setdefault("status", "completed" if rec.get("completed") else "interrupted")
            run.update(rec)
        else:
            run.update({k: v for k, v in rec.items() if k not in run})
    return list(runs.values())


class ResultStore:
    """``episodes.jsonl`` (append log, one fsynced line per episode) + ``episodes.csv`` (sorted, atomic)."""

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = Path(out_dir)
        self.log = self.out_dir / "episodes.jsonl"
        self.csv = self.out_dir / "episodes.csv"
        self.rows: dict[tuple, dict[str, Any]] = {}
        #: the keys of the campaign's episodes (None: every recorded row); rows of agents since
        #: removed stay in the log but leave the table
        self.wanted: set[tuple] | None = None
        self.logged_before = 0  # lines in the log when this store opened it
        if self.log.is_file():
            good = read_lines(self.log)  # an episode whose line a crash cut is simply run again
            self.rows = {key_of(row): row for row in good}
            # Drop the cut line so the next append starts on a fresh line.
            atomic_write(self.log, "".join(json.dumps(row, allow_nan=True) + "\n" for row in good))
            self.logged_before = len(good)
        # J* per episode key (experiments.optimum_table): its own append log, joined into the rows
        self.optimum_log = self.out_dir / "optimum.jsonl"
        self.optimum: dict[str, dict[str, Any]] = {}
        self._optimum_cells: dict[tuple, dict[str, Any]] = {}  # (env, scenario, fault, seed) → J* row
        for r in read_lines(self.optimum_log):
            self._add_optimum(r)

    def done(self, key: dict[str, Any]) -> bool:
        return key_of(key) in self.rows

    def append(self, row: dict[str, Any]) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        append_line(self.log, row)
        self.rows[key_of(row)] = row
        self.write_csv()

    def optimum_done(self, key_hash: str) -> bool:
        return key_hash in self.optimum

    def optimum_row(self, key_hash: str) -> dict[str, Any]:
        return self.optimum[key_hash]

    def _add_optimum(self, row: dict[str, Any]) -> None:
        self.optimum[row["hash"]] = row
        for cell in row["cells"]:
            self._optimum_cells[tuple(cell)] = row

    def append_optimum(self, row: dict[str, Any]) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        append_line(self.optimum_log, row)
        self._add_optimum(row)

    def with_optimum(self, row: dict[str, Any]) -> dict[str, Any]:
        """``row`` with ``j_star`` (its episode's oracle optimum; NaN when unknown),
        ``j_over_j_star`` (J / J*), ``j_star_source`` (table, cache, solved, unsupported, missing)
        and J*'s own outcome (:func:`optimum_outcome`): ``j_star_metric``, ``j_star_terminated``
        and one ``j_star_<measurement>`` column per success-metric measurement."""
        found = self._optimum_cells.get((row["env"], row["scenario"], row["fault"], row["seed"]))
        j_star = float(found["j_star"]) if found is not None else float("nan")
        J = float(row["J"])
        ratio = J / j_star if np.isfinite(j_star) and j_star > 0 and not np.isnan(J) else float("nan")
        source = found["source"] if found is not None else "missing"
        outcome = optimum_outcome(found if found is not None and np.isfinite(j_star) else None)
        return {**row, "j_star": j_star, "j_over_j_star": ratio, "j_star_source": source, **outcome}

    def sorted_rows(self) -> list[dict[str, Any]]:
        keys = self.rows if self.wanted is None else [k for k in self.rows if k in self.wanted]
        return [self.with_optimum(self.rows[k]) for k in sorted(keys, key=sort_key)]

    def write_csv(self) -> Path:
        rows = [for_table(r) for r in self.sorted_rows()]
        return atomic_write(self.csv, lambda tmp: write_csv(rows, tmp))


#: the prefix of J*'s own columns in an episode row (:func:`optimum_outcome`)
J_STAR_PREFIX = "j_star_"


def optimum_outcome(optimum_row: dict[str, Any] | None) -> dict[str, Any]:
    """J*'s own episode outcome as flat episode-row columns: ``j_star_metric`` (the env's
    success-metric name, :data:`attitude_envs.evaluation.success.METRICS`, ``""`` when
    unknown), ``j_star_terminated`` (its replay ended early; None when unknown) and
    ``j_star_<name>`` per measurement (e.g. ``j_star_final_error_deg``, deg; for a relative
    metric ``j_star_initial_state_norm`` and ``j_star_final_state_norm``). Unknown without a
    J* row, for a row without ``measurements`` (a J* table entry or solver cache entry from
    before they were kept) or with measurements of no known metric."""
    measurements = (optimum_row or {}).get("measurements")
    terminated = (optimum_row or {}).get("terminated")
    metric = metric_of(measurements) if measurements else None
    if metric is None or terminated is None:
        return {f"{J_STAR_PREFIX}metric": "", f"{J_STAR_PREFIX}terminated": None}
    out: dict[str, Any] = {f"{J_STAR_PREFIX}metric": metric.name, f"{J_STAR_PREFIX}terminated": bool(terminated)}
    return out | {f"{J_STAR_PREFIX}{k}": float(v) for k, v in measurements.items()}


def for_table(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` as the tables show it: without ``episode_wall_s`` (machine-dependent)."""
    return {k: v for k, v in row.items() if k != "episode_wall_s"}


@dataclass
class CampaignResult:
    """What :func:`~experiments.campaign.run.run_campaign` returns: the rows of every episode of
    the campaign (this run's and earlier runs'), the training runs, and the wall times, s."""

    campaign: Campaign
    out_dir: Path
    rows: list[dict[str, Any]]
    trained: list[dict[str, Any]]
    skipped_agents: dict[str, str]
    episodes_run: int
    episodes_skipped: int
    wall_time_s: float
    executor: str
    total_wall_time_s: float = 0.0  # this run and every earlier one logged in runs.jsonl
    optimum_notes: list[str] = field(default_factory=list)  # episodes without J* (why), for the report
    runs: int = 1
    run_statuses: dict[str, int] = field(default_factory=dict)  # status → count over runs.jsonl
    run_log: list[dict[str, Any]] = field(default_factory=list)  # every run of runs.jsonl (read_runs)
