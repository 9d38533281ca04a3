"""Campaign report: leaderboards (J mean, 95 % bootstrap CI, IQM), paper metrics, plots, metadata.

Statistics are over episodes (evaluation seeds × training seeds) of one agent in one
env × scenario × fault cell: the mean of J with a percentile bootstrap 95 % confidence
interval (``n_boot`` resamples, fixed RNG seed, so the report is reproducible) and the
interquartile mean (mean of the middle 50 %, ``scipy.stats.trim_mean(J, 0.25)``; Agarwal
et al. 2021). A cell with fewer than ``MIN_EPISODES`` episodes is flagged; a cell whose
episodes all have the same J (a deterministic agent from a fixed start) has no CI: the
report prints "deterministic". Success is per env, stated in the report
(:func:`experiments.campaign.episode.success_criterion`). An agent's ``note`` is shown beside
it in the leaderboards.
"""

from __future__ import annotations

import copy
import json
import subprocess
import zipfile
from collections.abc import Mapping, Sequence
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import RecordVideo
from scipy import stats

from attitude_envs.evaluation.success import METRICS
from attitude_envs.evaluation.trace import record_episode, record_state_trace
from attitude_envs.files import atomic_write
from attitude_envs.info import policy_view
from experiments.campaign.episode import success_criterion
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.store import J_STAR_PREFIX
from experiments.machine_reference import REFERENCE_ENV
from experiments.optimum_table import COMMAND, DESCRIPTION, SOURCES, TABLE_FILE
from experiments.policies import build_policy

MIN_EPISODES = 5
PAPER_METRICS = ("eulerint_deg_s", "settling_time_abs_s", "final_error_deg", "peak_wheel_speed_rpm")


def bootstrap_ci(
    values: Sequence[float], n_boot: int = 2000, level: float = 0.95, seed: int = 0
) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean (``(nan, nan)`` for no finite value)."""
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if len(x) == 0:
        return (float("nan"), float("nan"))
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, len(x), size=(int(n_boot), len(x)))].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    return (float(np.quantile(means, alpha)), float(np.quantile(means, 1.0 - alpha)))


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean (mean of the middle 50 % of the finite values)."""
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    return float(stats.trim_mean(x, 0.25)) if len(x) else float("nan")


def _finite_mean(values: Sequence[Any]) -> float:
    x = np.asarray([float(v) for v in values if v is not None and np.isfinite(float(v))], dtype=float)
    return float(x.mean()) if len(x) else float("nan")


def is_deterministic(values: Sequence[float]) -> bool:
    """More than one value and all equal: every seed gave the same J (e.g. a fixed start)."""
    x = np.asarray(values, dtype=float)
    return len(x) > 1 and bool(np.all(x == x[0]))


def leaderboards(
    rows: Sequence[Mapping[str, Any]], thresholds: Mapping[str, float] | None = None
) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """``(env, scenario, fault)`` → one entry per agent, best first: the agents whose every
    episode ran to the time limit by J mean, then those with episodes that terminated early
    (a limit crossed: the vehicle lost), by the fraction that did, then J. J sums the cost
    only up to the end of the episode, so an episode cut short costs less; ranking it by J
    alone would reward ending it (an agent trained on the reward −cost can learn exactly that).

    Where the rows carry J* (``j_star``), each board ends with J*'s own line
    (:func:`oracle_entry`, ``"oracle": True``, agent :data:`ORACLE_AGENT`): unranked, no
    agent. ``thresholds``: success-metric name → the campaign's threshold
    (:func:`campaign_thresholds`) that J*'s success is judged at (default: each metric's own)."""
    cells: dict[tuple[str, str, str], dict[str, list[Mapping[str, Any]]]] = {}
    for r in rows:
        cells.setdefault((r["env"], r["scenario"], r["fault"]), {}).setdefault(r["agent"], []).append(r)
    out = {}
    for cell, agents in cells.items():
        board = []
        for agent, rs in agents.items():
            J = [float(r["J"]) for r in rs]
            deterministic = is_deterministic(J)
            lo, hi = (float("nan"), float("nan")) if deterministic else bootstrap_ci(J)
            entry = {
                "agent": agent,
                "episodes": len(rs),
                "train_seeds": len({r.get("train_seed") for r in rs}),
                "J_mean": _finite_mean(J),
                "J_ci_low": lo,
                "J_ci_high": hi,
                "deterministic": deterministic,
                "J_iqm": iqm(J),
                "success_rate": float(np.mean([bool(r.get("success")) for r in rs])),
                "terminated_rate": float(np.mean([_flag(r.get("terminated")) for r in rs])),
                "recovery_time_s": _finite_mean([r.get("recovery_time_s") for r in rs]),
                **_ratio_stats(rs),
            }
            for m in PAPER_METRICS:
                if any(m in r for r in rs):
                    entry[m] = _finite_mean([r.get(m) for r in rs])
            board.append(entry)
        board.sort(key=lambda e: (not np.isfinite(e["J_mean"]), e["terminated_rate"], e["J_mean"]))
        oracle = oracle_entry([r for rs in agents.values() for r in rs], thresholds, board[0])
        out[cell] = board + ([oracle] if oracle is not None else [])
    return dict(sorted(out.items()))


