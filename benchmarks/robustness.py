"""Robustness curves: J/J* of controllers as one flight feature grows, on the lab's episodes.

Every point has the flight sensors on (so a controller acts on measurements, through its
estimator where it has one) and turns on one more feature of :mod:`attitude_envs.conditions`
at increasing levels:

* ``parameters``: the true plant drawn within ± that relative inertia error (0–50 %; the
  other tolerances of the plant's flight table scale with it);
* ``delay``: 0–3 control periods of command delay;
* ``noise``: the flight sensors with their noise ×1–×10.

Every episode is the lab episode of the same seed (flight draws come from a spawned
generator) and J* is its oracle under the same conditions (:mod:`experiments.optimum`). The
oracle knows the true state, so sensors do not change it: J* is solved without them.
Rows are ``agent, axis, level, j_over_j_star, cvar10, seeds``: ΣJ/ΣJ* over the seeds and
the CVaR₀.₁ of the per-episode J/J* (the mean of its worst tenth). Every episode is appended
to ``<out>.episodes.jsonl`` as it finishes, so an interrupted run resumes where it stopped.

    python -m benchmarks.robustness --plant wheel --seeds 20 --out docs/campaigns/wheel/robustness.csv
"""

from __future__ import annotations

import argparse
import csv
import json
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym

import attitude_envs  # noqa: F401
from attitude_envs.conditions import Conditions
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.files import atomic_write
from attitude_envs.presets import flight
from experiments import optimum
from experiments.report.statistics import cvar

#: the env id of each plant page and its flight table's inertia tolerance key
PLANTS = {
    "wheel": "attitude_envs/ReactionWheel-v0",
    "air-bearing": "attitude_envs/AirBearing-v0",
}
#: the levels of each axis, as (level, conditions); the parameter level is the relative inertia error
PARAMETER_LEVELS = (0.0, 0.1, 0.25, 0.5)
#: a whole run's wall time, min, from nothing (J* solves most of it; one process on a shared
#: 2-core machine, 2026-11-28); a rerun reads every episode back from its record in seconds
RUN_MINUTES = {"wheel": 13, "air-bearing": 43}
DELAY_LEVELS = (0, 1, 2, 3)
NOISE_LEVELS = (1.0, 3.0, 10.0)


def axes(env_id: str) -> list[tuple[str, float, dict]]:
    """``(axis, level, conditions)`` of every point of the curves."""
    inertia_tol = flight.table(env_id).plant_value("inertia_moment")
    points = [("parameters", p, {"sensors": 1.0, "parameters": p / inertia_tol}) for p in PARAMETER_LEVELS]
    points += [("delay", float(d), {"sensors": 1.0, "delay_steps": d}) for d in DELAY_LEVELS]
    points += [("noise", k, {"sensors": k}) for k in NOISE_LEVELS]
    return points


def agents() -> dict[str, Callable]:
    """The controllers on the curves: name → factory(env) of a policy (``reset``, ``act``)."""
    from baselines.lqr import LQRPolicy

    found: dict[str, Callable] = {"lqr": LQRPolicy}
    from baselines.estimated import lqr_mekf

    found["lqr+mekf"] = lqr_mekf
    # the LQR designed for the env's command delay (a known design value), through the MEKF
    found["lqr-delay+mekf"] = lambda env: lqr_mekf(env, delay_steps="env", name="lqr-delay+mekf")
    return found


def j_star(env_id: str, conditions: dict, seed: int, env_kwargs: dict | None = None) -> float:
    """The oracle's J of the episode: under ``conditions`` without the sensors (the oracle
    knows the true state), the lab's where nothing else is on."""
    plant = Conditions.from_config({k: v for k, v in conditions.items() if k != "sensors"})
    kwargs = dict(env_kwargs or {})
    if not plant.is_lab:
        kwargs["conditions"] = plant.as_dict()
    return optimum.solve_episode(env_id, kwargs, seed=seed).j_star


