"""Robustness curves: J/J* of controllers as one flight feature grows, on the lab's episodes.

Every point has the flight sensors on (so a controller acts on measurements, through its
estimator where it has one) and turns on one more feature of :mod:`attitude_envs.conditions`
at increasing levels:

* ``parameters``: the true plant drawn within ± that relative inertia error (0–50 %; the
  other tolerances of the plant's flight table scale with it);
* ``delay``: 0–3 control periods of command delay;
* ``noise``: the flight sensors with their noise ×1–×10;
* ``held-out``: the whole flight conditions with the parameter tolerances ×1 (the flight
  cells', where the flight-trained agents trained), ×2 and ×4 (outside their training
  distribution).

The learned agents (``--models``: a campaign's results directory with the plant's trained
``ppo``, lab-trained, and ``ppo-flight``, trained under flight conditions) play the same
episodes on the plant's learning task (``-v1``), every training seed's best snapshot.

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
from functools import cache
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
#: the learned agents on the curves: the plant campaign's PPO trained in the lab and its PPO
#: trained under flight conditions
LEARNED = ("ppo", "ppo-flight")
#: the levels of each axis, as (level, conditions); the parameter level is the relative inertia error
PARAMETER_LEVELS = (0.0, 0.1, 0.25, 0.5)
#: a whole run's wall time, min, from nothing, every axis and agent (J* solves most of it: the
#: held-out axis's flight episodes 17 s each on ReactionWheel, 80-120 s on AirBearing's 2000
#: steps; one process on a 2-core machine shared with other runs, 2026-11-28 and -29); a rerun
#: reads every episode back from its record in seconds
RUN_MINUTES = {"wheel": 40, "air-bearing": 105}
#: the plant campaign's wall time, min, with its flight cells (its runs.jsonl: the lab run plus
#: the flight cells' run, 2026-11-29, shared cores)
CAMPAIGN_MINUTES = {"wheel": 62, "air-bearing": 28}
DELAY_LEVELS = (0, 1, 2, 3)
NOISE_LEVELS = (1.0, 3.0, 10.0)
#: the held-out axis: the flight conditions' parameter tolerances times these (1: the flight cells')
HELD_OUT_LEVELS = (1.0, 2.0, 4.0)
AXES = ("parameters", "delay", "noise", "held-out")


def axes(env_id: str) -> list[tuple[str, float, dict | str]]:
    """``(axis, level, conditions)`` of every point of the curves."""
    inertia_tol = flight.table(env_id).plant_value("inertia_moment")
    points = [("parameters", p, {"sensors": 1.0, "parameters": p / inertia_tol}) for p in PARAMETER_LEVELS]
    points += [("delay", float(d), {"sensors": 1.0, "delay_steps": d}) for d in DELAY_LEVELS]
    points += [("noise", k, {"sensors": k}) for k in NOISE_LEVELS]
    points += [("held-out", k, "flight" if k == 1 else {"base": "flight", "parameters": k}) for k in HELD_OUT_LEVELS]
    return points


def agents() -> dict[str, Callable]:
    """The analytic controllers on the curves: name → factory(env) of a policy (``reset``, ``act``)."""
    from baselines.estimated import lqr_mekf
    from baselines.lqr import LQRPolicy

    return {
        "lqr": LQRPolicy,
        "lqr+mekf": lqr_mekf,
        # the LQR designed for the env's command delay (a known design value), through the MEKF
        "lqr-delay+mekf": lambda env: lqr_mekf(env, delay_steps="env", name="lqr-delay+mekf"),
    }


@cache
def campaign_of(plant: str):
    """The plant's campaign (``experiments/campaigns/<plant>.yml``): its cell, its learned agents."""
    from experiments.campaign.spec import load_campaign

    return load_campaign(plant)


def cell_kwargs(plant: str) -> dict:
    """The keywords of the plant campaign's lab cell (its episodes and J*)."""
    return dict(next(e for e in campaign_of(plant).envs if "conditions" not in e.kwargs).kwargs)


def learning_id(plant: str) -> str:
    """The env id the campaign's learned agents play its cells' episodes on (its learning task)."""
    return next(a for a in campaign_of(plant).agents if a.name == LEARNED[0]).env_id


def learned_models(plant: str, results: Path) -> dict[str, list[tuple[int, Path]]]:
    """name → ``(training seed, best snapshot)`` of each training seed of the learned agents
    (:data:`LEARNED`) in the campaign results directory ``results``, where the campaign trains
    them (:func:`~experiments.campaign.jobs.train_dir`); a ``ValueError`` naming what is missing."""
    from experiments.campaign.jobs import train_dir, trained_model

    campaign = campaign_of(plant)
    found = {}
    for name in LEARNED:
        agent = next(a for a in campaign.agents if a.name == name)
        entry = campaign.trained_on(agent, next(e for e in campaign.envs if agent in campaign.agents_for(e)))
        runs = [(seed, train_dir(results, entry, name, seed)) for seed in agent.train["seeds"]]
        models = [(seed, trained_model(run, "best")) for seed, run in runs]
        missing = [str(path) for _, path in models if not path.is_file()]
        if missing:
            raise ValueError(f"--models {str(results)!r} has no trained {name} of the {plant} campaign: {missing}")
        found[name] = models
    return found