#: the name of J*'s own line on a leaderboard (not an agent: unranked, never "best")
ORACLE_AGENT = "J* (oracle)"


def is_oracle(entry: Mapping[str, Any]) -> bool:
    """Whether a leaderboard entry is J*'s own line (:func:`oracle_entry`), not an agent."""
    return bool(entry.get("oracle"))


def campaign_thresholds(campaign: Any) -> dict[str, float]:
    """Success-metric name → ``campaign``'s threshold (``campaign.success_threshold(metric)``)
    for every metric of :data:`~attitude_envs.evaluation.success.METRICS`."""
    return {name: float(campaign.success_threshold(metric)) for name, metric in METRICS.items()}


def _known_flag(value: Any) -> bool | None:
    """A row's boolean, None when unknown (None, ``""`` or NaN, as a CSV row carries it)."""
    if value is None or value == "" or (isinstance(value, float) and np.isnan(value)):
        return None
    return _flag(value)


def oracle_success(row: Mapping[str, Any], thresholds: Mapping[str, float] | None = None) -> bool | None:
    """Whether J* itself succeeds on ``row``'s episode, by the campaign's criterion: J* finite,
    its replay not terminated and its success-metric measurements (``j_star_<name>``
    columns, :func:`experiments.campaign.store.optimum_outcome`) meeting the metric
    (:meth:`~attitude_envs.evaluation.success.SuccessMetric.met`) at ``thresholds[metric]``
    (default: the metric's own). None when J*'s measurements are unknown."""
    metric = METRICS.get(str(row.get(f"{J_STAR_PREFIX}metric") or ""))
    terminated = _known_flag(row.get(f"{J_STAR_PREFIX}terminated"))
    j_star = float(row.get("j_star", float("nan")))
    if metric is None or terminated is None or not np.isfinite(j_star):
        return None
    try:
        measured = {n: float(row[f"{J_STAR_PREFIX}{n}"]) for n in metric.measurement_names()}
    except (KeyError, TypeError, ValueError):
        return None
    threshold = (thresholds or {}).get(metric.name, metric.threshold)
    return bool(not terminated and metric.met(measured, threshold))


def oracle_entry(
    rows: Sequence[Mapping[str, Any]],
    thresholds: Mapping[str, float] | None = None,
    like: Mapping[str, Any] | None = None,
) -> dict[str, Any] | None:
    """J*'s own line for one cell's ``rows`` (every agent's; one J* per episode, so episodes
    are the distinct seeds), None when the rows carry no ``j_star``: ``J_mean`` the mean J*
    (over the episodes that have one), its CI and IQM, ``J_over_J_star`` 1 by construction,
    ``success_rate`` J*'s own (:func:`oracle_success`) and ``terminated_rate`` its replay's —
    each NaN unless known for every episode (``success_known``, ``terminated_known``: how
    many are). The paper metrics of ``like`` (an agent's entry) are NaN but
    ``final_error_deg`` (deg), which J*'s measurements give where known for every episode."""
    if not any("j_star" in r for r in rows):
        return None
    episodes = list({r["seed"]: r for r in rows}.values())
    n = len(episodes)
    js = [float(r.get("j_star", float("nan"))) for r in episodes]
    finite = [j for j in js if np.isfinite(j)]
    deterministic = is_deterministic(finite)
    lo, hi = (float("nan"), float("nan")) if deterministic else bootstrap_ci(finite)
    success = [oracle_success(r, thresholds) for r in episodes]
    ended = [_known_flag(r.get(f"{J_STAR_PREFIX}terminated")) for r in episodes]
    known_success = [s for s in success if s is not None]
    known_ended = [t for t in ended if t is not None]
    entry: dict[str, Any] = {
        "agent": ORACLE_AGENT,
        "oracle": True,
        "episodes": n,
        "train_seeds": 0,
        "J_mean": _finite_mean(finite),
        "J_ci_low": lo,
        "J_ci_high": hi,
        "deterministic": deterministic,
        "J_iqm": iqm(finite),
        "success_rate": float(np.mean(known_success)) if len(known_success) == n else float("nan"),
        "success_known": len(known_success),
        "terminated_rate": float(np.mean(known_ended)) if len(known_ended) == n else float("nan"),
        "terminated_known": len(known_ended),
        "recovery_time_s": float("nan"),
        "J_over_J_star": 1.0 if finite else float("nan"),
        "J_over_J_star_ci_low": float("nan"),
        "J_over_J_star_ci_high": float("nan"),
        "J_over_J_star_median": 1.0 if finite else float("nan"),
        "J_over_J_star_deterministic": bool(finite),
        "J_over_J_star_episodes": len(finite),
    }
    for m in PAPER_METRICS:
        if like is not None and m in like:
            entry[m] = float("nan")
    if "final_error_deg" in entry:
        errors = [r.get(f"{J_STAR_PREFIX}final_error_deg") for r in episodes]
        if all(e not in (None, "") and np.isfinite(float(e)) for e in errors):
            entry["final_error_deg"] = _finite_mean(errors)
    return entry