def run(
    plant: str, seeds: int, out: Path, names: list[str] | None = None, env_kwargs: dict | None = None
) -> list[dict]:
    """Every point of ``plant``'s curves over ``seeds`` episodes (of the env built with
    ``env_kwargs``, default: its default preset); rows written to ``out``."""
    env_id = PLANTS[plant]
    log = out.with_suffix(".episodes.jsonl")
    done: dict[tuple, dict] = {}
    if log.is_file():
        for line in log.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[(r["agent"], r["axis"], r["level"], r["seed"])] = r
    factories = agents()
    chosen = names or list(factories)
    out.parent.mkdir(parents=True, exist_ok=True)
    rows = []
    with log.open("a") as sink:
        for axis, level, conditions in axes(env_id):
            for name in chosen:
                env = gym.make(env_id, conditions=conditions, **dict(env_kwargs or {}))
                policy = factories[name](env)
                ratios, js, jstars = [], [], []
                for seed in range(seeds):
                    key = (name, axis, level, seed)
                    if key not in done:
                        j = float(rollout(env, policy, seed=seed)["J"])  # the policy sees no ground truth
                        done[key] = {
                            "agent": name,
                            "axis": axis,
                            "level": level,
                            "seed": seed,
                            "j": j,
                            "j_star": j_star(env_id, conditions, seed, env_kwargs),
                        }
                        sink.write(json.dumps(done[key]) + "\n")
                        sink.flush()
                    r = done[key]
                    js.append(r["j"])
                    jstars.append(r["j_star"])
                    ratios.append(r["j"] / r["j_star"])
                env.close()
                row = {
                    "agent": name,
                    "axis": axis,
                    "level": level,
                    "j_over_j_star": sum(js) / sum(jstars),
                    "cvar10": cvar(ratios, 0.1),
                    "seeds": seeds,
                }
                rows.append(row)
                print(
                    f"{plant} {name:9s} {axis:10s} {level:5g}  ΣJ/ΣJ* {row['j_over_j_star']:.4f}  "
                    f"CVaR0.1 {row['cvar10']:.4f}",
                    flush=True,
                )

    def write_csv(path: Path) -> None:
        with path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)

    atomic_write(out, write_csv)
    return rows


def figure(rows: list[dict], plant: str, path: Path) -> None:
    """The curves: ΣJ/ΣJ* (top row) and the CVaR₀.₁ of J/J* (bottom row, log scale: a few
    episodes of tiny J* dominate it), one column per axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_names = ["parameters", "delay", "noise"]
    labels = {
        "parameters": "inertia error (relative)",
        "delay": "delay (control periods)",
        "noise": "sensor noise (× flight)",
    }
    fig, grid = plt.subplots(2, 3, figsize=(11, 5.2), sharex="col")
    for col, axis in enumerate(axes_names):
        for name in sorted({r["agent"] for r in rows}):
            pts = sorted(
                (r["level"], r["j_over_j_star"], r["cvar10"]) for r in rows if r["agent"] == name and r["axis"] == axis
            )
            if not pts:
                continue
            x, mean, tail = zip(*pts, strict=True)
            grid[0, col].plot(x, mean, marker="o", label=name)
            grid[1, col].plot(x, tail, marker="o", ls="--", label=name)
        grid[1, col].set_yscale("log")
        grid[1, col].set_xlabel(labels[axis])
        for row in (0, 1):
            grid[row, col].grid(alpha=0.3)
    grid[0, 0].set_ylabel("ΣJ / ΣJ*")
    grid[1, 0].set_ylabel("CVaR₀.₁ of J / J*")
    grid[0, -1].legend(fontsize=8)
    seeds = rows[0]["seeds"]
    fig.suptitle(f"{PLANTS[plant].split('/')[1]}: robustness ({seeds} lab episodes per point, flight sensors on)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


AXIS_LEVEL = {
    "parameters": lambda v: f"{v:.0%}",
    "delay": lambda v: f"{v:g}",
    "noise": lambda v: f"×{v:g}",
}


def page(rows: list[dict], plant: str, episodes: list[dict]) -> str:
    """The Markdown page of the curves: the figure, the table, what the points are, the
    episode of least J* (which the CVaR of J/J* follows), and how to reproduce it."""
    env_name = PLANTS[plant].split("/")[1]
    agents_seen = list(dict.fromkeys(r["agent"] for r in rows))
    head = "| axis | level | " + " | ".join(f"{a} ΣJ/ΣJ*" for a in agents_seen) + " | "
    head += " | ".join(f"{a} CVaR₀.₁" for a in agents_seen) + " |"
    lines = [head, "|" + "---|" * (2 + 2 * len(agents_seen))]
    by = {(r["axis"], r["level"], r["agent"]): r for r in rows}
    for axis in ("parameters", "delay", "noise"):
        for level in dict.fromkeys(r["level"] for r in rows if r["axis"] == axis):
            cells = [f"{by[(axis, level, a)]['j_over_j_star']:.4f}" for a in agents_seen]
            cells += [f"{by[(axis, level, a)]['cvar10']:.3g}" for a in agents_seen]
            lines.append(f"| {axis} | {AXIS_LEVEL[axis](level)} | " + " | ".join(cells) + " |")
    smallest = min((e for e in episodes if e["axis"] == "noise"), key=lambda e: e["j_star"])
    worst = max((e for e in episodes if e["seed"] == smallest["seed"] and e["axis"] == "noise"), key=lambda e: e["j"])
    seeds = rows[0]["seeds"]
    return rf"""# {env_name}: robustness to flight conditions

