"""The report files of a campaign: ``report.md``, ``leaderboard.json`` and ``metadata.json``
(:func:`write_report`, :func:`write_campaign_report` with its figures), and ``index.md`` of
``--config all`` (:func:`write_campaign_index`); each written atomically."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from attitude_envs.files import atomic_write
from experiments.report.figures import campaign_figures
from experiments.report.leaderboards import (
    best_entry,
    campaign_thresholds,
    free_drift_agents,
    leaderboards,
    learned_agents,
)
from experiments.report.markdown import best_cell, env_label, report_markdown
from experiments.report.provenance import all_runs_summary, campaign_metadata, git_revision, package_version


def write_report(
    out_dir: str | Path,
    rows: Sequence[Mapping[str, Any]],
    metadata: Mapping[str, Any],
    figures: Mapping[str, str] | None = None,
    notes: Sequence[str] = (),
) -> Path:
    """``report.md`` (metadata, leaderboards, figures), ``leaderboard.json`` and ``metadata.json``."""
    out_dir = Path(out_dir)
    boards = leaderboards(rows, metadata.get("success_thresholds"))
    serial = [{"env": c[0], "scenario": c[1], "fault": c[2], "board": b} for c, b in boards.items()]
    atomic_write(out_dir / "leaderboard.json", json.dumps(serial, indent=2) + "\n")
    atomic_write(out_dir / "metadata.json", json.dumps(dict(metadata), indent=2, default=str) + "\n")
    return atomic_write(out_dir / "report.md", report_markdown(rows, boards, metadata, figures, notes))


def write_campaign_report(result, video: bool | None = None, command: str | None = None) -> Path:
    """The full report of a :class:`~experiments.campaign.CampaignResult`:
    leaderboards, J-with-CI plot, fault heatmaps, example time histories and (with moviepy)
    an episode video of the best agent per env. ``command``: the command line, for the record."""
    out_dir = Path(result.out_dir)
    video = result.campaign.video if video is None else bool(video)
    rows = result.rows
    if not rows:
        raise ValueError("the campaign produced no episodes (every agent skipped?)")
    boards = leaderboards(rows)
    figures, figure_notes = campaign_figures(result, boards, out_dir, video)
    notes = [f"agent {a} skipped: {why}" for a, why in result.skipped_agents.items()]
    notes += getattr(result, "optimum_notes", [])
    return write_report(out_dir, rows, campaign_metadata(result, command), figures, notes + figure_notes)


def write_campaign_index(out_dir: str | Path, results: Sequence[tuple[str, Any]]) -> Path:
    """``OUT/index.md`` of ``--config all``: first, per leaderboard cell, the best analytic
    controller and the best learned agent (mean J and J/J*); then the run record: per campaign its
    envs (id and kwargs), wall time and report, and the package and git revision. The
    leaderboards themselves are in each campaign's report."""
    out_dir = Path(out_dir)
    lines = ["# All campaigns (--config all)", ""]
    lines += ["| campaign | env · scenario · fault | best analytic | best learned |", "|---|---|---|---|"]
    for name, result in results:
        trained, drift = learned_agents(result.campaign), free_drift_agents(result.campaign)
        for cell, board in leaderboards(result.rows, campaign_thresholds(result.campaign)).items():
            analytic, learned = best_entry(board, False, trained, drift), best_entry(board, True, trained, drift)
            lines.append(f"| {name} | {' · '.join(cell)} | {best_cell(analytic)} | {best_cell(learned)} |")
    lines += ["", "## Run record", ""]
    lines += ["| campaign | env (id, kwargs) | episodes | wall time s (all runs) | report |", "|---|---|---:|---|---|"]
    for name, result in results:
        envs = "; ".join(env_label(e) for e in result.campaign.envs)
        lines.append(
            f"| {name} | {envs} | {len(result.rows)} | {all_runs_summary(result)} | [{name}/report.md]({name}/report.md) |"
        )
    lines += ["", f"Package {package_version()}, git {git_revision()}."]
    return atomic_write(out_dir / "index.md", "\n".join(lines) + "\n")
