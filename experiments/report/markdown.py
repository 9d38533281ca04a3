"""Markdown of a report: numbers as the tables print them, the leaderboard tables and the text
of ``report.md``."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from experiments.optimum_table import COMMAND, DESCRIPTION, SOURCES, TABLE_FILE
from experiments.report.leaderboards import ORACLE_AGENT, PAPER_METRICS, is_oracle

#: a cell with fewer episodes is flagged in its leaderboard
MIN_EPISODES = 5


def fmt(v: Any) -> str:
    """A number as the tables print it (4 significant digits, scientific from 1e5, — when not
    finite); anything else as ``str``."""
    if isinstance(v, float):
        if not np.isfinite(v):
            return "—"
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:.3e}"
    return str(v)


def ratio_text(v: float) -> str:
    """A J / J* ratio: 4 decimals below 10, else as :func:`fmt`."""
    return f"{v:.4f}" if np.isfinite(v) and abs(v) < 10 else fmt(v)


def ratio_cell(e: Mapping[str, Any]) -> str:
    """``1.0123 [1.0050, 1.0200]``, ``1.0123 (deterministic)`` or ``—`` (no J*)."""
    mean = e.get("J_over_J_star", float("nan"))
    if not np.isfinite(mean):
        return "—"
    if e.get("J_over_J_star_deterministic"):
        cell = f"{ratio_text(mean)} (deterministic)"
    elif np.isfinite(e["J_over_J_star_ci_low"]):
        cell = f"{ratio_text(mean)} [{ratio_text(e['J_over_J_star_ci_low'])}, {ratio_text(e['J_over_J_star_ci_high'])}]"
    else:
        cell = ratio_text(mean)
    n = e.get("J_over_J_star_episodes", e["episodes"])
    return cell if n == e["episodes"] else f"{cell} ({n} of {e['episodes']} episodes)"


def leaderboard_markdown(
    boards: Mapping[tuple[str, str, str], list[dict[str, Any]]], notes: Mapping[str, str] | None = None
) -> str:
    """One markdown table per env × scenario × fault; ``notes`` (agent → one line) are shown
    beside their agents."""
    notes = notes or {}
    parts = []
    for (env, scenario, fault), board in boards.items():
        extra = [m for m in PAPER_METRICS if m in board[0]]
        constrained = "violating_rate" in board[0]
        tail = any(np.isfinite(e.get("J_over_J_star", float("nan"))) for e in board)  # J* known: its CVaR
        constraint_head = ["violating episodes", "violation steps", "least margin [deg]"]
        head = [
            "rank",
            "agent",
            "episodes",
            "J mean",
            "95 % CI",
            "IQM",
            "J / J*",
            *(["CVaR₀.₁ J/J*"] if tail else []),
            "success",
            "ended early",
            "recovery [s]",
            *(constraint_head if constrained else []),
            *extra,
        ]
        lines = [f"### {env} · {scenario} · fault: {fault}", "", "| " + " | ".join(head) + " |"]
        lines.append("|" + "---|" * len(head))
        rank = 0
        for e in board:
            flag = "" if e["episodes"] >= MIN_EPISODES else " (< 5 episodes)"
            oracle = is_oracle(e)
            rank += not oracle
            cells = [
                "—" if oracle else str(rank),
                _agent_cell(e["agent"], None if oracle else notes.get(e["agent"])),
                f"{e['episodes']}{flag}",
                fmt(e["J_mean"]),
                _ci_cell(e),
                fmt(e["J_iqm"]),
                ratio_cell(e),
                *([ratio_text(float(e.get("J_over_J_star_cvar10", float("nan"))))] if tail else []),
                _rate_cell(e, "success_rate", "success_known", "J* success"),
                _rate_cell(e, "terminated_rate", "terminated_known", "J* ended early"),
                fmt(e["recovery_time_s"]),
                *(_constraint_cells(e) if constrained else []),
                *[fmt(e.get(m, float("nan"))) for m in extra],
            ]
            lines.append("| " + " | ".join(cells) + " |")
        parts.append("\n".join(lines))
    return "\n\n".join(parts) + "\n"


def _constraint_cells(e: Mapping[str, Any]) -> list[str]:
    """A constrained cell's columns: the share of episodes with a violation, the mean violating
    steps per episode and the least cone margin (deg)."""
    rate = e.get("violating_rate", float("nan"))
    return [
        f"{100 * rate:.0f} %" if np.isfinite(rate) else "—",
        fmt(float(e.get("violation_steps", float("nan")))),
        fmt(float(e.get("min_margin_deg", float("nan")))),
    ]


def layers_markdown(
    rows: Sequence[Mapping[str, Any]],
    boards: Mapping[tuple[str, str, str], list[dict[str, Any]]],
    layers: Sequence[Mapping[str, str]],
) -> str:
    """Per cell, one row per layer (``{"name", "without", "with"}``: two agents that differ by
    it): each side's J / J* and violating episodes, and the layer's cost in J,
    ``ΣJ_with / ΣJ_without − 1`` over the episodes both played (paired by seed and training
    seed, J finite on both sides)."""
    lines = []
    for cell, board in boards.items():
        by_agent = {e["agent"]: e for e in board}
        shown = [layer for layer in layers if layer["without"] in by_agent and layer["with"] in by_agent]
        if not shown:
            continue
        episodes: dict[str, dict[tuple, float]] = {}
        for r in rows:
            if (r["env"], r["scenario"], r["fault"]) == cell:
                episodes.setdefault(r["agent"], {})[(str(r["seed"]), str(r.get("train_seed")))] = float(r["J"])
        lines += [f"### {' · '.join(cell[:2])} · fault: {cell[2]}", ""]
        lines += ["| layer | without | J / J* | violating episodes | with | J / J* | violating episodes | cost in J |"]
        lines += ["|---|---|---|---|---|---|---|---|"]
        for layer in shown:
            a, b = by_agent[layer["without"]], by_agent[layer["with"]]
            ja, jb = episodes.get(a["agent"], {}), episodes.get(b["agent"], {})
            pairs = [(ja[k], jb[k]) for k in ja.keys() & jb.keys() if np.isfinite(ja[k]) and np.isfinite(jb[k])]
            base = sum(p[0] for p in pairs)
            cost = sum(p[1] for p in pairs) / base - 1.0 if pairs and base > 0 else float("nan")
            cells = [layer["name"], a["agent"], ratio_text(a.get("J_over_J_star", float("nan")))]
            cells += [_constraint_cells(a)[0], b["agent"], ratio_text(b.get("J_over_J_star", float("nan")))]
            cells += [_constraint_cells(b)[0], f"{100 * cost:+.1f} %" if np.isfinite(cost) else "—"]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines) + "\n"


def conditions_pairs(rows: Sequence[Mapping[str, Any]]) -> list[tuple[str, str, str]]:
    """``(lab env, flight env, scenario)`` for each env run under other conditions than the lab's
    (the rows' ``conditions``) whose scenario also ran in exactly one lab env: the pairs the
    lab-and-flight table sets side by side."""
    envs: dict[str, tuple[str, set[str]]] = {}
    for r in rows:
        cond = str(r.get("conditions") or "lab")
        envs.setdefault(r["env"], (cond, set()))[1].add(r["scenario"])
    pairs = []
    for name, (cond, scenarios) in envs.items():
        if cond == "lab":
            continue
        for s in sorted(scenarios):
            labs = [n for n, (c, sc) in envs.items() if c == "lab" and s in sc]
            if len(labs) == 1:
                pairs.append((labs[0], name, s))
    return pairs


def conditions_markdown(
    rows: Sequence[Mapping[str, Any]], boards: Mapping[tuple[str, str, str], list[dict[str, Any]]]
) -> str:
    """Per lab/flight pair (:func:`conditions_pairs`), one row per agent: J / J* (and CVaR₀.₁ of
    the per-episode ratios) on the lab's fault-free cell beside each of the flight env's cells
    (its faults there being sensor faults or none). Each side is scored against its own J*:
    the flight oracle knows that episode's drawn plant and acts through the same actuators."""
    lines = []
    for lab, flight, scenario in conditions_pairs(rows):
        cells = [(lab, scenario, "none")] if (lab, scenario, "none") in boards else []
        cells += sorted((c for c in boards if c[0] == flight and c[1] == scenario), key=lambda c: c[2] != "none")
        if len(cells) < 2:
            continue
        by_cell = {c: {e["agent"]: e for e in boards[c] if not is_oracle(e)} for c in cells}
        agents = list(dict.fromkeys(a for c in cells for a in by_cell[c]))
        lines += [f"### {lab} (lab) and {flight} · {scenario}", ""]
        head = [f"{c[0]} · {c[2]}" for c in cells]
        lines += ["| agent | " + " | ".join(f"{h}: J / J* (CVaR₀.₁)" for h in head) + " |"]
        lines += ["|---|" + "---|" * len(cells)]
        for agent in agents:
            out = []
            for c in cells:
                e = by_cell[c].get(agent)
                mean = e.get("J_over_J_star", float("nan")) if e else float("nan")
                if e is None or not np.isfinite(mean):
                    out.append("—" if e is None else f"J {fmt(e['J_mean'])}")
                    continue
                out.append(f"{ratio_text(mean)} ({ratio_text(e.get('J_over_J_star_cvar10', float('nan')))})")
            lines.append(f"| {agent} | " + " | ".join(out) + " |")
        lines.append("")
    return "\n".join(lines) + "\n" if lines else ""


def _rate_cell(e: Mapping[str, Any], rate: str, known: str, what: str) -> str:
    """``20 %``, or for J*'s line with some episodes unknown ``— (J* success: 12 of 20 episodes known)``."""
    value = float(e.get(rate, 0.0))
    if np.isfinite(value):
        return f"{100 * value:.0f} %"
    return f"— ({what}: {e.get(known, 0)} of {e['episodes']} episodes known)"


def _agent_cell(agent: str, note: str | None) -> str:
    """``agent``, or ``agent (note)`` (a ``|`` in the note escaped for the table)."""
    if note is None:
        return agent
    escaped = note.replace("|", "\\|")
    return f"{agent} ({escaped})"


def _ci_cell(e: Mapping[str, Any]) -> str:
    if e.get("deterministic"):
        return "deterministic"
    if not (np.isfinite(e["J_ci_low"]) and np.isfinite(e["J_ci_high"])):
        return "—"
    return f"[{fmt(e['J_ci_low'])}, {fmt(e['J_ci_high'])}]"


def best_cell(e: Mapping[str, Any] | None) -> str:
    """``agent: J …, J/J* …`` of a leaderboard entry, with its share of episodes ended early; — for none."""
    if e is None:
        return "—"
    early = e.get("terminated_rate", 0.0)
    flag = f", ended early {100 * early:.0f} %" if early > 0 else ""
    return f"{e['agent']}: J {fmt(e['J_mean'])}, J/J* {ratio_cell(e)}{flag}"


def env_label(env) -> str:
    """A campaign env as its registered id and constructor kwargs, both as code spans."""
    return f"`{env.id}` `{json.dumps(env.kwargs)}`"


def _optimum_legend(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """What J* is and where this report's values came from (counts of distinct episodes)."""
    if not any("j_star" in r for r in rows):
        return []
    episodes = {(r["env"], r["scenario"], r["fault"], r["seed"]): r.get("j_star_source", "missing") for r in rows}
    counts = {s: n for s in SOURCES if (n := sum(v == s for v in episodes.values()))}
    where = {
        "table": f"the J* table (shipped: experiments/{TABLE_FILE}, regenerated by `{COMMAND}`)",
        "cache": "the solver's on-disk cache",
        "solved": "solved for this campaign",
        "unsupported": "not available (no symbolic model)",
        "missing": "not available",
    }
    got = "; ".join(f"{n} from {where[s]}" if s in ("table", "cache") else f"{n} {where[s]}" for s, n in counts.items())
    oracle = (
        f"The line {ORACLE_AGENT} of each leaderboard is J* itself, unranked (no agent): J mean is the mean J*, "
        "J / J* is 1 by construction, success is whether the optimum's own episode (its actions replayed) meets "
        "the same criterion as the agents', and ended early is whether that replay terminated; — where J*'s "
        "measurements are unknown for some episode (a J* solved before they were kept)."
    )
    return [DESCRIPTION, f"J* of this report's {len(episodes)} distinct episodes: {got}.", "", oracle, ""]


def report_markdown(
    rows: Sequence[Mapping[str, Any]],
    boards: Mapping[tuple[str, str, str], list[dict[str, Any]]],
    metadata: Mapping[str, Any],
    figures: Mapping[str, str] | None = None,
    notes: Sequence[str] = (),
) -> str:
    """The text of ``report.md``, results first: the leaderboards, ``notes`` (each once) and
    ``figures`` (caption → relative path), then what the columns mean and where J* came from,
    and last the run record (``metadata`` as a table: what ran, where, from which code)."""
    notes = list(dict.fromkeys(notes))
    lines = [f"# Benchmark report: {metadata.get('campaign', '')}", ""]
    lines += [
        "The leaderboards and figures first; what their columns mean under "
        "[Reading the leaderboards](#reading-the-leaderboards), what ran, where and from which code under "
        "[Run record](#run-record).",
        "",
    ]
    lines += ["## Leaderboards", "", leaderboard_markdown(boards, metadata.get("agent_notes"))]
    if metadata.get("layers"):
        lines += ["## What each layer costs", "", layers_markdown(rows, boards, metadata["layers"])]
    flight = conditions_markdown(rows, boards)
    if flight:
        lines += ["## Lab and flight", ""]
        lines += ["Every row's J / J* in the lab (fault-free) beside the same episodes under flight conditions,"]
        lines += ["fault-free and with each sensor fault; each side against its own J* (the flight oracle knows"]
        lines += ["the drawn plant and the true state, and acts through the same actuators and delay)."]
        lines += ["— : not played there.", ""]
        lines += [flight]
    if notes:
        lines += ["## Notes", "", *[f"* {n}" for n in notes], ""]
    if figures:
        lines += ["## Figures", ""]
        for caption, rel in figures.items():
            lines.append(f"* [{caption}]({rel})" if rel.endswith(".mp4") else f"![{caption}]({rel})")
        lines.append("")
    lines += ["## Reading the leaderboards", ""]
    lines += ["J = ∫(xᵀQx + uᵀRu) dt per episode (lower is better); CI: 95 % percentile bootstrap of the mean"]
    lines += ['("deterministic": every episode of the cell gave the same J, so there is no interval);']
    lines += ["IQM: interquartile mean; success: the env's criterion in the run record;"]
    lines += ["ended early: episodes that terminated before the time limit (a limit crossed); the env charges their"]
    lines += ["last step the terminal state's running cost over the rest of the horizon (termination_cost), and"]
    lines += ["agents with such episodes rank after those without (by that fraction, then J);"]
    lines += ["recovery: time from the fault onset until the error stays within the settling band;"]
    lines += ["J / J*: mean J over mean J* of the same episodes (the cost above the optimum, as a factor), 95 % paired"]
    lines += ["bootstrap CI; the per-episode ratios (and their median, in leaderboard.json) are in episodes.csv;"]
    lines += ["CVaR₀.₁ J/J*: the mean of the worst tenth of the per-episode ratios J / J* (the tail beside the mean;"]
    lines += ["an episode that starts near its target has a small J*, so its ratio can dominate the tail).", ""]
    if any("violations" in r for r in rows):
        lines += ["Constraints (each g ≤ 0, checked at every decision time): violating episodes is the failure rate,"]
        lines += ["the share of episodes with at least one step that violates a constraint; violation steps the mean"]
        lines += ["number of such steps per episode; least margin the smallest keep-out cone margin θ − α over every"]
        lines += ["step of every episode (deg, negative inside a cone). J*'s line gives its own replays' constraint"]
        lines += ["outcome. Agents with violating episodes rank after those without (by that share, after ended"]
        lines += ["early), then by J.", ""]
    lines += _optimum_legend(rows)
    lines += ["## Run record", "", *run_record(metadata), ""]
    return "\n".join(lines)


def run_record(metadata: Mapping[str, Any]) -> list[str]:
    """``metadata`` as the lines of a two-column markdown table: the campaign, command, package and
    git revision, seeds, executor, episodes, wall times (s), each trained agent's budget and task,
    the given models, the success criteria and the definitions of envs, scenarios and faults."""
    lines = ["| | |", "|---|---|"]
    for key in (
        "campaign",
        "source",
        "command",
        "package_version",
        "git_revision",
        "seeds",
        "executor",
        "episodes",
        "wall_time_s",
        "wall_time_all_runs_s",
    ):
        if key in metadata and metadata[key] not in (None, "", "<dict>"):
            lines.append(f"| {key} | {metadata[key]} |")
    for agent, budget in (metadata.get("training_budget") or {}).items():
        lines.append(f"| training budget: {agent} | {budget} |")
    for agent, task in (metadata.get("training_task") or {}).items():
        if task:
            lines.append(f"| training task: {agent} | {task} |")
    for agent, model in (metadata.get("models") or {}).items():
        lines.append(f"| model: {agent} | {model} |")
    for env, criterion in (metadata.get("success_criteria") or {}).items():
        lines.append(f"| success: {env} | {criterion} |")
    for what, definition in (metadata.get("definitions") or {}).items():
        lines.append(f"| {what} | {definition} |")
    return lines
