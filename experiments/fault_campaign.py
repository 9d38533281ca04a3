"""Fault campaigns: a grid of actuator fault kind × severity × onset run for any policy,
each episode's cost J reported relative to the healthy episode of the same seed, with
optional IMM fault detection (detection delay, false alarms) — table and heatmap.

Severity ``s`` in [0, 1] maps to each kind's fault dict (:data:`SEVERITY`), so one grid
compares kinds on a common axis. Built on :func:`attitude_envs.evaluation.rollout.rollout`.

Command line (``python -m experiments.fault_campaign``)::

    ... scenario wheel-failure --policy lqr --seeds 3          # one scenario vs healthy
    ... campaign --policy lqr --out results/ [--fdi] [--quick] # the fault-campaign grid
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from matplotlib.colors import LogNorm

from attitude_envs import validation
from attitude_envs.estimation.fdi import ActuatorFDI, run_fdi_episode
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.scenarios import load_scenario, make_scenario_env
from baselines.base import ZeroPolicy
from baselines.lqr import LQRPolicy
from experiments.seeds import SYNTAX, seeds_arg


def _horizon(env) -> float:
    base = env.unwrapped
    if hasattr(base, "episode_duration_s"):
        return float(base.episode_duration_s)
    return float(base.episode_steps * base.model.dt_s)


def _limit(env, index: int) -> float:
    """Physical output limit of actuator ``index`` (N·m for wheels)."""
    return float(env.unwrapped.fault_layer.limits[index])


# severity s in [0, 1] -> fault dict entries (limit: the actuator's limit; rest: time left after onset, s)
SEVERITY: dict[str, Callable[[float, float, float], dict]] = {
    "loss_of_effectiveness": lambda s, limit, rest: {"value": s},
    "bias": lambda s, limit, rest: {"value": s * limit},
    "stuck": lambda s, limit, rest: {"value": s * limit},
    "drift": lambda s, limit, rest: {"value": s * limit / 10.0},
    "saturation": lambda s, limit, rest: {"value": 1.0 - s},
    "outage": lambda s, limit, rest: {"duration_s": s * rest},
}


# sensor faults: kind "<sensor>.<kind>", e.g. "gyro.bias"; severity 1 = this full scale
SENSOR_SCALE = {"gyro": 0.01, "star_tracker": 0.01, "tachometer": 50.0, "state": 1.0}  # rad/s, rad, rad/s, state
SENSOR_SEVERITY: dict[str, Callable[[float, float, float], dict]] = {
    "bias": lambda s, scale, rest: {"value": s * scale},
    "drift": lambda s, scale, rest: {"value": s * scale / 10.0},
    "stuck": lambda s, scale, rest: {"duration_s": s * rest},
    "dropout": lambda s, scale, rest: {"duration_s": s * rest, "mode": "hold"},
    "noise_increase": lambda s, scale, rest: {"value": 1.0 + 9.0 * s},
}


def campaign_fault(env, kind: str, severity: float, onset_s: float, index: int | str = 0) -> dict:
    """The fault dict of one grid cell: an actuator kind of :data:`SEVERITY` (``index``
    an actuator or ``"random"``) or ``"<sensor>.<kind>"`` of :data:`SENSOR_SEVERITY`
    (``index`` an axis; the star tracker's stuck/dropout take the whole sensor)."""
    s = float(severity)
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"severity must be in [0, 1], got {severity!r}")
    rest = max(_horizon(env) - float(onset_s), 0.0)
    if "." in str(kind):
        sensor, sensor_kind = str(kind).split(".", 1)
        validation.choice("kind (sensor part)", sensor, set(SENSOR_SCALE))
        validation.choice("kind (fault part)", sensor_kind, set(SENSOR_SEVERITY))
        whole = sensor == "star_tracker" and sensor_kind in {"stuck", "dropout"}
        fault = {"kind": sensor_kind, "target": "sensor", "sensor": sensor, "index": "all" if whole else index}
        fault["onset_s"] = float(onset_s)
        return fault | SENSOR_SEVERITY[sensor_kind](s, SENSOR_SCALE[sensor], rest)
    validation.choice("kind", kind, set(SEVERITY) | {f"<sensor>.{k}" for k in SENSOR_SEVERITY})
    limit = _limit(env, 0 if index == "random" else int(index))
    return {"kind": kind, "target": "actuator", "index": index, "onset_s": float(onset_s)} | SEVERITY[kind](
        s, limit, rest
    )


