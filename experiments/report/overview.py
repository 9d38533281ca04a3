"""The benchmark at a glance: one leaderboard over the campaigns of ``--config all`` (the five
plant campaigns and the constrained slews) and two figures.

Reads each campaign's committed ``episodes.csv`` (``docs/campaigns/<plant>/``) and writes

* a markdown table, one row per plant × cell (env · scenario · fault): J*'s own success, the
  best analytic controller and the best learned agent with ΣJ / ΣJ* and its 95 % paired
  bootstrap CI (:func:`~experiments.report.statistics.ratio_stats`, the plant pages' column);
* figure 1 (``overview-ratios.png``): J / J* of every episode per controller and plant (log y);
* figure 2 (``overview-profiles.png``) and a small table: the cross-plant aggregates of the
  normalized score J* / J (1: the optimum, 0: an unbounded cost) over the tasks (plant × cell):
  performance profiles, IQM and the probability that the best learned agent beats the best
  analytic controller on a task, each with a 95 % stratified bootstrap CI.

The aggregates follow rliable (Agarwal et al. 2021; the optional extra ``rliable``):
``rliable.metrics`` gives the IQM and the probability of improvement and
``rliable.plot_utils`` draws the profiles. Their CIs are percentile intervals of
:func:`scipy.stats.bootstrap` with one sample per task (each task's episodes resampled on their
own: rliable's stratified bootstrap); rliable's own bootstrap (``rliable.library``) imports
``arch``, whose 7.x releases (rliable 1.2.0 needs ``arch<8``) fail to import under pandas 3.
Runs are pooled over the tasks, each task with its own episode count (the learned agents have
training seeds × evaluation seeds).

The table and the aggregates are pasted into ``docs/benchmarks.md`` between
:data:`MARK_START` and :data:`MARK_END`::

    python -m experiments.report.overview   # docs/campaigns → docs/benchmarks.md, docs/figures (≈ 45 s)
"""

from __future__ import annotations

import argparse
import csv
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from attitude_envs.files import atomic_write
from experiments.campaign.spec import ALL_CAMPAIGNS, PRESETS, load_campaign
from experiments.campaign.store import RUN_STATUSES, CampaignResult, read_runs
from experiments.report.leaderboards import (
    best_entry,
    campaign_thresholds,
    free_drift_agents,
    is_oracle,
    leaderboards,
    learned_agents,
)
from experiments.report.markdown import ratio_cell
from experiments.report.statistics import N_BOOT, SEED
from experiments.report.writing import write_campaign_index

#: the markers in ``docs/benchmarks.md`` between which :func:`write_overview` pastes its text
MARK_START = "<!-- leaderboard:start -->"
MARK_END = "<!-- leaderboard:end -->"

#: the aggregates' two chosen controllers of every task
BEST_ANALYTIC = "best analytic"
BEST_LEARNED = "best learned"

#: the columns of ``episodes.csv`` that stay text (every other is a number, a flag or empty)
TEXT_COLUMNS = frozenset({"env", "scenario", "fault", "agent", "j_star_source", "j_star_metric"})

#: the normalized-score thresholds τ of the performance profiles (J* / J, dimensionless)
TAUS = np.linspace(0.0, 1.0, 51)

#: the command that regenerates the overview (for the page)
COMMAND = "python -m experiments.report.overview"

_REPO = Path(__file__).resolve().parents[2]


def _value(column: str, text: str) -> Any:
    """One ``episodes.csv`` cell typed: None for empty, bool for True/False, float for a number."""
    if column in TEXT_COLUMNS:
        return text
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    try:
        return float(text)
    except ValueError:
        return text