def _flag(value: Any) -> bool:
    """A row's boolean (CSV rows carry ``"True"``/``"False"`` or 1/0)."""
    return value in (True, 1, "True", "true", "1")


def _ratio_stats(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """J / J* of a cell as a ratio of means: Σ J / Σ J* over the episodes that have a J*, with a
    95 % paired bootstrap CI (episodes resampled with their J and J* together), the median of
    the per-episode ratios, whether every episode gave the same ratio, and how many episodes had
    a J*. A mean of per-episode ratios would be dominated by episodes that start near the
    target, where J* is close to zero and any controller's ratio is huge."""
    pairs = [
        (float(r["J"]), float(r["j_star"]))
        for r in rows
        if r.get("j_star") is not None
        and np.isfinite(float(r["j_star"]))
        and float(r["j_star"]) > 0.0
        and np.isfinite(float(r["J"]))
    ]
    if not pairs:
        return {
            "J_over_J_star": float("nan"),
            "J_over_J_star_ci_low": float("nan"),
            "J_over_J_star_ci_high": float("nan"),
            "J_over_J_star_median": float("nan"),
            "J_over_J_star_deterministic": False,
            "J_over_J_star_episodes": 0,
        }
    J, Js = np.asarray(pairs).T
    ratios = J / Js
    deterministic = is_deterministic(ratios)
    lo, hi = (float("nan"), float("nan"))
    if not deterministic:
        idx = np.random.default_rng(0).integers(0, len(J), size=(2000, len(J)))
        boot = J[idx].sum(axis=1) / Js[idx].sum(axis=1)
        lo, hi = float(np.quantile(boot, 0.025)), float(np.quantile(boot, 0.975))
    return {
        "J_over_J_star": float(J.sum() / Js.sum()),
        "J_over_J_star_ci_low": lo,
        "J_over_J_star_ci_high": hi,
        "J_over_J_star_median": float(np.median(ratios)),
        "J_over_J_star_deterministic": deterministic,
        "J_over_J_star_episodes": len(J),
    }


def _ratio(v: float) -> str:
    return f"{v:.4f}" if np.isfinite(v) and abs(v) < 10 else _fmt(v)


def _ratio_cell(e: Mapping[str, Any]) -> str:
    """``1.0123 [1.0050, 1.0200]``, ``1.0123 (deterministic)`` or ``—`` (no J*)."""
    mean = e.get("J_over_J_star", float("nan"))
    if not np.isfinite(mean):
        return "—"
    if e.get("J_over_J_star_deterministic"):
        cell = f"{_ratio(mean)} (deterministic)"
    elif np.isfinite(e["J_over_J_star_ci_low"]):
        cell = f"{_ratio(mean)} [{_ratio(e['J_over_J_star_ci_low'])}, {_ratio(e['J_over_J_star_ci_high'])}]"
    else:
        cell = _ratio(mean)
    n = e.get("J_over_J_star_episodes", e["episodes"])
    return cell if n == e["episodes"] else f"{cell} ({n} of {e['episodes']} episodes)"


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        if not np.isfinite(v):
            return "—"
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:.3e}"
    return str(v)


def leaderboard_markdown(
    boards: Mapping[tuple[str, str, str], list[dict[str, Any]]], notes: Mapping[str, str] | None = None
) -> str:
    """One markdown table per env × scenario × fault; ``notes`` (agent → one line) are shown
    beside their agents."""
    notes = notes or {}
    parts = []
    for (env, scenario, fault), board in boards.items():
        extra = [m for m in PAPER_METRICS if m in board[0]]
        head = [
            "rank",
            "agent",
            "episodes",
            "J mean",
            "95 % CI",
            "IQM",
            "J / J*",
            "success",
            "ended early",
            "recovery [s]",
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
                _fmt(e["J_mean"]),
                _ci_cell(e),
                _fmt(e["J_iqm"]),
                _ratio_cell(e),
                _rate_cell(e, "success_rate", "success_known", "J* success"),
                _rate_cell(e, "terminated_rate", "terminated_known", "J* ended early"),
                _fmt(e["recovery_time_s"]),
                *[_fmt(e.get(m, float("nan"))) for m in extra],
            ]
            lines.append("| " + " | ".join(cells) + " |")
        parts.append("\n".join(lines))
    return "\n\n".join(parts) + "\n"


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
    return f"[{_fmt(e['J_ci_low'])}, {_fmt(e['J_ci_high'])}]"


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