def run_campaign(
    env,
    policy,
    kinds: Sequence[str],
    severities: Sequence[float],
    onsets_s: Sequence[float],
    seeds: Sequence[int],
    index: int | str = 0,
    fdi_factory: Callable[[Any], Any] | None = None,
) -> list[dict]:
    """Run the grid; one row per episode. Healthy rows have ``kind="healthy"``; every
    faulty row carries ``J_healthy`` (same seed) and ``J_ratio = J / J_healthy``. With
    ``fdi_factory(env)`` (e.g. ``ActuatorFDI.for_env``) rows add the FDI verdict."""

    def episode(seed: int, faults: list[dict]) -> dict:
        options = {"faults": faults}
        if fdi_factory is None:
            return rollout(env, policy, seed=seed, options=options)
        return run_fdi_episode(env, policy, fdi_factory(env), seed=seed, options=options)

    rows, healthy = [], {}
    for seed in seeds:
        r = episode(seed, [])
        healthy[seed] = r["J"]
        rows.append({"kind": "healthy", "severity": 0.0, "onset_s": None, "seed": seed, **r, "J_ratio": 1.0})
    for kind in kinds:
        for severity in severities:
            for onset in onsets_s:
                fault = campaign_fault(env, kind, severity, onset, index)
                for seed in seeds:
                    r = episode(seed, [fault])
                    row = {"kind": kind, "severity": float(severity), "onset_s": float(onset), "seed": seed, **r}
                    row["J_healthy"] = healthy[seed]
                    row["J_ratio"] = r["J"] / healthy[seed]
                    rows.append(row)
    return rows


def _cell_ratio(cell: list[dict]) -> float:
    """ΣJ / ΣJ_healthy over a cell's seeds (a mean of per-seed ratios would be dominated
    by seeds whose healthy maneuver is tiny); NaN for an empty cell."""
    if not cell:
        return float("nan")
    return float(sum(r["J"] for r in cell) / sum(r["J_healthy"] for r in cell))