<!-- Generated by benchmarks/robustness.py from robustness.episodes.jsonl; rerun it, do not edit. -->

![robustness curves](figures/robustness.png)

{chr(10).join(lines)}

Each point covers the {seeds} lab episodes (seeds 0–{seeds - 1}) of {env_name}'s default
preset, with the flight sensors on (`attitude_envs.conditions`). One more feature is switched
on per axis:

* **parameters**: the true inertia drawn within ± that relative error, with the plant's other
  tolerances scaled with it;
* **delay**: that many control periods of command delay;
* **noise**: the flight sensors' noise times that factor.

J* is the oracle under the same conditions. Sensors do not enter it, because it knows the
true state.

The agents:

* `lqr` is the nominal LQR on the raw measurements.
* `lqr+mekf` is the same LQR acting through the MEKF.
* `lqr-delay+mekf` is the LQR designed for the delay, through the MEKF. Its state is
  augmented with the commands in flight (`baselines.lqr`, `delay_steps="env"`).

**The CVaR₀.₁ of J/J\* follows the smallest J\*.** Episode {smallest["seed"]} has the smallest
J\* on the noise axis, {smallest["j_star"]:.3g}. There an agent's J/J\* reaches
{worst["j"] / worst["j_star"]:.3g} ({worst["agent"]} at noise ×{worst["level"]:g}), because
the sensor noise floor's cost does not shrink with the maneuver. ΣJ/ΣJ\* is the robust summary.

Reproduce: `python -m benchmarks.robustness --plant {plant} --seeds {seeds}` (≈ {RUN_MINUTES[plant]} min on
2 cores from nothing, most of it J\*). The run resumes from `robustness.episodes.jsonl`, which holds every episode's J
and J\*. The data are in [`robustness.csv`](robustness.csv), with columns agent, axis, level,
j_over_j_star, cvar10 and seeds.
"""


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=sorted(PLANTS), required=True)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--agents", nargs="*", default=None, help="names of agents() (default: all)")
    parser.add_argument("--out", default=None, help="CSV (default docs/campaigns/<plant>/robustness.csv)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    out = Path(args.out or f"docs/campaigns/{args.plant}/robustness.csv")
    rows = run(args.plant, args.seeds, out, args.agents)
    figure(rows, args.plant, out.parent / "figures" / "robustness.png")
    log = out.with_suffix(".episodes.jsonl")
    episodes = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    out.with_suffix(".md").write_text(page(rows, args.plant, episodes), encoding="utf-8")
    return rows


if __name__ == "__main__":
    main()