def _plots():
    """:mod:`experiments.plots` (matplotlib.pyplot on the Agg backend), imported on first use."""
    from experiments import plots  # heavy: matplotlib.pyplot (~0.4 s) would slow every command of the CLI

    return plots


def plot_leaderboard(boards, path: str | Path) -> Path:
    """J mean per agent with 95 % CI bars, one panel per env × scenario × fault (log scale)."""
    plt = _plots().plt
    cells = list(boards)
    fig, axes = plt.subplots(len(cells), 1, figsize=(7.5, 2.4 * len(cells) + 0.6), squeeze=False)
    for ax, cell in zip(axes[:, 0], cells, strict=True):
        board = [e for e in boards[cell] if not is_oracle(e)]
        names = [e["agent"] for e in board]
        mean = np.array([e["J_mean"] for e in board])
        err = np.array([[e["J_mean"] - e["J_ci_low"], e["J_ci_high"] - e["J_mean"]] for e in board]).T
        ax.barh(names, mean, xerr=np.nan_to_num(err), color="tab:blue", alpha=0.8, capsize=3)
        ax.set_xscale("log")
        ax.invert_yaxis()
        ax.set_title(" · ".join(cell), fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
    axes[-1, 0].set_xlabel("episode cost J (mean, 95 % bootstrap CI)")
    fig.tight_layout()
    return _save(fig, path)


def plot_fault_heatmap(rows: Sequence[Mapping[str, Any]], env: str, path: str | Path) -> Path | None:
    """Agent × fault heatmap of mean J (colour: log10), for one env; None with a single fault case."""
    rs = [r for r in rows if r["env"] == env]
    faults = list(dict.fromkeys(r["fault"] for r in rs))
    if len(faults) < 2:
        return None
    plt = _plots().plt
    agents = list(dict.fromkeys(r["agent"] for r in rs))
    grid = np.array(
        [[_finite_mean([r["J"] for r in rs if r["agent"] == a and r["fault"] == f]) for f in faults] for a in agents]
    )
    fig, ax = plt.subplots(figsize=(1.6 * len(faults) + 3, 0.45 * len(agents) + 1.6))
    im = ax.imshow(np.log10(grid), aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(faults)), faults, rotation=20, ha="right")
    ax.set_yticks(range(len(agents)), agents)
    for i in range(len(agents)):
        for j in range(len(faults)):
            ax.text(j, i, _fmt(float(grid[i, j])), ha="center", va="center", color="w", fontsize=8)
    fig.colorbar(im, ax=ax, label="log10 mean J")
    ax.set_title(f"{env}: mean J per agent and fault")
    fig.tight_layout()
    return _save(fig, path)


def _save(fig, path: str | Path) -> Path:
    return _plots().save_figure(fig, path, dpi=100)


def git_revision(root: str | Path | None = None) -> str:
    """``git rev-parse HEAD`` of the source tree (``"unknown"`` outside a checkout)."""
    root = Path(root or Path(__file__).resolve().parents[1])
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 else "unknown"


def package_version() -> str:
    try:
        return importlib_metadata.version("attitude-envs")
    except importlib_metadata.PackageNotFoundError:
        return "unknown"