def campaign_table(rows: list[dict]) -> str:
    """Markdown table: ΣJ / ΣJ_healthy per kind and onset (rows) × severity (columns)."""
    faulty = [r for r in rows if r["kind"] != "healthy"]
    severities = sorted({r["severity"] for r in faulty})
    keys = list(dict.fromkeys((r["kind"], r["onset_s"]) for r in faulty))
    lines = ["| kind | onset [s] | " + " | ".join(f"s = {s:g}" for s in severities) + " |"]
    lines.append("|---|---:|" + "---:|" * len(severities))
    for kind, onset in keys:
        cells = []
        for s in severities:
            cell = [r for r in faulty if (r["kind"], r["onset_s"], r["severity"]) == (kind, onset, s)]
            cells.append(f"{_cell_ratio(cell):.3g}" if cell else "")
        lines.append(f"| {kind} | {onset:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def fdi_summary(rows: list[dict]) -> dict:
    """Detection statistics of an FDI campaign: false-alarm rate on the healthy runs and
    on faulty runs before onset, isolation rate and detection delay (s) of faulty runs."""
    healthy = [r for r in rows if r["kind"] == "healthy"]
    faulty = [r for r in rows if r["kind"] != "healthy"]
    delays = [r["delay_s"] for r in faulty if r["correct"]]
    return {
        "healthy_runs": len(healthy),
        "false_alarm_rate_healthy": float(np.mean([r["detected_index"] is not None for r in healthy]))
        if healthy
        else None,
        "faulty_runs": len(faulty),
        "false_alarm_rate_before_onset": float(np.mean([r["false_alarm"] for r in faulty])) if faulty else None,
        "isolation_rate": float(np.mean([r["correct"] for r in faulty])) if faulty else None,
        "wrong_isolation_rate": float(
            np.mean([r["detected_index"] is not None and not r["correct"] and not r["false_alarm"] for r in faulty])
        )
        if faulty
        else None,
        "delay_median_s": float(np.median(delays)) if delays else None,
        "delay_p90_s": float(np.percentile(delays, 90)) if delays else None,
        "delay_max_s": float(np.max(delays)) if delays else None,
    }


def fdi_table(rows: list[dict]) -> str:
    """Markdown table of FDI performance per kind and severity (isolation rate, delays)."""
    faulty = [r for r in rows if r["kind"] != "healthy"]
    lines = ["| kind | severity | runs | isolated | false alarm | median delay [s] | max delay [s] |"]
    lines.append("|---|---:|---:|---:|---:|---:|---:|")
    for kind, sev in dict.fromkeys((r["kind"], r["severity"]) for r in faulty):
        cell = [r for r in faulty if (r["kind"], r["severity"]) == (kind, sev)]
        d = [r["delay_s"] for r in cell if r["correct"]]
        med = f"{np.median(d):.1f}" if d else "—"
        mx = f"{np.max(d):.1f}" if d else "—"
        iso = np.mean([r["correct"] for r in cell])
        fa = np.mean([r["false_alarm"] for r in cell])
        lines.append(f"| {kind} | {sev:g} | {len(cell)} | {iso:.0%} | {fa:.0%} | {med} | {mx} |")
    healthy = [r for r in rows if r["kind"] == "healthy"]
    if healthy:
        fa = np.mean([r["detected_index"] is not None for r in healthy])
        lines.append(f"| healthy | 0 | {len(healthy)} | — | {fa:.0%} | — | — |")
    return "\n".join(lines)


def campaign_heatmap(rows: list[dict], path: str | Path, title: str = "") -> Path:
    """Heatmap PNG of ΣJ / ΣJ_healthy (log color scale): kind × severity, one panel per onset."""
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # heavy (~0.4 s): only for the heatmap, after selecting the headless backend

    faulty = [r for r in rows if r["kind"] != "healthy"]
    kinds = list(dict.fromkeys(r["kind"] for r in faulty))
    severities = sorted({r["severity"] for r in faulty})
    onsets = sorted({r["onset_s"] for r in faulty})
    grids = []
    for onset in onsets:
        g = np.full((len(kinds), len(severities)), np.nan)
        for i, k in enumerate(kinds):
            for j, s in enumerate(severities):
                g[i, j] = _cell_ratio([r for r in faulty if (r["kind"], r["severity"], r["onset_s"]) == (k, s, onset)])
        grids.append(g)
    finite = np.concatenate([g[np.isfinite(g)] for g in grids])
    norm = LogNorm(vmin=max(min(finite.min(), 1.0), 1e-3), vmax=max(finite.max(), 1.0 + 1e-6))
    fig, axes = plt.subplots(
        1, len(onsets), figsize=(1.6 + 1.3 * len(severities) * len(onsets), 0.6 + 0.5 * len(kinds))
    )
    axes = np.atleast_1d(axes)
    for ax, onset, g in zip(axes, onsets, grids, strict=True):
        im = ax.imshow(g, norm=norm, cmap="viridis", aspect="auto")
        ax.set_xticks(range(len(severities)), [f"{s:g}" for s in severities])
        ax.set_yticks(range(len(kinds)), kinds if ax is axes[0] else [""] * len(kinds))
        ax.set_xlabel("severity")
        ax.set_title(f"onset {onset:g} s")
        for i in range(len(kinds)):
            for j in range(len(severities)):
                if np.isfinite(g[i, j]):
                    ax.text(j, i, f"{g[i, j]:.2g}", ha="center", va="center", color="w", fontsize=8)
    fig.colorbar(im, ax=list(axes), label="ΣJ / ΣJ_healthy (seeds)")
    if title:
        fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


# ---------------------------------------------------------------------- command line
def _policy(name: str, env):
    policies = {"lqr": lambda e: LQRPolicy(e, "zoh"), "zero": ZeroPolicy}
    validation.choice("--policy", name, set(policies))
    return policies[name](env)


def evaluate_scenario(name: str, policy: str = "lqr", seeds: Sequence[int] = (0,), env_id: str | None = None) -> str:
    """Markdown table of J with the scenario's faults vs. the healthy run, per seed."""
    sc = load_scenario(name)
    faulty = make_scenario_env(sc, env_id)
    healthy = make_scenario_env(dict(sc, faults=[]), env_id)
    pol = _policy(policy, faulty)
    lines = [f"scenario {sc['name']}: {' '.join(str(sc.get('description', '')).split())}", ""]
    lines += ["| seed | J healthy | J faulty | J / J_healthy | final error [deg] |", "|---:|---:|---:|---:|---:|"]
    for seed in seeds:
        h = rollout(healthy, pol, seed=seed)
        f = rollout(faulty, pol, seed=seed)
        err = f.get("final_error_deg", float("nan"))
        lines.append(f"| {seed} | {h['J']:.4g} | {f['J']:.4g} | {f['J'] / h['J']:.3g} | {err:.3g} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.fault_campaign")
    sub = parser.add_subparsers(dest="command", required=True)
    sc = sub.add_parser("scenario", help="run one scenario preset against its healthy twin")
    sc.add_argument("name")
    sc.add_argument("--policy", default="lqr")
    sc.add_argument("--seeds", type=seeds_arg, default="3", help=f"episode seeds: {SYNTAX} (default 3)")
    sc.add_argument("--env", default=None, help="env id when the scenario names none")
    ca = sub.add_parser("campaign", help="fault kind x severity x onset grid: table + heatmap")
    ca.add_argument("--scenario", default="fault-campaign")
    ca.add_argument("--policy", default="lqr")
    ca.add_argument("--out", default="results")
    ca.add_argument("--fdi", action="store_true", help="also run the IMM FDI and report delays / false alarms")
    ca.add_argument("--quick", action="store_true", help="one seed, two severities, one onset")
    args = parser.parse_args(argv)
    try:
        if args.command == "scenario":
            print(evaluate_scenario(args.name, args.policy, args.seeds, args.env))
            return 0
        print(run_campaign_cli(args.scenario, args.policy, Path(args.out), args.fdi, args.quick))
        return 0
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def run_campaign_cli(scenario: str, policy: str, out: Path, fdi: bool = False, quick: bool = False) -> str:
    """Run a campaign scenario; writes ``out/<name>.md`` and ``out/<name>.png``; returns the markdown."""
    sc = load_scenario(scenario)
    grid = sc.get("campaign")
    if not grid:
        raise ValueError(f"scenario {sc['name']!r} has no 'campaign' grid")
    env = make_scenario_env(sc)
    pol = _policy(policy, env)
    sev, onsets, seeds = grid["severities"], grid["onsets_s"], grid["seeds"]
    if quick:
        sev, onsets, seeds = sev[1::2][:2], onsets[:1], seeds[:1]
    factory = None
    if fdi:
        factory = ActuatorFDI.for_env
    rows = run_campaign(env, pol, grid["kinds"], sev, onsets, seeds, grid.get("index", 0), factory)
    md = [
        f"# {sc['name']}: policy {policy}",
        "",
        "ΣJ / ΣJ_healthy over the seeds of each cell (same seeds, same initial conditions):",
        "",
        campaign_table(rows),
    ]
    if fdi:
        md += ["", "IMM fault detection and isolation:", "", fdi_table(rows), "", str(fdi_summary(rows))]
    out.mkdir(parents=True, exist_ok=True)
    png = campaign_heatmap(rows, out / f"{sc['name']}-{policy}.png", f"{sc['name']}, {policy}")
    text = "\n".join(md) + f"\n\n![heatmap]({png.name})\n"
    (out / f"{sc['name']}-{policy}.md").write_text(text)
    return text


if __name__ == "__main__":
    sys.exit(main())