def read_episodes(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a campaign's ``episodes.csv``, typed (:func:`_value`): J and J* in the env's
    cost units, ``train_seed`` None for an agent that was not trained."""
    with Path(path).open(newline="", encoding="utf-8") as fh:
        return [{k: _value(k, v) for k, v in row.items()} for row in csv.DictReader(fh)]


@dataclass
class Plant:
    """One plant campaign's episodes and what the overview needs to know of its agents.

    ``learned``: agents that learn (trained ones carry a ``train_seed``; the campaign's
    ``policy: sb3`` and ``policy: q-learning-lqr`` agents); ``drift``: agents that apply no
    control (``policy: zero``, or named ``zero``); ``thresholds``: success-metric name → the
    campaign's threshold (J*'s own success), None for each metric's default."""

    name: str
    rows: list[dict[str, Any]]
    learned: set[str] = field(default_factory=set)
    drift: set[str] = field(default_factory=set)
    thresholds: dict[str, float] | None = None


def load_plant(name: str, campaigns_dir: str | Path, campaign: Any = None) -> Plant:
    """``campaigns_dir/name/episodes.csv`` as a :class:`Plant`; ``campaign`` (a
    :class:`~experiments.campaign.spec.Campaign`, default: the preset ``name`` when there is one)
    adds its agents' policies and success thresholds to what the rows carry."""
    rows = read_episodes(Path(campaigns_dir) / name / "episodes.csv")
    if campaign is None and name in PRESETS:
        campaign = load_campaign(name)
    learned = {r["agent"] for r in rows if r.get("train_seed") is not None}
    drift = {r["agent"] for r in rows if r["agent"] == "zero"}
    thresholds = None
    if campaign is not None:
        learned |= learned_agents(campaign)
        drift |= free_drift_agents(campaign)
        thresholds = campaign_thresholds(campaign)
    return Plant(name, rows, learned, drift, thresholds)


@dataclass
class Cell:
    """One row of the overview: a plant's env × scenario × fault cell, its leaderboard and the
    episodes of each agent."""

    plant: str
    cell: tuple[str, str, str]
    board: list[dict[str, Any]]
    episodes: dict[str, list[dict[str, Any]]]
    analytic: Mapping[str, Any] | None
    learned: Mapping[str, Any] | None
    oracle: Mapping[str, Any] | None
    drift: set[str] = field(default_factory=set)


def overview_cells(plants: Sequence[Plant]) -> list[Cell]:
    """Every plant's cells in order, each with its best analytic controller and best learned
    agent: the first of its kind on the cell's leaderboard (fewest episodes ended early, then
    the lowest mean J: :func:`~experiments.report.leaderboards.leaderboards`), free drift none."""
    out = []
    for plant in plants:
        by_cell: dict[tuple[str, str, str], dict[str, list[dict[str, Any]]]] = {}
        for r in plant.rows:
            by_cell.setdefault((r["env"], r["scenario"], r["fault"]), {}).setdefault(r["agent"], []).append(r)
        for cell, board in leaderboards(plant.rows, plant.thresholds).items():
            out.append(
                Cell(
                    plant=plant.name,
                    cell=cell,
                    board=board,
                    episodes=by_cell[cell],
                    analytic=best_entry(board, False, plant.learned, plant.drift),
                    learned=best_entry(board, True, plant.learned, plant.drift),
                    oracle=next((e for e in board if is_oracle(e)), None),
                    drift=set(plant.drift),
                )
            )
    return out


def _rate(value: float) -> str:
    """A share as ``95 %``; — when unknown."""
    return f"{100 * value:.0f} %" if np.isfinite(value) else "—"


def _agent_cell(e: Mapping[str, Any] | None) -> str:
    """An entry's agent, a trained one with its episodes (``ppo (3 training seeds × 20 episodes)``)."""
    if e is None:
        return "—"
    seeds = int(e.get("train_seeds", 1))
    if seeds > 1:
        return f"{e['agent']} ({seeds} training seeds × {e['episodes'] // seeds} episodes)"
    return str(e["agent"])


def _ratio(e: Mapping[str, Any] | None) -> str:
    """ΣJ / ΣJ* [95 % CI], with the share of episodes ended early when any did."""
    if e is None:
        return "—"
    early = float(e.get("terminated_rate", 0.0))
    return ratio_cell(e) + (f", ended early {100 * early:.0f} %" if early > 0 else "")