def write_report(
    out_dir: str | Path,
    rows: Sequence[Mapping[str, Any]],
    metadata: Mapping[str, Any],
    figures: Mapping[str, str] | None = None,
    notes: Sequence[str] = (),
) -> Path:
    """``report.md`` (metadata, leaderboards, figures), ``leaderboard.json`` and ``metadata.json``."""
    out_dir = Path(out_dir)
    notes = list(dict.fromkeys(notes))
    boards = leaderboards(rows, metadata.get("success_thresholds"))
    serial = [{"env": c[0], "scenario": c[1], "fault": c[2], "board": b} for c, b in boards.items()]
    atomic_write(out_dir / "leaderboard.json", json.dumps(serial, indent=2) + "\n")
    atomic_write(out_dir / "metadata.json", json.dumps(dict(metadata), indent=2, default=str) + "\n")
    lines = [f"# Benchmark report: {metadata.get('campaign', '')}", ""]
    lines += ["| | |", "|---|---|"]
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
    lines += ["", "J = ∫(xᵀQx + uᵀRu) dt per episode (lower is better); CI: 95 % percentile bootstrap of the mean"]
    lines += ['("deterministic": every episode of the cell gave the same J, so there is no interval);']
    lines += ["IQM: interquartile mean; success: the env's criterion above;"]
    lines += ["ended early: episodes that terminated before the time limit (a limit crossed); the env charges their"]
    lines += ["last step the terminal state's running cost over the rest of the horizon (termination_cost), and"]
    lines += ["agents with such episodes rank after those without (by that fraction, then J);"]
    lines += ["recovery: time from the fault onset until the error stays within the settling band;"]
    lines += ["J / J*: mean J over mean J* of the same episodes (the cost above the optimum, as a factor), 95 % paired"]
    lines += ["bootstrap CI; the per-episode ratios (and their median, in leaderboard.json) are in episodes.csv.", ""]
    lines += _optimum_legend(rows)
    lines += ["## Leaderboards", "", leaderboard_markdown(boards, metadata.get("agent_notes"))]
    if notes:
        lines += ["## Notes", "", *[f"* {n}" for n in notes], ""]
    if figures:
        lines += ["## Figures", ""]
        for caption, rel in figures.items():
            lines.append(f"* [{caption}]({rel})" if rel.endswith(".mp4") else f"![{caption}]({rel})")
        lines.append("")
    return atomic_write(out_dir / "report.md", "\n".join(lines))


