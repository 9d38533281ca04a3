"""Robustness curves: J/J* of controllers as one flight feature grows, on the lab's episodes.

Every point has the flight sensors on (so a controller acts on measurements, through its
estimator where it has one) and turns on one more feature of :mod:`attitude_envs.conditions`
at increasing levels:

* ``parameters``: the true plant drawn within ± that relative error (0–50 %) of the plant's
  parameter the axis names (:data:`PARAMETER_AXIS`: the inertia, FuelSlosh's slosh masses,
  LinearSystem's input gains); the other tolerances of its flight table scale with it;
* ``delay``: 0–3 control periods of command delay;
* ``noise``: the flight sensors with their noise ×1–×10;
* ``held-out``: the whole flight conditions with the parameter tolerances ×1 (the flight
  cells', where the flight-trained agents trained), ×2 and ×4 (outside their training
  distribution).

The analytic agents are rows of the plant's campaign (:data:`ANALYTIC`), built from their
campaign spec. The learned agents (``--models``: a campaign results directory) are the
campaign's trained rows (:func:`learned_agents`), every training seed's selected snapshot.
Every agent plays the episodes on its campaign play env
(:func:`experiments.campaign.spec.play_env`: a learning task such as ``-v1``, an MPC's own
period), so a delay level counts that env's control periods.

Every episode is the lab episode of the same seed (flight draws come from a spawned
generator) and J* is its oracle under the same conditions (:mod:`experiments.optimum`), on
the campaign's cell. The oracle knows the true state, so sensors do not change it: J* is
solved without them. Rows are ``agent, axis, level, j_over_j_star, cvar10, seeds``: ΣJ/ΣJ*
over the seeds and the CVaR₀.₁ of the per-episode J/J* (the mean of its worst tenth). Every
episode is appended to ``<out>.episodes.jsonl`` as it finishes, so an interrupted run resumes
where it stopped; ``--recorded`` writes the curves of the points already complete in it, and
the page names the others.

    python -m benchmarks.robustness --plant wheel --seeds 20 --out docs/campaigns/wheel/robustness.csv
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401
from attitude_envs.conditions import MAX_PARAMETER_SCALE, Conditions
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.files import atomic_write
from attitude_envs.presets import flight
from experiments import optimum
from experiments.report.statistics import cvar
from experiments.training.hyperparams import zoo_objects

#: the env id of each plant page (its campaign's cells)
PLANTS = {
    "wheel": "attitude_envs/ReactionWheel-v0",
    "air-bearing": "attitude_envs/AirBearing-v0",
    "magnetorquer": "attitude_envs/Magnetorquer-v0",
    "slosh": "attitude_envs/FuelSlosh-v0",
    "linear": "attitude_envs/LinearSystem-v0",
}


@dataclass(frozen=True)
class ParameterAxis:
    """What a plant's parameters level is a relative error of: ``tolerance``, a ``plant`` key
    of its flight table or ``"gain_tolerance"`` (the actuators' scale factors), and ``what``,
    the page's and figure's words for it."""

    tolerance: str
    what: str


#: each plant's parameters axis: the inertia where the plant has one; FuelSlosh's flight table
#: draws no inertia but the slosh masses and the pendulum lengths (both ±15 %, so one level
#: is the error of both); LinearSystem's table has no plant tolerance, its flight parameter
#: error is B's gain (each input's column of B times a drawn gain)
PARAMETER_AXIS = {
    "wheel": ParameterAxis("inertia_moment", "inertia"),
    "air-bearing": ParameterAxis("inertia_moment", "inertia"),
    "magnetorquer": ParameterAxis("inertia_moment", "inertia"),
    "slosh": ParameterAxis("slosh_mass", "slosh masses and pendulum lengths"),
    "linear": ParameterAxis("gain_tolerance", "input gains (each column of B)"),
}
#: the page's words for each flight tolerance the ``parameters`` scale multiplies, and its unit
#: (``%``: relative)
TOLERANCE_WORDS = {
    "inertia_moment": ("principal moments", "%"),
    "inertia_axis_deg": ("principal axes", "°"),
    "wheel_misalignment_deg": ("wheel mounting", "°"),
    "offset_torque_nm": ("centre-of-mass offset torque", " N·m"),
    "slosh_mass": ("slosh masses", "%"),
    "pendulum_length": ("pendulum lengths", "%"),
    "gain_tolerance": ("actuator scale factors", "%"),
}

_GYROSTAT_ANALYTIC = {
    "lqr": "the nominal LQR on the raw measurements.",
    "lqr+mekf": "the same LQR acting through the MEKF.",
    "lqr-delay+mekf": "the LQR designed for the delay, through the MEKF. Its state is augmented with the "
    'commands in flight (`baselines.lqr`, `delay_steps="env"`).',
}
#: the analytic agents on each plant's curves, rows of its campaign by name, and what each is
#: (the page's words). On the magnetorquer they are its best flight rows: the MPC (1.63 × J* on
#: mt-flight; 6-9 s an episode, 108 s of a seed's 510 here: --agents can leave it out) and the
#: adaptive sliding mode on the measurements and through the MEKF (4.95 × J*; the paper's other
#: sliding modes within 0.2 %)
ANALYTIC: dict[str, dict[str, str]] = {
    "wheel": _GYROSTAT_ANALYTIC,
    "air-bearing": _GYROSTAT_ANALYTIC,
    "magnetorquer": {
        "amnftsmc": "Sadigh et al.'s adaptive sliding mode on the raw measurements.",
        "amnftsmc+mekf": "the same controller acting through the MEKF.",
        "mpc": "the campaign's MPC (the field predicted along the orbit, a disturbance observer) on the raw "
        "measurements.",
    },
    "slosh": {
        "slosh-lqr": "Navabi & Davoodi's LQR on the measurements (the slosh pendulums are not measured: they read 0).",
        "slosh-lqr+kf": "the same LQR on the Kalman filter's estimate, the slosh states reconstructed from "
        "the measured ones.",
    },
    "linear": {
        "lqr-dare": "the discrete LQR of the nominal (A, B) (its DARE) on the raw state measurements.",
        "linear-lqr+kf": "the same LQR on the Kalman filter's estimate.",
    },
}
#: the levels of each axis; a parameters level is the relative error of the plant's axis parameter
#: (:data:`PARAMETER_AXIS`)
PARAMETER_LEVELS = (0.0, 0.1, 0.25, 0.5)
#: a whole run's wall time, min, from nothing, every axis and agent (J* solves most of it: the
#: held-out axis's flight episodes 17 s each on ReactionWheel, 80-120 s on AirBearing's 2000
#: steps; one process on a 2-core machine shared with other runs, 2026-11-28 and -29); a rerun
#: reads every episode back from its record in seconds. magnetorquer, slosh and linear: 20 × one
#: seed's every point measured on 2 shared cores, 2026-11-29 (its 8 J* solves besides the shipped
#: table's, then its episodes): 510 s a seed on Magnetorquer (J* 385 s, 11-13 s a solve but
#: 136-176 s on held-out ×2 and ×4; the MPC's episodes 108 s), 415 s on FuelSlosh (J* 404 s,
#: 15-19 s a parameters solve, 62-82 s a delay or held-out one), 230 s on LinearSystem (J* 106 s;
#: the LQR's 40000-step episodes 2.6 s, through the Kalman filter 5.7 s; the whole LinearSystem
#: run took 81 min of wall time, 2026-11-29, split by axis over up to three processes)
#: Magnetorquer's mpc and ppo-flight rows: 96 min of wall time, 2026-11-29, beside two FuelSlosh runs.
#: FuelSlosh in full (2026-11-28 and -29): its delay and held-out solves take 2-5 min each from the
#: chained warm start (``_optimum``) and up to 30 min from the LQR's; with three runs sharing 2 cores
#: the page's points took more than 5 h, its held-out ×2 and ×4 unfinished. From ppo-flight's
#: closed loop (:data:`WARM_AGENT`) the last 33 solves took 20-30 s each: those points, with every
#: point of ppo and ppo-flight replayed, 11.5 min in one process (2026-11-29, night); a run from
#: nothing (8 solves a seed) is estimated from that (a time as text)
RUN_MINUTES: dict[str, int | str] = {
    "wheel": 40,
    "air-bearing": 105,
    "magnetorquer": "≈ 100 min on 2 cores shared with two other runs",
    "slosh": "an estimated 70 min in one process, 160 J\\* solves of 20-30 s each from ppo-flight's closed loop"
    " (33 of them measured; more than 5 h on 2 cores before that warm start),",
    "linear": 80,
}
#: the plant campaign's wall time, min, with its flight cells (the sum of the runs in its page's
#: runs.jsonl, 2026-11-26 to -29, shared cores; slosh: its one run of 2026-11-29 (night), alone)
CAMPAIGN_MINUTES = {"wheel": 72, "air-bearing": 47, "magnetorquer": 60, "slosh": 12, "linear": 30}
#: pages whose learned rows played an earlier training of the campaign's entries than the campaign
#: page's own (training on 2 CPU threads does not repeat bit for bit): what the page says of it.
#: Remove a plant's entry when its learned points are rerun on the campaign page's models.
EARLIER_MODELS: dict[str, str] = {}
DELAY_LEVELS = (0, 1, 2, 3)
NOISE_LEVELS = (1.0, 3.0, 10.0)
#: the held-out axis: the flight conditions' parameter tolerances times these (1: the flight cells')
HELD_OUT_LEVELS = (1.0, 2.0, 4.0)
AXES = ("parameters", "delay", "noise", "held-out")


def check_plant(plant: str) -> str:
    """``plant`` if it is a plant page (:data:`PLANTS`), else a ``ValueError`` naming them."""
    if plant not in PLANTS:
        raise ValueError(f"plant must be one of {sorted(PLANTS)}, got {plant!r}")
    return plant


def flight_tolerances(plant: str) -> dict[str, Any]:
    """Every flight tolerance of ``plant`` that the conditions' ``parameters`` scale multiplies:
    its flight table's plant tolerances and ``gain_tolerance`` (a number, or one per actuator)."""
    table = flight.table(PLANTS[check_plant(plant)])
    return {**{k: v.value for k, v in table.plant.items()}, "gain_tolerance": table.gain_tolerance.value}


def parameter_tolerance(plant: str) -> float:
    """The flight tolerance (relative) the plant's parameters levels are errors of
    (:data:`PARAMETER_AXIS`); a ``ValueError`` where it is not one number."""
    key = PARAMETER_AXIS[check_plant(plant)].tolerance
    value = np.asarray(flight_tolerances(plant)[key], dtype=float)
    if value.ndim:
        raise ValueError(f"the {plant} parameters axis needs one {key} tolerance, its flight table has {value}")
    return float(value)


def parameter_scale(plant: str, error: float) -> float:
    """The conditions' ``parameters`` scale that draws ``plant``'s axis parameter within ±
    ``error`` (relative); a ``ValueError`` where Conditions cannot express it."""
    tol = parameter_tolerance(plant)
    scale = error / tol
    if scale > MAX_PARAMETER_SCALE:
        raise ValueError(
            f"the {plant} parameters axis cannot reach {_percent(error)}: its {PARAMETER_AXIS[plant].tolerance} "
            f"tolerance ±{_percent(tol)} would need conditions['parameters'] = {scale:g}, above {MAX_PARAMETER_SCALE:g} "
            f"(accepted errors: up to {_percent(MAX_PARAMETER_SCALE * tol)})"
        )
    return scale


def axes(plant: str) -> list[tuple[str, float, dict | str]]:
    """``(axis, level, conditions)`` of every point of ``plant``'s curves."""
    points = [("parameters", p, {"sensors": 1.0, "parameters": parameter_scale(plant, p)}) for p in PARAMETER_LEVELS]
    points += [("delay", float(d), {"sensors": 1.0, "delay_steps": d}) for d in DELAY_LEVELS]
    points += [("noise", k, {"sensors": k}) for k in NOISE_LEVELS]
    points += [("held-out", k, "flight" if k == 1 else {"base": "flight", "parameters": k}) for k in HELD_OUT_LEVELS]
    return points


def scaled_tolerances(plant: str, scale: float) -> list[str]:
    """The page's words for every flight tolerance of ``plant`` but its axis's own at the
    ``parameters`` ``scale`` (``"principal axes ±20°"``), and a warning where an actuator's
    scale factor can be drawn at or below zero."""
    own = PARAMETER_AXIS[plant].tolerance
    words = []
    for key, value in flight_tolerances(plant).items():
        if key == own:
            continue
        name, unit = TOLERANCE_WORDS.get(key, (key, ""))
        values = np.atleast_1d(np.asarray(value, dtype=float)) * scale
        shown = [_percent(v) if unit == "%" else f"{v:.3g}{unit}" for v in dict.fromkeys(values.tolist())]
        words.append(f"{name} ±{' / '.join(shown)}")
        if key == "gain_tolerance" and values.max() >= 1.0:
            words[-1] += " (±100 % draws an actuator's gain down to zero)"
    return words


def _percent(fraction: float) -> str:
    """``0.05`` → ``"5 %"`` (three significant digits)."""
    return f"{100 * fraction:.3g} %"


def agents(plant: str) -> list[str]:
    """The analytic agents of ``plant``'s curves (:data:`ANALYTIC`), in order."""
    return list(ANALYTIC[check_plant(plant)])


@cache
def campaign_of(plant: str):
    """The plant's campaign (``experiments/campaigns/<plant>.yml``): its cells, its agents."""
    from experiments.campaign.spec import load_campaign

    return load_campaign(plant)


def cells(plant: str) -> tuple[Any, Any]:
    """The plant campaign's lab cell and its flight cell (the entry with ``conditions``)."""
    envs = campaign_of(plant).envs
    return next(e for e in envs if "conditions" not in e.kwargs), next(e for e in envs if "conditions" in e.kwargs)


def cell_kwargs(plant: str) -> dict:
    """The keywords of the plant campaign's lab cell (its episodes and J*)."""
    return dict(cells(plant)[0].kwargs)


def campaign_row(plant: str, name: str):
    """The plant campaign's agent ``name`` (its :class:`~experiments.campaign.spec.AgentSpec`)."""
    rows = {a.name: a for a in campaign_of(plant).agents}
    if name not in rows:
        raise ValueError(f"the {plant} campaign has no agent {name!r}; accepted: {sorted(rows)}")
    return rows[name]


def learned_agents(plant: str) -> list[str]:
    """The campaign's trained rows on ``plant``'s curves, in campaign order: every agent with
    ``train`` whose curves play a training on the lab or the flight cell (:func:`training_entry`)."""
    trained_on = {c.name for c in cells(plant)}
    return [
        a.name for a in campaign_of(plant).agents if a.train is not None and training_entry(plant, a.name) in trained_on
    ]


def play_of(plant: str, name: str, kwargs: dict | None = None) -> tuple[str, dict]:
    """The env id and keywords agent ``name`` plays ``plant``'s cell (built with ``kwargs``,
    default the lab cell's) on: its campaign play env
    (:func:`~experiments.campaign.spec.play_env`), without conditions."""
    from experiments.campaign.spec import play_env

    return play_env(campaign_row(plant, name), PLANTS[plant], dict(cell_kwargs(plant) if kwargs is None else kwargs))


def training_entry(plant: str, name: str) -> str:
    """The campaign env entry whose training of learned agent ``name`` plays the curves: its
    ``train.env``, else the flight cell where it plays it (its flight training), else the lab cell."""
    agent = campaign_row(plant, name)
    lab, flight_cell = cells(plant)
    played = flight_cell if agent.envs is None or flight_cell.name in agent.envs else lab
    return campaign_of(plant).trained_on(agent, played)


def learned_models(plant: str, results: Path, names: list[str] | None = None) -> dict[str, list[tuple[int, Path]]]:
    """name → ``(training seed, snapshot)`` of each training seed of the learned agents
    ``names`` (default :func:`learned_agents`) in the campaign results directory ``results``,
    where the campaign trains them (:func:`~experiments.campaign.jobs.train_dir`; the snapshot its
    ``train.select`` picks, ``best`` by default); a ``ValueError`` naming what is missing."""
    from experiments.campaign.jobs import train_dir, trained_model

    found, missing = {}, {}
    for name in learned_agents(plant) if names is None else names:
        agent = campaign_row(plant, name)
        if agent.train is None:
            raise ValueError(
                f"--agents {name!r} is not a trained agent of the {plant} campaign; accepted: {learned_agents(plant)}"
            )
        entry = training_entry(plant, name)
        runs = [(seed, train_dir(results, entry, name, seed)) for seed in agent.train["seeds"]]
        found[name] = [(seed, trained_model(run, agent.train.get("select", "best"))) for seed, run in runs]
        absent = [str(path) for _, path in found[name] if not path.is_file()]
        if absent:
            missing[name] = absent
    if missing:
        raise ValueError(
            f"--models {str(results)!r} has no trained {', '.join(missing)} of the {plant} campaign: "
            + "; ".join(f"{name}: {paths}" for name, paths in missing.items())
            + " (--agents can leave them out)"
        )
    return found


class Player(NamedTuple):
    """One policy on the curves: ``factory(env)`` builds it for its play env ``env_id`` with
    ``env_kwargs`` (no conditions); ``train_seed`` for a learned agent's training run."""

    train_seed: int | None
    factory: Callable
    env_id: str
    env_kwargs: dict


def _factory(spec: dict, name: str) -> Callable:
    """factory(env) of the policy ``spec`` (:func:`~experiments.policies.build_policy`) named ``name``."""
    from experiments.policies import build_policy

    return lambda env: build_policy(spec, env, name=name)


def players(plant: str, names: list[str] | None, models: Path | None, kwargs: dict) -> dict[str, list[Player]]:
    """name → the players of each agent on the curves (``names``, default every analytic one and,
    with the campaign results directory ``models``, every learned one) on ``plant``'s cell built
    with ``kwargs``; a ``ValueError`` naming an unknown agent and the accepted ones."""
    analytic = agents(plant)
    learned = learned_agents(plant)
    chosen = names or [*analytic, *(learned if models is not None else [])]
    unknown = [n for n in chosen if n not in analytic and (models is None or n not in learned)]
    if unknown:
        need = f" (the learned {learned} need --models)" if models is None else ""
        raise ValueError(f"--agents {unknown} unknown; accepted: {analytic + learned}{need}")
    found = learned_models(plant, models, [n for n in chosen if n in learned]) if models is not None else {}
    out = {}
    for name in chosen:
        row = campaign_row(plant, name)
        play_id, play_kwargs = play_of(plant, name, kwargs)
        if name in found:
            out[name] = [
                Player(seed, _factory({**row.spec, "model": str(path)}, name), play_id, play_kwargs)
                for seed, path in found[name]
            ]
        else:
            out[name] = [Player(None, _factory(dict(row.spec), name), play_id, play_kwargs)]
    return out


def j_star(
    env_id: str,
    conditions: dict | str,
    seed: int,
    env_kwargs: dict | None = None,
    warm: Callable[[], np.ndarray] | None = None,
) -> float:
    """The oracle's J of the episode under ``conditions`` without the sensors (the oracle knows
    the true state; the lab's where nothing else is on): the shipped table's where it holds the
    episode, else solved (from ``warm()``'s actions where given, see :func:`_optimum`);
    :class:`UnsolvedOptimum` when the solve ends without a solution."""
    from experiments.optimum_table import table_value

    kwargs = dict(env_kwargs or {})
    listed = table_value(env_id, {**kwargs, "conditions": conditions}, seed, None)
    if listed is not None:
        return float(listed)
    spec = Conditions.from_config(conditions).as_dict()
    plant = Conditions.from_config({k: v for k, v in spec.items() if k != "sensors"})
    if not plant.is_lab:
        kwargs["conditions"] = plant.as_dict()
    listed = table_value(env_id, kwargs, seed, None)  # the lab cell's, where only sensors are on
    if listed is not None:
        return float(listed)
    result = (
        _optimum(env_id, kwargs, seed)
        if warm is None
        else optimum.solve_episode(env_id, kwargs, seed, warm_start=warm())
    )
    if not result.solved:
        raise UnsolvedOptimum(f"J* did not solve ({result.status} after {result.iterations} iterations)")
    return result.j_star


class UnsolvedOptimum(RuntimeError):
    """The oracle's solve of an episode ended without a solution: its J is no J*."""


#: plant → the learned agent (its first training seed) whose closed loop, played at the cell's
#: control period, warm-starts J* there. On FuelSlosh under flight conditions the LQR's rollout
#: leaves the burn and IPOPT takes up to 30 min from it (the chain of :func:`_optimum` 2-5 min);
#: from ppo-flight's episode, which completes the burn, a held-out solve takes 20-30 s and lands
#: on the chain's J* (2026-11-29: to 1.1e-8 on the 7 held-out ×2 episodes both solved)
WARM_AGENT: dict[str, str] = {"slosh": "ppo-flight"}


def warm_start_of(plant: str, models: Path | None, kwargs: dict) -> Callable[[dict | str, int], np.ndarray] | None:
    """``warm(conditions, seed)``: the actions of :data:`WARM_AGENT`'s closed loop on the episode
    ``seed`` under ``conditions`` (sensors on: it observes the measurements), at the period of
    the cell built with ``kwargs`` and zero after an early end, one per step of the cell's
    episode (J*'s warm start); None where the plant has no warm agent or ``models`` (a campaign
    results directory) is None."""
    if models is None or plant not in WARM_AGENT:
        return None
    name = WARM_AGENT[plant]
    player = players(plant, [name], models, kwargs)[name][0]
    cell = gym.make(PLANTS[plant], **kwargs)
    period_s, steps = float(cell.unwrapped.control_dt_s), cell.unwrapped.decisions_per_episode
    cell.close()

    def warm(conditions: dict | str, seed: int) -> np.ndarray:
        env = gym.make(player.env_id, conditions=conditions, **{**player.env_kwargs, "control_dt_s": period_s})
        try:
            return optimum.policy_rollout(env, player.factory(env), seed, max_steps=steps)[0]
        finally:
            env.close()

    return warm


def _optimum(env_id: str, kwargs: dict, seed: int) -> optimum.OptimumResult:
    """The oracle's solve of one episode, warm-started from the point before it on its axis
    where the default warm start (the LQR's rollout) is lost, as on FuelSlosh in flight, and
    IPOPT then takes tens of minutes per episode: under a delay of ``d ≥ 2`` periods, the
    ``d − 1`` optimum's commands issued one period earlier (they act at the same instants);
    at a held-out scale ``k > 1``, the optimum at ``k / 2`` (at 1: the flight cell's)."""
    conditions = Conditions.from_config(kwargs.get("conditions", "lab"))
    if conditions.delay_steps >= 2:
        fewer = {**kwargs, "conditions": {**conditions.as_dict(), "delay_steps": conditions.delay_steps - 1}}
        earlier = _optimum(env_id, fewer, seed).actions
        warm = np.vstack([earlier[1:], earlier[-1:]])
    elif conditions.actuators and conditions.delay_steps == 1 and conditions.parameters > 1.0:
        half = conditions.parameters / 2.0
        nearer = {**kwargs, "conditions": "flight" if half <= 1.0 else {**conditions.as_dict(), "parameters": half}}
        warm = _optimum(env_id, nearer, seed).actions
    else:
        return optimum.solve_episode(env_id, kwargs, seed=seed)
    return optimum.solve_episode(env_id, kwargs, seed=seed, warm_start=warm)


def _read_log(log: Path) -> tuple[dict[tuple, dict], dict[tuple, float]]:
    """The episodes already in the record ``log``, by ``(agent, axis, level, seed, train_seed)``,
    and their J* by ``(axis, level, seed)``."""
    done: dict[tuple, dict] = {}
    j_stars: dict[tuple, float] = {}
    if log.is_file():
        for line in log.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[(r["agent"], r["axis"], r["level"], r["seed"], r.get("train_seed"))] = r
                j_stars[(r["axis"], r["level"], r["seed"])] = r["j_star"]
    return done, j_stars


def _row(name: str, axis: str, level: float, episodes: list[dict], seeds: int) -> dict:
    """The curves' row of agent ``name`` at one point from its ``episodes``."""
    js = [r["j"] for r in episodes]
    jstars = [r["j_star"] for r in episodes]
    return {
        "agent": name,
        "axis": axis,
        "level": level,
        "j_over_j_star": sum(js) / sum(jstars),
        "cvar10": cvar([j / s for j, s in zip(js, jstars, strict=True)], 0.1),
        "seeds": seeds,
    }


def run(
    plant: str,
    seeds: int,
    out: Path,
    names: list[str] | None = None,
    models: Path | None = None,
    axes_chosen: list[str] | None = None,
    env_kwargs: dict | None = None,
    recorded: bool = False,
) -> list[dict]:
    """Every point of ``plant``'s curves over ``seeds`` episodes of its campaign cell (its
    keywords, ``env_kwargs`` over them); the learned agents' from the campaign results
    directory ``models`` (None: the analytic ones only); rows written to ``out``. An
    episode's J* is solved once, whichever agent plays it. ``recorded``: play and solve
    nothing, rows only for the agents' points whose episodes are all in the record."""
    env_id = PLANTS[check_plant(plant)]
    kwargs = {**cell_kwargs(plant), **dict(env_kwargs or {})}
    log = out.with_suffix(".episodes.jsonl")
    done, j_stars = _read_log(log)
    chosen = players(plant, names, models, kwargs)
    warm = warm_start_of(plant, models, kwargs)
    rows = []
    if not recorded:
        out.parent.mkdir(parents=True, exist_ok=True)
    with contextlib.nullcontext() if recorded else log.open("a") as sink:
        for axis, level, conditions in axes(plant):
            if axes_chosen and axis not in axes_chosen:
                continue
            for name, agent_players in chosen.items():
                keys = [(name, axis, level, seed, p.train_seed) for p in agent_players for seed in range(seeds)]
                if recorded and not all(key in done for key in keys):
                    continue
                episodes = []
                for player in agent_players:
                    env = policy = None  # built for the first episode not in the record
                    for seed in range(seeds):
                        key = (name, axis, level, seed, player.train_seed)
                        if key not in done:
                            if env is None:
                                env = gym.make(player.env_id, conditions=conditions, **player.env_kwargs)
                                policy = player.factory(env)
                            episode = (axis, level, seed)
                            if episode not in j_stars:
                                try:
                                    start = None if warm is None else partial(warm, conditions, seed)
                                    j_stars[episode] = j_star(env_id, conditions, seed, kwargs, start)
                                except UnsolvedOptimum as exc:
                                    print(f"{plant} {axis} {level:g} seed {seed}: {exc}; the point stays incomplete")
                                    j_stars[episode] = None
                            if j_stars[episode] is None:
                                continue
                            done[key] = {
                                "agent": name,
                                "axis": axis,
                                "level": level,
                                "seed": seed,
                                **({"train_seed": player.train_seed} if player.train_seed is not None else {}),
                                # the policy sees no ground truth
                                "j": float(rollout(env, policy, seed=seed)["J"]),
                                "j_star": j_stars[episode],
                            }
                            sink.write(json.dumps(done[key]) + "\n")
                            sink.flush()
                        episodes.append(done[key])
                    if env is not None:
                        env.close()
                if len(episodes) < len(keys):  # an episode's J* did not solve
                    continue
                row = _row(name, axis, level, episodes, seeds)
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

    if rows:
        atomic_write(out, write_csv)
    return rows


def figure(rows: list[dict], plant: str, path: Path) -> None:
    """The curves: ΣJ/ΣJ* (top row; log scale where a column spans more than ×10) and the
    CVaR₀.₁ of J/J* (bottom row, log scale: a few episodes of tiny J* dominate it), one column
    per axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_names = [a for a in AXES if any(r["axis"] == a for r in rows)]
    labels = {
        "parameters": f"{PARAMETER_AXIS[plant].what} error (relative)",
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
        means = [r["j_over_j_star"] for r in rows if r["axis"] == axis]
        if max(means) > 10 * min(means):  # agents orders of magnitude apart (an episode ended early)
            grid[0, col].set_yscale("log")
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


def _table(rows: list[dict], agents_seen: list[str]) -> list[str]:
    """The page's table: one line per point, each agent's ΣJ/ΣJ* then each one's CVaR₀.₁."""
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
    return lines


def _wrap(text: str, first: str = "", then: str = "") -> str:
    """``text`` wrapped at 95 characters, never inside a word (agent names have hyphens)."""
    return textwrap.fill(
        text, width=95, initial_indent=first, subsequent_indent=then, break_long_words=False, break_on_hyphens=False
    )


def _bullet(text: str) -> str:
    """A Markdown bullet of ``text``, wrapped at 95 characters."""
    return _wrap(text, "* ", "  ")


def _parameters_text(plant: str, top: float) -> str:
    """The page's parameters bullet: what the level is an error of and, at the ``top`` level,
    the plant's other flight tolerances scaled with it."""
    axis = PARAMETER_AXIS[plant]
    tol = parameter_tolerance(plant)
    text = (
        f"**parameters**: the true {axis.what} drawn within ± that relative error (conditions' "
        f"`parameters` = the level over the flight table's ±{_percent(tol)} `{axis.tolerance}`)"
    )
    others = scaled_tolerances(plant, parameter_scale(plant, top))
    if not others:
        return _bullet(text + f", {PLANTS[plant].split('/')[1].split('-v')[0]}'s only flight parameter tolerance;")
    return _bullet(
        text + f", with the plant's other flight tolerances scaled with it; at {_percent(top)}: {', '.join(others)};"
    )


def control_period(env_id: str, kwargs: dict) -> float:
    """The control period (s) of env ``env_id`` built with ``kwargs``."""
    env = gym.make(env_id, **kwargs)
    try:
        return float(env.unwrapped.control_dt_s)
    finally:
        env.close()


def _periods(plant: str, agents_seen: list[str]) -> str:
    """The page's words for the control period of each agent's play env, grouped."""
    groups: dict[tuple[str, float], list[str]] = {}
    for name in agents_seen:
        env_id, kwargs = play_of(plant, name)
        groups.setdefault((env_id, control_period(env_id, kwargs)), []).append(f"`{name}`")
    return "; ".join(f"{dt:g} s for {', '.join(names)} ({i.split('/')[1]})" for (i, dt), names in groups.items())


def learned_note(plant: str, name: str) -> str:
    """The page's words for learned agent ``name``: its algorithm, where it trained, what on."""
    agent = campaign_row(plant, name)
    lab = cells(plant)[0]
    where = (
        "in the lab"
        if training_entry(plant, name) == lab.name
        else "under flight conditions (domain randomization over the flight cells' distribution)"
    )
    note = f"the campaign's {agent.train['algo'].upper()} trained {where}"
    if (agent.train.get("env_kwargs") or {}).get("faults"):
        note += ", on random actuator faults"
    wrappers = zoo_objects("env_wrapper", (agent.train.get("overrides") or {}).get("env_wrapper"))
    if wrappers:
        named = ", ".join(
            path + (f"({', '.join(f'{k}={v!r}' for k, v in kw.items())})" if kw else "") for path, kw in wrappers
        )
        note += f", trained and played behind `{named}`"
    return note + "."


def _agents_text(plant: str, agents_seen: list[str], seeds: int) -> str:
    """The page's list of the agents on the curves, analytic then learned."""
    learned = [a for a in agents_seen if a in learned_agents(plant)]
    lines = [_bullet(f"`{a}` is {ANALYTIC[plant][a]}") for a in agents_seen if a in ANALYTIC[plant]]
    lines += [_bullet(f"`{a}` is {learned_note(plant, a)}") for a in learned]
    if learned:
        runs = sorted({len(campaign_row(plant, a).train["seeds"]) for a in learned})
        lines.append(
            "\nThe learned agents play the episodes on the measurements, each training seed's best snapshot\n"
            f"(its final one where none was saved): their points cover {' or '.join(map(str, runs))} × {seeds} "
            "episodes."
        )
    return "\n".join(lines)


def _held_out_text(plant: str, agents_seen: list[str], run: bool) -> str:
    """The page's held-out bullet: the flight cells ×1 (where the flight-trained agents trained), ×2 and ×4."""
    if not run:
        return "* **held-out** (the flight cells' tolerances ×1–×4) is not run here."
    flight_cell = cells(plant)[1].name
    trained = [f"`{a}`" for a in agents_seen if a in learned_agents(plant) and training_entry(plant, a) == flight_cell]
    where = f", the distribution {', '.join(trained)} trained on" if trained else ""
    return _bullet(
        "**held-out**: every flight feature, with the parameter tolerances times that factor. At ×1 "
        f"these are the campaign's flight cells{where}; ×2 and ×4 lie outside it."
    )


def _cvar_text(episodes: list[dict]) -> str:
    """The page's paragraph on the episode of least J* on the noise axis, which the CVaR follows."""
    noise = [e for e in episodes if e["axis"] == "noise"]
    if not noise or min(e["j_star"] for e in noise) > 0.5 * max(e["j_star"] for e in noise):
        return ""  # no episode's J* stands out (LinearSystem: every seed starts from the paper's x₀)
    smallest = min(noise, key=lambda e: e["j_star"])
    worst = max((e for e in noise if e["seed"] == smallest["seed"]), key=lambda e: e["j"])
    return f"""**The CVaR₀.₁ of J/J\\* follows the smallest J\\*.** Episode {smallest["seed"]} has the smallest
J\\* on the noise axis, {smallest["j_star"]:.3g}. There an agent's J/J\\* reaches
{worst["j"] / worst["j_star"]:.3g} ({worst["agent"]} at noise ×{worst["level"]:g}): a tiny J\\* magnifies
whatever cost an agent cannot avoid, such as the sensor noise floor's, which does not shrink
with the maneuver. ΣJ/ΣJ\\* is the robust summary.
"""


_RUN_NOTE = " from nothing with every agent, most of it J\\*"


def _minutes(table: dict[str, int | str], plant: str, what: str = "") -> str:
    """``≈ N min on 2 cores`` (then ``what``) from a measured ``table`` (a text entry as it is),
    or that it is not measured yet."""
    if plant not in table:
        return "its time is not measured yet"
    time = table[plant]
    return f"{time}{what}" if isinstance(time, str) else f"≈ {time} min on 2 cores{what}"


def _missing_text(missing: list[tuple[str, float]]) -> str:
    if not missing:
        return ""
    points = ", ".join(f"{axis} {AXIS_LEVEL[axis](level)}" for axis, level in missing)
    return (
        "\n"
        + _wrap(f"Not measured yet: {points}. The run stopped before them; rerunning the command below resumes it.")
        + "\n"
    )


def page(
    rows: list[dict],
    plant: str,
    episodes: list[dict],
    missing: list[tuple[str, float]] = (),
    requested: list[str] | None = None,
) -> str:
    """The Markdown page of the curves: the figure, the table, the points not measured yet
    (``missing``: axis and level), what the points are, the episode of least J* (which the
    CVaR of J/J* follows), and how to reproduce it (the run of the ``requested`` agents, None:
    those in ``rows``, and of the axes measured or missing)."""
    env_name = PLANTS[check_plant(plant)].split("/")[1]
    agents_seen = list(dict.fromkeys(r["agent"] for r in rows))
    seeds = rows[0]["seeds"]
    run_axes = [a for a in AXES if any(r["axis"] == a for r in rows) or any(m[0] == a for m in missing)]
    axes_arg = "" if run_axes == list(AXES) else " --axes " + " ".join(run_axes)
    every = agents(plant) + learned_agents(plant)
    run_agents = agents_seen if requested is None else list(requested)
    agents_arg = "" if sorted(run_agents) == sorted(every) else " --agents " + " ".join(run_agents)
    top = max([r["level"] for r in rows if r["axis"] == "parameters"] or [PARAMETER_LEVELS[-1]])
    return rf"""# {env_name}: robustness to flight conditions

<!-- Generated by benchmarks/robustness.py from robustness.episodes.jsonl; rerun it, do not edit. -->

![robustness curves](figures/robustness.png)

{chr(10).join(_table(rows, agents_seen))}
{_missing_text(list(missing))}
Each point covers the {seeds} episodes (seeds 0–{seeds - 1}) of the {plant} campaign's cell
(`{json.dumps(cell_kwargs(plant))}`), with the flight sensors on (`attitude_envs.conditions`).
One more feature is switched on per axis:

{_parameters_text(plant, top)}
* **delay**: that many control periods of command delay;
* **noise**: the flight sensors' noise times that factor;
{_held_out_text(plant, agents_seen, "held-out" in run_axes)}

{_wrap(f"The delay counts control periods of the env each agent plays: {_periods(plant, agents_seen)}.")}

J* is the oracle under the same conditions, on the cell's env ({env_name}). Sensors do not
enter it, because it knows the true state.

The agents:

{_agents_text(plant, agents_seen, seeds)}
{chr(10) + _wrap(EARLIER_MODELS[plant]) + chr(10) if plant in EARLIER_MODELS and learned_agents(plant) else ""}
{_cvar_text(episodes)}
The learned rows need the campaign's models: `attitude-envs benchmark --config {plant} --out results/{plant}` ({_minutes(CAMPAIGN_MINUTES, plant)}).
Then `python -m benchmarks.robustness --plant {plant} --seeds {seeds} --models results/{plant}{axes_arg}{agents_arg}` ({_minutes(RUN_MINUTES, plant, _RUN_NOTE)}). The run resumes from `robustness.episodes.jsonl`, which holds every episode's J
and J\*. The data are in [`robustness.csv`](robustness.csv), with columns agent, axis, level,
j_over_j_star, cvar10 and seeds.
"""


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=sorted(PLANTS), required=True)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument(
        "--agents",
        nargs="*",
        default=None,
        help="agents on the curves (default: the plant's analytic ones and, with --models, its learned ones)",
    )
    parser.add_argument(
        "--models", default=None, help="a campaign results directory: its learned agents join the curves"
    )
    parser.add_argument("--axes", nargs="*", choices=AXES, default=None, help="axes to run (default: all)")
    parser.add_argument(
        "--recorded",
        action="store_true",
        help="play and solve nothing: the curves of the points whose episodes are all in the record",
    )
    parser.add_argument("--out", default=None, help="CSV (default docs/campaigns/<plant>/robustness.csv)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    out = Path(args.out or f"docs/campaigns/{args.plant}/robustness.csv")
    models = Path(args.models) if args.models else None
    if models is not None and not models.is_dir():
        parser.error(f"--models must be a campaign results directory, got {args.models!r}")
    rows = run(args.plant, args.seeds, out, args.agents, models, args.axes, recorded=args.recorded)
    if not rows:
        parser.error(f"no point of {args.plant}'s curves has all its episodes in {out.with_suffix('.episodes.jsonl')}")
    figure(rows, args.plant, out.parent / "figures" / "robustness.png")
    log = out.with_suffix(".episodes.jsonl")
    episodes = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    measured = {(r["axis"], r["level"]) for r in rows}
    missing = [(a, v) for a, v, _ in axes(args.plant) if (not args.axes or a in args.axes) and (a, v) not in measured]
    text = page(rows, args.plant, episodes, missing, args.agents)
    out.with_suffix(".md").write_text(text, encoding="utf-8")
    return rows


if __name__ == "__main__":
    main()