#: what the leaderboard table's columns mean (printed under the figures)
LEADERBOARD_LEGEND = (
    "J* success: the share of the cell's episodes whose optimum (its actions replayed) meets the campaign's "
    "success criterion; — where J*'s measurements are not kept. ΣJ / ΣJ*: the cell's total cost over the total "
    "optimal cost of the same episodes (1: optimal), 95 % paired percentile bootstrap CI over episodes "
    "(deterministic: every episode gave the same ratio). Best: the first of its kind on the cell's leaderboard "
    "on the plant page (fewest episodes ended early, then, in the slew's cell, the fewest with a constraint "
    "violated, then the lowest mean J). Learned: the agents trained by "
    "the campaign (PPO, SAC: every training seed × every evaluation seed) and the Q-learning LQR; analytic: "
    "every other controller; free drift (zero torque) is neither."
)


def leaderboard_table(cells: Sequence[Cell]) -> str:
    """The overview's markdown table (one row per plant × cell) and its footnote."""
    head = [
        "plant",
        "env · scenario · fault",
        "J* success",
        "best analytic",
        "ΣJ / ΣJ* [95 % CI]",
        "best learned",
        "ΣJ / ΣJ* [95 % CI]",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    previous = None
    for c in cells:
        success = _rate(float(c.oracle["success_rate"])) if c.oracle is not None else "—"
        page = f"[{c.plant}](campaigns/{c.plant}/report.md)" if c.plant != previous else ""
        previous = c.plant
        lines.append(
            f"| {page} | {' · '.join(c.cell)} | {success} | {_agent_cell(c.analytic)} | {_ratio(c.analytic)} "
            f"| {_agent_cell(c.learned)} | {_ratio(c.learned)} |"
        )
    return "\n".join(lines) + "\n"


# --- the cross-plant aggregates (rliable's metrics) ---------------------------------------------


def normalized_scores(rows: Sequence[Mapping[str, Any]]) -> np.ndarray:
    """J* / J of each episode that has a positive J* (dimensionless; 1 at the optimum, 0 for a
    non-finite J)."""
    out = []
    for r in rows:
        j_star, j = r.get("j_star"), r.get("J")
        if j_star is None or not np.isfinite(float(j_star)) or float(j_star) <= 0.0:
            continue
        out.append(float(j_star) / float(j) if j is not None and np.isfinite(float(j)) and float(j) > 0 else 0.0)
    return np.asarray(out, dtype=float)


def task_scores(cells: Sequence[Cell]) -> dict[str, list[np.ndarray]]:
    """Algorithm → one array of normalized scores (:func:`normalized_scores`) per task (plant ×
    cell): :data:`BEST_ANALYTIC`, :data:`BEST_LEARNED` and each controller that ran on every task,
    over the tasks where both best ones have at least two scored episodes."""
    tasks = []
    for c in cells:
        if c.analytic is None or c.learned is None:
            continue
        a, b = normalized_scores(c.episodes[c.analytic["agent"]]), normalized_scores(c.episodes[c.learned["agent"]])
        if len(a) > 1 and len(b) > 1:
            tasks.append((c, a, b))
    out: dict[str, list[np.ndarray]] = {BEST_ANALYTIC: [a for _, a, _ in tasks], BEST_LEARNED: [b for _, _, b in tasks]}
    drift = set().union(*(c.drift for c, _, _ in tasks)) if tasks else set()
    common = set.intersection(*(set(c.episodes) for c, _, _ in tasks)) - drift if tasks else set()
    for agent in sorted(common):
        scores = [normalized_scores(c.episodes[agent]) for c, _, _ in tasks]
        if all(len(s) > 1 for s in scores):
            out[agent] = scores
    return out


def _rliable():
    """``(rliable.metrics, rliable.plot_utils)``; ImportError saying how to install them."""
    try:
        from rliable import metrics, plot_utils  # optional: the rliable extra
    except ImportError as exc:
        raise ImportError(
            "the cross-plant aggregates need rliable: pip install -c constraints.txt -e '.[rliable]' "
            "(or run the overview with --no-aggregates)"
        ) from exc
    return metrics, plot_utils


def stratified_ci(
    samples: Sequence[np.ndarray], statistic: Callable[..., Any], n_boot: int = N_BOOT, seed: int = SEED
) -> tuple[np.ndarray, np.ndarray]:
    """95 % percentile CI of ``statistic(*samples)`` by :func:`scipy.stats.bootstrap` with each
    sample (a task's scores) resampled on its own (``paired=False``: a stratified bootstrap),
    ``n_boot`` resamples from a generator seeded with ``seed``; arrays for an array statistic."""
    res = stats.bootstrap(
        tuple(samples),
        statistic,
        n_resamples=int(n_boot),
        confidence_level=0.95,
        method="percentile",
        vectorized=False,
        paired=False,
        random_state=np.random.default_rng(seed),
    )
    return np.asarray(res.confidence_interval.low), np.asarray(res.confidence_interval.high)


def score_profile(samples: Sequence[np.ndarray], taus: np.ndarray = TAUS) -> np.ndarray:
    """The performance profile: the share of all runs (pooled over tasks) scoring above each τ."""
    pooled = np.concatenate(samples)
    return (pooled[None, :] > np.asarray(taus)[:, None]).mean(axis=1)


#: normalized scores (J* / J, in [0, 1]) are compared at this many decimals in P(X > Y), so that
#: two controllers equal to floating-point noise tie: LinearSystem's Q-learning LQR and its DARE
#: LQR give the same J to 3e-14, and unrounded, the last bits decided that whole task (0 or 1)
TIE_DECIMALS = 9


def improvement_probability(metrics: Any, x: Sequence[np.ndarray], y: Sequence[np.ndarray]) -> float:
    """P(X > Y) of two algorithms' scores ``x`` and ``y`` (one array per task), averaged over the
    tasks: ``metrics`` is ``rliable.metrics``, whose ``probability_of_improvement`` runs here on
    one task at a time, so that X and Y may have different run counts on a task. Scores equal
    to :data:`TIE_DECIMALS` decimals count as a tie (½)."""
    return float(
        np.mean(
            [
                metrics.probability_of_improvement(
                    np.round(a, TIE_DECIMALS)[:, None], np.round(b, TIE_DECIMALS)[:, None]
                )
                for a, b in zip(x, y, strict=True)
            ]
        )
    )


def aggregates(scores: Mapping[str, list[np.ndarray]], n_boot: int = N_BOOT, seed: int = SEED) -> dict[str, Any]:
    """Per algorithm its IQM of the normalized score with a 95 % stratified bootstrap CI
    (``iqm``: ``(point, low, high)``), its performance profile over :data:`TAUS` with CIs
    (``profile``: ``(point, low, high)`` arrays), the task count and, as
    ``improvement``, P(best learned > best analytic) with its CI (both resampled in one
    stratified bootstrap, each task's two samples on their own). Needs rliable."""
    metrics, _ = _rliable()
    out: dict[str, Any] = {"algorithms": {}, "tasks": len(next(iter(scores.values()), []))}
    for name, samples in scores.items():
        point = float(metrics.aggregate_iqm(np.concatenate(samples)))
        lo, hi = stratified_ci(samples, lambda *s: metrics.aggregate_iqm(np.concatenate(s)), n_boot, seed)
        p_lo, p_hi = stratified_ci(samples, lambda *s: score_profile(s), n_boot, seed)
        out["algorithms"][name] = {
            "iqm": (point, float(lo), float(hi)),
            "profile": (score_profile(samples), p_lo, p_hi),
            "runs": int(sum(len(s) for s in samples)),
        }
    x, y = scores[BEST_LEARNED], scores[BEST_ANALYTIC]
    n = len(x)
    point = improvement_probability(metrics, x, y)
    lo, hi = stratified_ci([*x, *y], lambda *s: improvement_probability(metrics, s[:n], s[n:]), n_boot, seed)
    out["improvement"] = (point, float(lo), float(hi))
    return out


def aggregates_table(agg: Mapping[str, Any]) -> str:
    """The aggregates as a markdown table (IQM per algorithm) and the probability of improvement."""
    lines = [
        f"| controller (over {agg['tasks']} tasks) | episodes | IQM of J* / J [95 % CI] |",
        "|---|---:|---|",
    ]
    for name, a in agg["algorithms"].items():
        point, lo, hi = a["iqm"]
        lines.append(f"| {name} | {a['runs']} | {point:.4f} [{lo:.4f}, {hi:.4f}] |")
    p, lo, hi = agg["improvement"]
    lines += [
        "",
        f"P(best learned > best analytic) = {p:.3f} [{lo:.3f}, {hi:.3f}]: the chance that an episode of the best "
        "learned agent scores above one of the best analytic controller on the same task, averaged over tasks "
        "(Mann–Whitney U / (n m), rliable's probability of improvement); 0.5 is a tie.",
    ]
    return "\n".join(lines) + "\n"


# --- figures -------------------------------------------------------------------------------------


def _plots():
    """:mod:`experiments.plots` (matplotlib.pyplot on the Agg backend), imported on first use."""
    from experiments import plots

    return plots


def plot_ratios(cells: Sequence[Cell], path: str | Path) -> Path:
    """Figure 1: J / J* of every episode per controller (box per cell, log y), one panel per plant;
    free drift left out, the best analytic and best learned of each cell marked."""
    plots = _plots()
    plants = list(dict.fromkeys(c.plant for c in cells))
    fig, axes = plots.plt.subplots(len(plants), 1, figsize=(9.0, 2.6 * len(plants) + 0.4), squeeze=False)
    colors = plots.plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, plant in zip(axes[:, 0], plants, strict=True):
        mine = [c for c in cells if c.plant == plant]
        agents = list(dict.fromkeys(e["agent"] for c in mine for e in c.board if not is_oracle(e)))
        agents = [a for a in agents if not any(a in c.drift for c in mine)]
        width = 0.8 / max(len(mine), 1)
        for k, c in enumerate(mine):
            data, pos = [], []
            for i, agent in enumerate(agents):
                s = normalized_scores(c.episodes.get(agent, []))
                s = s[s > 0]
                if len(s):
                    data.append(1.0 / s)
                    pos.append(i - 0.4 + width * (k + 0.5))
            if not data:
                continue
            color = colors[k % len(colors)]
            ax.boxplot(
                data,
                positions=pos,
                widths=width * 0.85,
                whis=(0, 100),
                patch_artist=True,
                boxprops={"facecolor": color, "alpha": 0.45, "edgecolor": color},
                medianprops={"color": "k"},
                whiskerprops={"color": color},
                capprops={"color": color},
            )
            ax.plot([], [], color=color, lw=6, alpha=0.45, label=" · ".join(c.cell[1:]))
        ax.set_yscale("log")
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xticks(range(len(agents)), agents, rotation=25, ha="right", fontsize=8)
        ax.set_xlim(-0.6, len(agents) - 0.4)
        ax.set_title(plant, fontsize=10)
        ax.set_ylabel("J / J*")
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("J / J* per episode (box: quartiles, whiskers: min–max; 1: the optimum)", fontsize=10)
    fig.tight_layout()
    return plots.save_figure(fig, path, dpi=100)


def plot_profiles(agg: Mapping[str, Any], path: str | Path) -> Path:
    """Figure 2: the performance profiles of J* / J with their 95 % CIs (rliable's plot) and
    each algorithm's IQM with its CI. Needs rliable."""
    _, plot_utils = _rliable()
    plots = _plots()
    fig, (left, right) = plots.plt.subplots(1, 2, figsize=(11.0, 4.0), gridspec_kw={"width_ratios": [3, 2]})
    algs = agg["algorithms"]
    profiles = {k: a["profile"][0] for k, a in algs.items()}
    cis = {k: np.stack([a["profile"][1], a["profile"][2]]) for k, a in algs.items()}
    colors = dict(zip(algs, plots.plt.rcParams["axes.prop_cycle"].by_key()["color"], strict=False))
    styles = {k: "-" if k in (BEST_ANALYTIC, BEST_LEARNED) else "--" for k in algs}
    plot_utils.plot_performance_profiles(
        profiles,
        TAUS,
        performance_profile_cis=cis,
        colors=colors,
        linestyles=styles,
        xlabel=r"normalized score J* / J ($\tau$)",
        ylabel=r"fraction of episodes with J* / J $> \tau$",
        ax=left,
    )
    handles = [plots.plt.Line2D([0], [0], color=colors[k], ls=styles[k]) for k in algs]
    left.legend(handles, list(algs), fontsize=8, loc="lower left")
    names = list(algs)
    for i, k in enumerate(names):
        point, lo, hi = algs[k]["iqm"]
        right.errorbar(point, i, xerr=[[point - lo], [hi - point]], fmt="o", color=colors[k], capsize=4)
    right.set_yticks(range(len(names)), names, fontsize=8)
    right.invert_yaxis()
    right.set_xlabel("IQM of J* / J (95 % stratified bootstrap CI)")
    right.grid(True, axis="x", alpha=0.3)
    fig.suptitle(f"Over {agg['tasks']} tasks (plant × cell)", fontsize=10)
    fig.tight_layout()
    return plots.save_figure(fig, path, dpi=100)


# --- the page ------------------------------------------------------------------------------------


def overview_markdown(cells: Sequence[Cell], agg: Mapping[str, Any] | None, figure_dir: str) -> str:
    """The text pasted between the markers: the table, figure 1 and (with ``agg``) figure 2 first,
    then what the table's columns mean and (with ``agg``) the aggregates' table; ``figure_dir``:
    the figures' folder relative to the page."""
    lines = [
        "<!-- generated from docs/campaigns/*/episodes.csv (the command: the last line of this block); "
        "edits here are overwritten -->",
        "",
        leaderboard_table(cells),
        f"![J / J* per controller and plant]({figure_dir}/overview-ratios.png)",
        "",
    ]
    if agg is not None:
        lines += [f"![Performance profiles and IQM of J* / J]({figure_dir}/overview-profiles.png)", ""]
    lines += [LEADERBOARD_LEGEND, ""]
    if agg is not None:
        lines += [
            "Across plants: the normalized score J* / J of every episode (1: the optimum), over the tasks "
            "(plant × cell) where both a best analytic controller and a best learned agent ran, and for the "
            "controllers that ran on every task; IQM (the mean of the middle half of the episodes, pooled over "
            "tasks) and performance profiles (the share of episodes above each score) with 95 % stratified "
            "bootstrap CIs (each task's episodes resampled on their own). The best of a cell is chosen on the "
            "same episodes, so the best columns lean optimistic.",
            "",
            aggregates_table(agg),
        ]
    lines += [
        f"This overview is generated by `{COMMAND}` (about 45 s on 2 cores) from each plant page's "
        "`episodes.csv` (the aggregates "
        'need the `rliable` extra: `pip install -c constraints.txt -e ".[rliable]"`).',
        "",
    ]
    return "\n".join(lines)


def paste_between_markers(page: str, text: str) -> str:
    """``page`` with everything between :data:`MARK_START` and :data:`MARK_END` replaced by
    ``text``; ValueError when the markers are missing or out of order."""
    start, end = page.find(MARK_START), page.find(MARK_END)
    if start < 0 or end < start:
        raise ValueError(f"the page needs the markers {MARK_START} and {MARK_END}, in that order")
    return page[: start + len(MARK_START)] + "\n" + text.rstrip("\n") + "\n" + page[end:]


def page_result(name: str, campaigns_dir: str | Path) -> CampaignResult:
    """A committed campaign page (``campaigns_dir/name``: ``episodes.csv`` and ``runs.jsonl``) as
    the :class:`~experiments.campaign.store.CampaignResult` its run returned, for
    :func:`~experiments.report.writing.write_campaign_index`: its rows and every logged run."""
    out_dir = Path(campaigns_dir) / name
    rows = read_episodes(out_dir / "episodes.csv")
    runs = read_runs(out_dir / "runs.jsonl")
    return CampaignResult(
        campaign=load_campaign(name),
        out_dir=out_dir,
        rows=rows,
        trained=[],
        skipped_agents={},
        episodes_run=0,
        episodes_skipped=len(rows),
        wall_time_s=0.0,
        executor="",
        total_wall_time_s=sum(float(r["wall_time_s"]) for r in runs),
        runs=len(runs),
        run_statuses={s: n for s in RUN_STATUSES if (n := sum(r["status"] == s for r in runs))},
        run_log=runs,
    )


def write_overview(
    campaigns_dir: str | Path,
    page: str | Path,
    figures_dir: str | Path,
    plants: Sequence[str] = ALL_CAMPAIGNS,
    aggregate: bool = True,
    n_boot: int = N_BOOT,
) -> dict[str, Path]:
    """Read ``campaigns_dir/<plant>/episodes.csv`` of ``plants``, draw the figures into
    ``figures_dir`` and paste the overview into ``page`` between the markers (atomically); when
    every plant is a shipped campaign, write ``campaigns_dir/index.md``
    (:func:`~experiments.report.writing.write_campaign_index`, the page ``--config all`` writes)
    from the same pages. ``aggregate``: also the rliable aggregates
    (figure 2 and their table). Returns what it wrote."""
    cells = overview_cells([load_plant(p, campaigns_dir) for p in plants])
    figures_dir, page = Path(figures_dir), Path(page)
    written = {"ratios": plot_ratios(cells, figures_dir / "overview-ratios.png")}
    agg = None
    if aggregate:
        agg = aggregates(task_scores(cells), n_boot=n_boot)
        written["profiles"] = plot_profiles(agg, figures_dir / "overview-profiles.png")
    rel = Path(os.path.relpath(figures_dir.resolve(), page.parent.resolve())).as_posix()
    text = overview_markdown(cells, agg, rel)
    written["page"] = atomic_write(page, paste_between_markers(page.read_text(encoding="utf-8"), text))
    if all(p in PRESETS for p in plants):  # the index names each campaign's envs: its definition is needed
        written["index"] = write_campaign_index(campaigns_dir, [(p, page_result(p, campaigns_dir)) for p in plants])
    return written


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m experiments.report.overview``: the overview of the committed plant campaigns."""
    parser = argparse.ArgumentParser(prog="python -m experiments.report.overview", description=__doc__.split("\n")[0])
    parser.add_argument("--campaigns", default=str(_REPO / "docs" / "campaigns"), help="folder of <plant>/episodes.csv")
    parser.add_argument("--page", default=str(_REPO / "docs" / "benchmarks.md"), help="page with the markers")
    parser.add_argument("--figures", default=str(_REPO / "docs" / "figures"), help="folder of the two PNGs")
    parser.add_argument("--plants", nargs="+", default=list(ALL_CAMPAIGNS), help="campaigns, in order")
    parser.add_argument("--no-aggregates", action="store_true", help="skip rliable's aggregates (figure 2)")
    args = parser.parse_args(argv)
    written = write_overview(args.campaigns, args.page, args.figures, args.plants, aggregate=not args.no_aggregates)
    for what, path in written.items():
        print(f"{what}: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