def _example_traces(result, env_spec, scenario: dict, fault: str, agents: Sequence[str], record=record_episode) -> dict:
    """Re-run seed ``campaign.seeds[0]`` of ``agents`` (first training seed) and record their
    traces with ``record`` (:func:`record_episode` for wheel envs, :func:`record_state_trace` for any)."""
    jobs = episode_jobs(result.campaign, result.out_dir, skip_agents=result.skipped_agents)
    traces = {}
    for agent in agents:
        job = next(
            (
                j
                for j in jobs
                if j["key"]["env"] == env_spec.name
                and j["key"]["scenario"] == scenario["name"]
                and j["key"]["fault"] == fault
                and j["key"]["agent"] == agent
            ),
            None,
        )
        if job is None:
            continue
        env = gym.make(job["env_id"], **job["env_kwargs"])
        try:
            policy = build_policy(job["policy"], env, name=agent)
            traces[agent] = record(env, policy, seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
        finally:
            env.close()
    return traces


def _record_video(result, env_spec, agent: str, path_dir: Path) -> Path | None:
    """An episode of ``agent`` through gymnasium's ``RecordVideo`` (None when moviepy is missing)."""
    try:
        import moviepy  # noqa: F401  (optional: the video extra; RecordVideo needs it)
    except ImportError:
        return None
    job = next(
        j
        for j in episode_jobs(result.campaign, result.out_dir, skip_agents=result.skipped_agents)
        if j["key"]["env"] == env_spec.name and j["key"]["agent"] == agent
    )
    base = gym.make(job["env_id"], render_mode="rgb_array", **job["env_kwargs"])
    policy = build_policy(job["policy"], base, name=agent)
    prefix = f"{env_spec.name}-{agent}"
    env = RecordVideo(base, str(path_dir), name_prefix=prefix, episode_trigger=lambda e: e == 0, disable_logger=True)
    obs, info = env.reset(seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    policy.reset(job["key"]["seed"])
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        done = terminated or truncated
    env.close()
    videos = sorted(Path(path_dir).glob(f"{prefix}-episode-0.mp4"))
    return videos[0] if videos else None


def learned_agents(campaign) -> set[str]:
    """Names of the agents that learn (SB3 models, trained or given, and the Q-learning LQR)."""
    return {a.name for a in campaign.agents if a.spec.get("policy") in ("sb3", "q-learning-lqr")}


def history_agents(
    board: Sequence[Mapping[str, Any]], learned: set[str], drift: set[str] = frozenset({"zero"})
) -> list[str]:
    """The agents whose time histories a report shows for a cell: the best analytic controller
    and the best learned agent (free drift, ``drift``, is no controller); the best two when
    only one kind ran."""
    analytic, trained = _best(board, False, learned, drift), _best(board, True, learned, drift)
    picked = [e["agent"] for e in (analytic, trained) if e is not None]
    if len(picked) < 2:
        picked = [e["agent"] for e in board if e["agent"] not in drift and not is_oracle(e)][:2]
    return picked


def _training_runs(result, agent) -> list[Path]:
    """The run directories of a trained agent (one per training seed), sorted."""
    jobs = episode_jobs(result.campaign, result.out_dir)
    return sorted({Path(j["policy"]["model"]).parent.parent for j in jobs if j["key"]["agent"] == agent.name})


def _training_summary(result, agent) -> str:
    """A trained agent's budget (``config.json`` of each run) and the snapshot its episodes
    ran: ``best snapshot at N steps`` (per run, from ``best/best.json``; ``0 (the untrained
    policy)`` when training never beat it) or ``final snapshot``, with the validation J
    (the run's own eval episodes, their count and first seed) of the best and of the final policy."""
    budgets, best_steps, backends, validation, episodes = set(), [], set(), [], set()
    select = agent.train.get("select", "best")
    for run in _training_runs(result, agent):
        config = run / "config.json"
        if config.is_file():
            saved = json.loads(config.read_text())
            budgets.add(saved["total_timesteps"])
            backends.add(saved.get("backend", "sb3"))
            evaluation = saved.get("evaluation", {})
            episodes.add((evaluation.get("episodes"), evaluation.get("seed")))
        best = run / "best" / "best.json"
        if select == "best" and best.is_file():
            steps = json.loads(best.read_text())["timesteps"]
            best_steps.append(f"{steps} (the untrained policy)" if steps == 0 else str(steps))
        rows = _evaluation_rows(run)
        if rows:
            j_best, j_final = min(r[1] for r in rows), rows[-1][1]
            validation.append(f"{_fmt(j_best)}/{_fmt(j_final)}")
    t = agent.train
    steps = ", ".join(map(str, sorted(budgets))) or t.get("timesteps", "file default")
    snapshot = f"best snapshot at {', '.join(best_steps)} steps" if best_steps else "final snapshot"
    if validation:
        n = ""
        if len(episodes) == 1 and None not in next(iter(episodes)):
            count, first = next(iter(episodes))
            n = f" ({count} episodes, seeds {first}+)"
        snapshot += f"; validation J{n} best/final per seed: {', '.join(validation)}"
    backend = "/".join(sorted(backends)) or t.get("backend", "sb3")
    return f"{t['algo']} ({backend}), {steps} steps × seeds {t.get('seeds', [0])}, evaluated: {snapshot}"


def _evaluation_rows(run: Path) -> list[tuple[int, float]]:
    """``(timesteps, J_mean)`` of a training run's ``evaluations.csv`` (empty without one)."""
    path = run / "evaluations.csv"
    if not path.is_file():
        return []
    rows = path.read_text(encoding="utf-8").splitlines()[1:]
    return [(int(r.split(",")[0]), float(r.split(",")[1])) for r in rows if r]


def _training_task(result, agent) -> str:
    """What a trained agent learned on: its env id, decision period, discount and horizon
    ``Δt/(1 − γ)``, episode (s and decisions), and its training wall time per seed (every
    segment of a resumed run, ``timing.jsonl``; machine-dependent, so apart from the budget)."""
    parts, walls = [], []
    for run in _training_runs(result, agent):
        config = run / "config.json"
        if config.is_file() and not parts:
            saved = json.loads(config.read_text())
            parts.append(_task_text(saved["env_id"], saved["env_kwargs"], saved["hyperparams"]))
        timing = run / "timing.jsonl"
        if timing.is_file():
            lines = [json.loads(x) for x in timing.read_text(encoding="utf-8").splitlines() if x.strip()]
            walls.append(f"{sum(float(x['wall_time_s']) for x in lines):.0f} s")
    if walls:
        parts.append(f"training wall time per seed: {', '.join(walls)}")
    return "; ".join(parts)


def _task_text(env_id: str, env_kwargs: Mapping[str, Any], hyperparams: Mapping[str, Any]) -> str:
    """``AirBearing-v1: decisions every 0.5 s, γ 0.96 (horizon 12.5 s), episodes of 20 s (40 decisions)``."""
    env = gym.make(env_id, **{k: v for k, v in env_kwargs.items() if k != "faults"})
    try:
        base = env.unwrapped
        dt, length, decisions = float(base.control_dt_s), base.episode_length_s, base.decisions_per_episode
    finally:
        env.close()
    gamma = float(hyperparams.get("gamma", 0.99))
    return (
        f"{env_id.split('/')[-1]}: decisions every {dt:g} s, γ {gamma:g} (horizon Δt/(1 − γ) = {dt / (1 - gamma):.3g} s), "
        f"episodes of {float(length):g} s ({decisions} decisions)"
    )


def snapshot_description(model: str | Path) -> str:
    """Which snapshot a saved model is: ``best snapshot at N steps`` / ``final snapshot at N
    steps`` (of a training run) or ``checkpoint at N steps``, else ``model file``."""
    model = Path(model)
    steps = None
    best = model.parent / "best.json"
    if model.parent.name == "best" and best.is_file():
        steps = json.loads(best.read_text(encoding="utf-8")).get("timesteps")
    if steps is None:
        try:
            with zipfile.ZipFile(model) as zf:
                steps = json.loads(zf.read("data").decode("utf-8")).get("num_timesteps")
        except (OSError, KeyError, ValueError, zipfile.BadZipFile):
            steps = None
    kind = {"best": "best snapshot", "final": "final snapshot"}.get(model.parent.name)
    if kind is None:
        kind = "checkpoint" if model.parent.parent.name == "checkpoints" else "model file"
    return f"{kind} at {steps} steps" if steps is not None else kind


def _all_runs(result) -> str:
    """``12.3 over 3 run(s) (runs.jsonl, 1 interrupted, 1 killed): <each run>``."""
    others = {k: n for k, n in getattr(result, "run_statuses", {}).items() if k != "completed"}
    detail = "".join(f", {n} {k}" for k, n in others.items())
    killed = " — a killed run counts up to its last progress line" if "killed" in others else ""
    each = "; ".join(_run_summary(r) for r in getattr(result, "run_log", []))
    each = f": {each}" if each else ""
    return f"{result.total_wall_time_s:.1f} over {result.runs} run(s) (runs.jsonl{detail}){killed}{each}"


def _run_summary(run: Mapping[str, Any]) -> str:
    """``1897.1 s on local-pool[2], 12 trained, 1520 episodes`` of one :func:`read_runs` entry."""
    parts = [f"{float(run.get('wall_time_s', 0.0)):.1f} s on {run.get('executor', '?')}"]
    if run.get("trained"):
        parts.append(f"{run['trained']} trained")
    if "episodes_run" in run:
        parts.append(f"{run['episodes_run']} episodes" if run["episodes_run"] else "report only")
    if run.get("status") not in (None, "completed"):
        parts.append(str(run["status"]))
    speeds = [run[k] for k in ("reference_steps_per_s", "reference_steps_per_s_end") if run.get(k)]
    if speeds:  # the machine's speed then (experiments.machine_reference), to compare wall times
        parts.append(f"{REFERENCE_ENV} at {' → '.join(f'{v / 1000:.1f}k' for v in speeds)} steps/s")
    return ", ".join(parts)


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
    figures: dict[str, str] = {}
    plot_leaderboard(boards, out_dir / "figures" / "leaderboard.png")
    figures["J per agent (mean, 95 % CI)"] = "figures/leaderboard.png"
    notes = [f"agent {a} skipped: {why}" for a, why in result.skipped_agents.items()]
    notes += getattr(result, "optimum_notes", [])
    for env_spec in result.campaign.envs:
        heat = plot_fault_heatmap(rows, env_spec.name, out_dir / "figures" / f"faults-{env_spec.name}.png")
        if heat is not None:
            figures[f"{env_spec.name}: fault campaign"] = f"figures/faults-{env_spec.name}.png"
        cell = next((c for c in boards if c[0] == env_spec.name), None)
        if cell is None:
            continue
        probe = gym.make(env_spec.id, **env_spec.kwargs)
        is_rw = probe.unwrapped.wheel_trace
        probe.close()
        best = boards[cell][0]["agent"]
        for scenario in env_spec.scenarios:  # every cell: its best analytic controller and best learned agent
            for fault in env_spec.faults:
                board = boards.get((env_spec.name, scenario["name"], fault), [])
                agents = history_agents(board, learned_agents(result.campaign), free_drift_agents(result.campaign))
                if not agents:
                    continue
                record = record_episode if is_rw else record_state_trace
                traces = _example_traces(result, env_spec, scenario, fault, agents, record)
                if not traces:
                    continue
                name = f"figures/history-{env_spec.name}-{scenario['name']}-{fault}.png"
                plot = _plots().plot_episodes if is_rw else _plots().plot_state_histories
                plot(
                    traces,
                    out_dir / name,
                    title=f"{env_spec.name} · {scenario['name']} · {fault} · seed {result.campaign.seeds[0]}",
                )
                label = f"{env_spec.name}: time histories, best analytic vs best learned ({scenario['name']}, {fault})"
                figures[label] = name
        if is_rw:
            if video:
                path = _record_video(result, env_spec, best, out_dir / "videos")
                if path is not None:
                    figures[f"{env_spec.name}: episode video of the best agent ({best})"] = f"videos/{path.name}"
                else:
                    notes.append("no episode video: gymnasium's RecordVideo needs the optional package moviepy")
            else:
                notes.append(
                    "episode videos off for this campaign (video: false; rendering a 60 s episode takes minutes)"
                )
    budget = {a.name: _training_summary(result, a) for a in result.campaign.agents if a.train is not None}
    tasks = {a.name: _training_task(result, a) for a in result.campaign.agents if a.train is not None}
    models = {
        a.name: f"{a.spec['model']} ({snapshot_description(a.spec['model'])})"
        for a in result.campaign.agents
        if a.train is None and a.spec.get("policy") == "sb3" and a.name not in result.skipped_agents
    }
    criteria = {e.name: success_criterion(e.id, e.kwargs, result.campaign) for e in result.campaign.envs}
    definitions = {}
    for e in result.campaign.envs:
        definitions[f"env: {e.name}"] = env_label(e)
        for scenario in e.scenarios:
            extra = {k: scenario[k] for k in ("options", "env_kwargs") if scenario.get(k)}
            if extra:
                definitions[f"scenario: {e.name} · {scenario['name']}"] = f"`{json.dumps(extra)}`"
        for fault, faults in e.faults.items():
            if faults:
                definitions[f"fault: {e.name} · {fault}"] = f"`{json.dumps(faults)}`"
    for a in result.campaign.agents:  # an agent's own task on the cells' episodes (J* stays the cell's)
        if a.env_id is not None or a.env_kwargs:
            own = [a.env_id.split("/")[-1]] if a.env_id is not None else []
            own += [f"`{json.dumps(a.env_kwargs)}`"] if a.env_kwargs else []
            definitions[f"agent task: {a.name}"] = f"plays the cells' episodes on {' '.join(own)}"
    metadata = {
        "campaign": result.campaign.name,
        "source": result.campaign.source,
        "command": command,
        "package_version": package_version(),
        "git_revision": git_revision(),
        "seeds": result.campaign.seeds,
        "executor": result.executor,
        "episodes": len(rows),
        "wall_time_s": round(result.wall_time_s, 1),
        "wall_time_all_runs_s": _all_runs(result),
        "training_budget": budget,
        "training_task": tasks,
        "models": models,
        "success_criteria": criteria,
        "success_thresholds": campaign_thresholds(result.campaign),  # J*'s own success (leaderboards)
        "definitions": definitions,
        "trained": result.trained,
    }
    if result.campaign.agent_notes:
        metadata["agent_notes"] = result.campaign.agent_notes
    return write_report(out_dir, rows, metadata, figures, notes)


def _best(
    board: Sequence[Mapping[str, Any]], learned: bool, trained: set[str], drift: set[str] = frozenset({"zero"})
) -> Mapping[str, Any] | None:
    """The lowest-J entry among the learned (``trained``) or the other agents; free drift
    (``drift``: the agents with ``policy: zero``) is no controller."""
    pick = [e for e in board if (e["agent"] in trained) == learned and e["agent"] not in drift and not is_oracle(e)]
    return pick[0] if pick else None


def free_drift_agents(campaign) -> set[str]:
    """Names of the agents that apply no control (``policy: zero``)."""
    return {a.name for a in campaign.agents if a.spec.get("policy") == "zero"}


def _best_cell(e: Mapping[str, Any] | None) -> str:
    if e is None:
        return "—"
    early = e.get("terminated_rate", 0.0)
    flag = f", ended early {100 * early:.0f} %" if early > 0 else ""
    return f"{e['agent']}: J {_fmt(e['J_mean'])}, J/J* {_ratio_cell(e)}{flag}"


def env_label(env) -> str:
    """A campaign env as its registered id and constructor kwargs, both as code spans."""
    return f"`{env.id}` `{json.dumps(env.kwargs)}`"


def write_campaign_index(out_dir: str | Path, results: Sequence[tuple[str, Any]]) -> Path:
    """``OUT/index.md`` of ``--config all``: per campaign its envs (id and kwargs), wall time
    and report, and per leaderboard cell the best analytic controller and the best learned
    agent (mean J and J/J*); the leaderboards themselves are in each campaign's report."""
    out_dir = Path(out_dir)
    lines = ["# All plant campaigns", "", f"Package {package_version()}, git {git_revision()}.", ""]
    lines += ["| campaign | env (id, kwargs) | episodes | wall time s (all runs) | report |", "|---|---|---:|---|---|"]
    for name, result in results:
        envs = "; ".join(env_label(e) for e in result.campaign.envs)
        lines.append(
            f"| {name} | {envs} | {len(result.rows)} | {_all_runs(result)} | [{name}/report.md]({name}/report.md) |"
        )
    lines += ["", "| campaign | env · scenario · fault | best analytic | best learned |", "|---|---|---|---|"]
    for name, result in results:
        trained, drift = learned_agents(result.campaign), free_drift_agents(result.campaign)
        for cell, board in leaderboards(result.rows, campaign_thresholds(result.campaign)).items():
            analytic, learned = _best(board, False, trained, drift), _best(board, True, trained, drift)
            lines.append(f"| {name} | {' · '.join(cell)} | {_best_cell(analytic)} | {_best_cell(learned)} |")
    return atomic_write(out_dir / "index.md", "\n".join(lines) + "\n")