def j_star(env_id: str, conditions: dict | str, seed: int, env_kwargs: dict | None = None) -> float:
    """The oracle's J of the episode: the shipped table's where it holds the episode, else
    solved under ``conditions`` without the sensors (the oracle knows the true state), the
    lab's where nothing else is on."""
    from experiments.optimum_table import table_value

    kwargs = dict(env_kwargs or {})
    listed = table_value(env_id, {**kwargs, "conditions": conditions}, seed, None)
    if listed is not None:
        return float(listed)
    spec = Conditions.from_config(conditions).as_dict()
    plant = Conditions.from_config({k: v for k, v in spec.items() if k != "sensors"})
    if not plant.is_lab:
        kwargs["conditions"] = plant.as_dict()
    return optimum.solve_episode(env_id, kwargs, seed=seed).j_star


def run(
    plant: str,
    seeds: int,
    out: Path,
    names: list[str] | None = None,
    models: Path | None = None,
    axes_chosen: list[str] | None = None,
    env_kwargs: dict | None = None,
) -> list[dict]:
    """Every point of ``plant``'s curves over ``seeds`` episodes of its campaign cell (its
    keywords, ``env_kwargs`` over them); the learned agents' from the campaign results
    directory ``models`` (None: the analytic ones only); rows written to ``out``. An
    episode's J* is solved once, whichever agent plays it."""
    env_id = PLANTS[plant]
    kwargs = {**cell_kwargs(plant), **dict(env_kwargs or {})}
    log = out.with_suffix(".episodes.jsonl")
    done: dict[tuple, dict] = {}
    j_stars: dict[tuple, float] = {}
    if log.is_file():
        for line in log.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[(r["agent"], r["axis"], r["level"], r["seed"], r.get("train_seed"))] = r
                j_stars[(r["axis"], r["level"], r["seed"])] = r["j_star"]
    factories = agents()
    learned = learned_models(plant, models) if models is not None else {}
    chosen = names or [*factories, *learned]
    unknown = set(chosen) - set(factories) - set(learned)
    if unknown:
        raise ValueError(f"--agents {sorted(unknown)} unknown; accepted: {[*factories, *learned]} (learned: --models)")
    out.parent.mkdir(parents=True, exist_ok=True)
    rows = []
    with log.open("a") as sink:
        for axis, level, conditions in axes(env_id):
            if axes_chosen and axis not in axes_chosen:
                continue
            for name in chosen:
                players = (
                    [(None, factories[name], env_id)]
                    if name in factories
                    else [(t, _learned_factory(path), learning_id(plant)) for t, path in learned[name]]
                )
                js, jstars, ratios = [], [], []
                for train_seed, factory, play_id in players:
                    env = gym.make(play_id, conditions=conditions, **kwargs)
                    policy = factory(env)
                    for seed in range(seeds):
                        key = (name, axis, level, seed, train_seed)
                        if key not in done:
                            episode = (axis, level, seed)
                            if episode not in j_stars:
                                j_stars[episode] = j_star(env_id, conditions, seed, kwargs)
                            done[key] = {
                                "agent": name,
                                "axis": axis,
                                "level": level,
                                "seed": seed,
                                **({"train_seed": train_seed} if train_seed is not None else {}),
                                # the policy sees no ground truth
                                "j": float(rollout(env, policy, seed=seed)["J"]),
                                "j_star": j_stars[episode],
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
                    f"{plant} {name:14s} {axis:10s} {level:5g}  ΣJ/ΣJ* {row['j_over_j_star']:.4f}  "
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


def _learned_factory(model: Path) -> Callable:
    """factory(env) of the trained policy saved at ``model``."""
    from experiments.policies import build_policy

    return lambda env: build_policy({"policy": "sb3", "model": str(model)}, env)


def figure(rows: list[dict], plant: str, path: Path) -> None:
    """The curves: ΣJ/ΣJ* (top row) and the CVaR₀.₁ of J/J* (bottom row, log scale: a few
    episodes of tiny J* dominate it), one column per axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_names = [a for a in AXES if any(r["axis"] == a for r in rows)]
    labels = {
        "parameters": "inertia error (relative)",
        "delay": "delay (control periods)",
        "noise": "sensor noise (× flight)",
        "held-out": "flight, tolerances × (1: trained)",
    }
    fig, grid = plt.subplots(2, len(axes_names), figsize=(3.7 * len(axes_names), 5.2), sharex="col", squeeze=False)
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
    "held-out": lambda v: f"×{v:g}",
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
    for axis in AXES:
        for level in dict.fromkeys(r["level"] for r in rows if r["axis"] == axis):
            cells = [
                f"{by[(axis, level, a)]['j_over_j_star']:.4f}" if (axis, level, a) in by else "—" for a in agents_seen
            ]
            cells += [f"{by[(axis, level, a)]['cvar10']:.3g}" if (axis, level, a) in by else "—" for a in agents_seen]
            lines.append(f"| {axis} | {AXIS_LEVEL[axis](level)} | " + " | ".join(cells) + " |")
    smallest = min((e for e in episodes if e["axis"] == "noise"), key=lambda e: e["j_star"])
    worst = max((e for e in episodes if e["seed"] == smallest["seed"] and e["axis"] == "noise"), key=lambda e: e["j"])
    seeds = rows[0]["seeds"]
    held_out = (
        "* **held-out**: every flight feature, with the parameter tolerances times that factor. At ×1\n"
        "  these are the campaign's flight cells, the distribution `ppo-flight` trained on; ×2 and ×4\n"
        "  lie outside it."
        if "held-out" in {r["axis"] for r in rows}
        else "* **held-out** (the flight cells' tolerances ×1–×4) is not run here: its J* needs 40 more\n"
        "  flight solves of 2000-step episodes, about an hour on 2 cores."
    )
    learned_id = learning_id(plant)
    dt = {i: gym.make(i).unwrapped.control_dt_s for i in (PLANTS[plant], learned_id)}
    run_axes = [a for a in AXES if any(r["axis"] == a for r in rows)]
    axes_arg = "" if run_axes == list(AXES) else " --axes " + " ".join(run_axes)
    periods = (
        f"{dt[PLANTS[plant]]:g} s for the analytic rows ({env_name}), "
        f"{dt[learned_id]:g} s for the learned ones ({learned_id.split('/')[1]})"
    )
    return rf"""# {env_name}: robustness to flight conditions

<!-- Generated by benchmarks/robustness.py from robustness.episodes.jsonl; rerun it, do not edit. -->

![robustness curves](figures/robustness.png)

{chr(10).join(lines)}

Each point covers the {seeds} episodes (seeds 0–{seeds - 1}) of the {plant} campaign's cell
(`{json.dumps(cell_kwargs(plant))}`), with the flight sensors on (`attitude_envs.conditions`).
One more feature is switched on per axis:

* **parameters**: the true inertia drawn within ± that relative error, with the plant's other
  tolerances scaled with it;
* **delay**: that many control periods of command delay;
* **noise**: the flight sensors' noise times that factor;
{held_out}

The delay counts control periods of the env each agent plays: {periods}.

J* is the oracle under the same conditions. Sensors do not enter it, because it knows the
true state.

The agents:

* `lqr` is the nominal LQR on the raw measurements.
* `lqr+mekf` is the same LQR acting through the MEKF.
* `lqr-delay+mekf` is the LQR designed for the delay, through the MEKF. Its state is
  augmented with the commands in flight (`baselines.lqr`, `delay_steps="env"`).
* `ppo` is the campaign's PPO, trained in the lab; `ppo-flight` the campaign's PPO trained
  under flight conditions (domain randomization over the flight cells' distribution). Both
  play the episodes on the learning task ({learned_id.split("/")[1]}) on the
  measurements, each of their 3 training seeds' best snapshot: their points cover 3 × {seeds}
  episodes.

**The CVaR₀.₁ of J/J\* follows the smallest J\*.** Episode {smallest["seed"]} has the smallest
J\* on the noise axis, {smallest["j_star"]:.3g}. There an agent's J/J\* reaches
{worst["j"] / worst["j_star"]:.3g} ({worst["agent"]} at noise ×{worst["level"]:g}), because
the sensor noise floor's cost does not shrink with the maneuver. ΣJ/ΣJ\* is the robust summary.

The learned rows need the campaign's models: `attitude-envs benchmark --config {plant} --out results/{plant}` (≈ {CAMPAIGN_MINUTES[plant]} min on 2 cores).
Then `python -m benchmarks.robustness --plant {plant} --seeds {seeds} --models results/{plant}{axes_arg}` (≈ {RUN_MINUTES[plant]} min on 2 cores from nothing, most of it J\*). The run resumes from `robustness.episodes.jsonl`, which holds every episode's J
and J\*. The data are in [`robustness.csv`](robustness.csv), with columns agent, axis, level,
j_over_j_star, cvar10 and seeds.
"""


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=sorted(PLANTS), required=True)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--agents", nargs="*", default=None, help="agents on the curves (default: all)")
    parser.add_argument(
        "--models", default=None, help="a campaign results directory: its learned agents join the curves"
    )
    parser.add_argument("--axes", nargs="*", choices=AXES, default=None, help="axes to run (default: all)")
    parser.add_argument("--out", default=None, help="CSV (default docs/campaigns/<plant>/robustness.csv)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    out = Path(args.out or f"docs/campaigns/{args.plant}/robustness.csv")
    models = Path(args.models) if args.models else None
    if models is not None and not models.is_dir():
        parser.error(f"--models must be a campaign results directory, got {args.models!r}")
    rows = run(args.plant, args.seeds, out, args.agents, models, args.axes)
    figure(rows, args.plant, out.parent / "figures" / "robustness.png")
    log = out.with_suffix(".episodes.jsonl")
    episodes = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    out.with_suffix(".md").write_text(page(rows, args.plant, episodes), encoding="utf-8")
    return rows


if __name__ == "__main__":
    main()
