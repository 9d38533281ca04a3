"""Genetic-algorithm PID tuning and the meta-model of the air-bearing GA-tuned PID paper
(Ahangarani Farahani, Adami & Arefkhani; year unknown), for any attitude env.

Pipeline (the paper's five steps):

1. :func:`tune_gains` — a GA (``pygad``) finds constant gains ``[Kp, Kd, KI] × (roll, pitch,
   yaw)`` (9 real genes) that minimize an objective summed over a set of maneuvers: the
   paper's IAE ``Σ_i ∫|e_i| dt`` over the 3-2-1 Euler-angle errors (deg·s, eq. 20/26) or the
   env's shared cost ``J = Σ info["cost"]``. Defaults are Table 2: population 20, 50
   generations, mutation probability 0.4 per gene, two-point crossover, roulette selection;
   the rest is assumed: crossover probability 0.8, elitism 1, fitness ``1/(1 + objective)``
   for the roulette wheel, bounds Kp ∈ [0, 10], Kd ∈ [0, 20], KI ∈ [0, 1]. Mutation draws
   the gene anew, uniformly within its bounds (pygad's gene-space mutation) — a Gaussian
   σ = 10 % is not what pygad offers; bounded uniform replacement keeps the genes in range.
2. :func:`build_schedule` — one GA per maneuver ("different initial values"); the optimal
   gains and the maneuver's states go to the data bank.
3.–4. :func:`fit_schedule` — ordinary least squares of each channel's optimal gains on
   ``[1, y_i, ẏ_i]`` (eq. 23): the Euler angle and rate of the maneuver's *initial* state by
   default (assumed), or the *final* state of the optimal run (``regressor="final"``, the
   paper's literal eq. 22 — nearly unidentifiable for regulation: the final states are all
   near zero).
5. :class:`baselines.pid.PIDPolicy` runs the fitted :class:`~baselines.pid.GainSchedule`.

Evaluations of a generation run in parallel in a process pool (``workers``); every worker
builds its env once. Episodes that end early (the air bearing's tilt stop, tumbling) are
charged the remaining time at the last error (IAE) or, for J, the env's own termination cost
(``termination_cost="hold"``; the last step's cost rate with ``"none"``), so the GA avoids them.

Command line: :func:`tune_pid_main` (``attitude-envs tune-pid``): tunes, shows a progress bar with
ETA (one status line every 30 s when not on a terminal) and writes a JSON gains file that :func:`baselines.pid.load_gains` / ``PIDPolicy.from_file`` read.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pygad

import attitude_envs  # noqa: F401  (registers the env ids, also in the pool's workers)
from attitude_envs import validation
from attitude_envs.info import TRUTH, policy_view
from experiments.processes import die_with_parent, pool_context
from experiments.progress import Progress
from baselines.pid import GAIN_NAMES, UNITS, GainSchedule, PIDGains, PIDPolicy, euler_error

OBJECTIVES = ("iae", "cost")
REGRESSORS = ("initial", "final")
#: the paper's eq. 25: the laboratory test, [φ, θ, ψ] = [10, −10, 10]° and ω = [1, 1, 0] °/s
LAB_MANEUVER = {"euler_321_deg": [10.0, -10.0, 10.0], "rate_rad_s": np.radians([1.0, 1.0, 0.0]).tolist()}


@dataclass(frozen=True)
class GAConfig:
    """GA settings (defaults: the paper's Table 2, the rest assumed). Bounds are (min, max) per gain type."""

    population: int = 20
    generations: int = 50
    mutation_probability: float = 0.4
    crossover_probability: float = 0.8
    crossover: str = "two_points"
    selection: str = "rws"
    elitism: int = 1
    seed: int = 0
    kp_bounds: tuple[float, float] = (0.0, 10.0)
    kd_bounds: tuple[float, float] = (0.0, 20.0)
    ki_bounds: tuple[float, float] = (0.0, 1.0)

    def __post_init__(self) -> None:
        if int(self.population) != self.population or self.population < 2:
            raise ValueError(f"population must be an integer >= 2, got {self.population!r}")
        if int(self.generations) != self.generations or self.generations < 1:
            raise ValueError(f"generations must be an integer >= 1, got {self.generations!r}")
        for name in ("mutation_probability", "crossover_probability"):
            v = float(getattr(self, name))
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {v!r}")
        validation.choice("crossover", self.crossover, {"single_point", "two_points", "uniform", "scattered"})
        validation.choice("selection", self.selection, {"rws", "sss", "sus", "rank", "random", "tournament"})
        if int(self.elitism) != self.elitism or not 0 <= self.elitism < self.population:
            raise ValueError(f"elitism must be an integer in [0, population), got {self.elitism!r}")
        for name in ("kp_bounds", "kd_bounds", "ki_bounds"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi or lo < 0.0:
                raise ValueError(f"{name} must be (min, max) with 0 <= min <= max < inf, got {getattr(self, name)!r}")
            object.__setattr__(self, name, (lo, hi))

    def gene_space(self) -> list[dict[str, float]]:
        """pygad gene space of the 9 genes ``[Kp, Kd, KI] × (roll, pitch, yaw)``."""
        per_axis = [self.kp_bounds, self.kd_bounds, self.ki_bounds]
        return [{"low": lo, "high": hi} for _ in range(3) for lo, hi in per_axis]


@dataclass
class TuningResult:
    """Best gains, their objective, and the best objective of the initial population and after
    each generation (``history[0]`` is the initial population's best)."""

    gains: PIDGains
    objective: float
    history: list[float]
    evaluations: int


@dataclass
class ScheduleResult:
    """Fitted schedule and its data bank: per maneuver the GA-optimal genes, the regressor
    states (rad, rad/s) and the fit's residual RMS per gain and channel."""

    schedule: GainSchedule
    genes: np.ndarray
    angles_rad: np.ndarray
    rates_rad_s: np.ndarray
    residual_rms: np.ndarray
    rank: np.ndarray
    tunings: list[TuningResult] = field(default_factory=list)


# ---------------------------------------------------------------------------- episodes
def pid_episode(env, policy, seed: int | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """One episode of ``policy``; IAE of the Euler-angle errors per axis (deg·s, trapezoid over
    the control samples), shared cost ``J``, and the charge for an early end.

    The policy acts on :func:`attitude_envs.info.policy_view` of each info (the measured state,
    as in flight); the IAE, effort and the initial/final states are scores from the truth."""
    obs, info = env.reset(seed=seed, options=None if options is None else dict(options))
    policy.reset(seed)
    base = env.unwrapped
    dt = float(base.control_dt_s)
    state = info[TRUTH]["state"]
    angle0, rate0 = euler_error(state["attitude"], state["rate_rad_s"], state["target_attitude"])
    prev = np.abs(angle0)
    iae = np.zeros(3)
    total = 0.0
    peak = 0.0
    effort = 0.0
    terminated = truncated = False
    cost = 0.0
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        cost = float(info["cost"])
        total += cost
        truth = info[TRUTH]
        torque = np.abs(truth["applied"])
        peak = max(peak, float(torque.max()))
        effort += float(torque.sum()) * dt
        state = truth["state"]
        angle, rate = euler_error(state["attitude"], state["rate_rad_s"], state["target_attitude"])
        cur = np.abs(angle)
        iae += 0.5 * (prev + cur) * dt
        prev = cur
    remaining = max(0.0, float(base.episode_duration_s) - float(info["time_s"]))
    iae_deg = np.degrees(iae)
    return {
        "iae_deg_s": iae_deg,
        "J": total,
        "terminated": bool(terminated),
        "remaining_s": remaining if terminated else 0.0,
        "iae_charged_deg_s": iae_deg + (np.degrees(prev) * remaining if terminated else 0.0),
        # the env charges a limit crossing itself (termination_cost="hold": the terminal
        # state's running cost over the rest of the horizon); with "none" the last step's rate
        "J_charged": total + (cost / dt * remaining if terminated and base.termination_cost == "none" else 0.0),
        "initial_angle_rad": angle0,
        "initial_rate_rad_s": rate0,
        "final_angle_rad": angle,
        "final_rate_rad_s": rate,
        "peak_motor_torque_nm": peak,
        "effort_integral_nm_s": effort,
    }


def maneuver_objective(env, gains: PIDGains | GainSchedule, maneuvers: Sequence[dict], objective: str) -> float:
    """Sum over ``maneuvers`` (dicts with ``options`` and ``seed``) of the charged IAE (all axes,
    deg·s) or charged shared cost."""
    policy = PIDPolicy(env, gains)
    total = 0.0
    for m in maneuvers:
        r = pid_episode(env, policy, m.get("seed"), m.get("options"))
        total += float(r["iae_charged_deg_s"].sum()) if objective == "iae" else r["J_charged"]
    return total if np.isfinite(total) else 1e12


_WORKER: dict[str, Any] = {}


def _worker_init(env_id: str, env_kwargs: dict[str, Any]) -> None:
    _WORKER["env"] = gym.make(env_id, **env_kwargs).unwrapped
    _WORKER["key"] = (env_id, repr(sorted(env_kwargs.items())))


def _pool_worker_init(parent_pid: int, env_id: str, env_kwargs: dict[str, Any]) -> None:
    die_with_parent(parent_pid)  # Ctrl-C is the parent's; the worker dies with it, also on SIGKILL
    _worker_init(env_id, env_kwargs)


def _worker_eval(task: tuple[np.ndarray, list[dict], str]) -> float:
    genes, maneuvers, objective = task
    return maneuver_objective(_WORKER["env"], PIDGains.from_vector(genes), maneuvers, objective)


class Evaluator:
    """Evaluates gain vectors on a set of maneuvers: in-process (``workers=1``) or in a process
    pool whose workers each build the env once. Use as a context manager."""

    def __init__(self, env_id: str, env_kwargs: dict[str, Any] | None = None, workers: int = 1) -> None:
        if int(workers) != workers or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs or {})
        self.workers = int(workers)
        self._pool: ProcessPoolExecutor | None = None
        _worker_init(env_id, self.env_kwargs)  # validates the env here, and serves workers=1
        self._local = _WORKER["env"]

    def __enter__(self) -> Evaluator:
        if self.workers > 1:
            self._pool = ProcessPoolExecutor(
                self.workers,
                mp_context=pool_context(),
                initializer=_pool_worker_init,
                initargs=(os.getpid(), self.env_id, self.env_kwargs),
            )
        return self

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    @property
    def env(self):
        return self._local

    def evaluate(self, genes: np.ndarray, maneuvers: list[dict], objective: str) -> np.ndarray:
        tasks = [(np.asarray(g, dtype=float), maneuvers, objective) for g in genes]
        if self._pool is None:
            return np.array(
                [maneuver_objective(self._local, PIDGains.from_vector(t[0]), maneuvers, objective) for t in tasks]
            )
        return np.array(list(self._pool.map(_worker_eval, tasks)))


# ---------------------------------------------------------------------------- GA
def tune_gains(
    evaluator: Evaluator,
    maneuvers: Sequence[dict],
    config: GAConfig | None = None,
    objective: str = "iae",
    progress: Callable[[int, float], None] | None = None,
) -> TuningResult:
    """GA over the 9 constant gains on ``maneuvers`` (list of ``{"options": ..., "seed": ...}``).

    ``progress(generation, best_objective)`` is called after every generation.
    """
    config = config or GAConfig()
    objective = validation.choice("objective", objective, set(OBJECTIVES))
    maneuvers = [dict(m) for m in maneuvers]
    if not maneuvers:
        raise ValueError("maneuvers must contain at least one maneuver")
    cache: dict[bytes, float] = {}
    history: list[float] = []

    def fitness(ga, solutions, indices):
        solutions = np.atleast_2d(np.asarray(solutions, dtype=float))
        todo = [s for s in solutions if s.tobytes() not in cache]
        if todo:
            values = evaluator.evaluate(np.array(todo), maneuvers, objective)
            for s, v in zip(todo, values, strict=True):
                cache[s.tobytes()] = float(v)
        objectives = np.array([cache[s.tobytes()] for s in solutions])
        if not history:
            history.append(float(objectives.min()))
        return (1.0 / (1.0 + objectives)).tolist()

    def on_generation(ga) -> None:
        best = float(1.0 / np.max(ga.last_generation_fitness) - 1.0)
        history.append(min(best, history[-1]))
        if progress is not None:
            progress(ga.generations_completed, history[-1])

    ga = pygad.GA(
        num_generations=int(config.generations),
        num_parents_mating=max(2, int(config.population) // 2),
        fitness_func=fitness,
        fitness_batch_size=int(config.population),
        sol_per_pop=int(config.population),
        num_genes=9,
        gene_space=config.gene_space(),
        gene_type=float,
        parent_selection_type=config.selection,
        keep_elitism=int(config.elitism),
        crossover_type=config.crossover,
        crossover_probability=float(config.crossover_probability),
        mutation_type="random",
        mutation_probability=float(config.mutation_probability),
        mutation_by_replacement=True,
        on_generation=on_generation,
        random_seed=int(config.seed),
        suppress_warnings=True,
    )
    ga.run()
    best_genes = min(cache, key=cache.get)
    genes = np.frombuffer(best_genes, dtype=float).copy()
    return TuningResult(PIDGains.from_vector(genes), cache[best_genes], history, len(cache))


# ---------------------------------------------------------------------------- meta-model
def fit_schedule(genes: np.ndarray, angles_rad: np.ndarray, rates_rad_s: np.ndarray, units: str = "rad"):
    """Least-squares fit of eq. 23: for each gain ``g`` and channel ``i``, ``K_gi ≈ k1 + k2 y_i + k3 ẏ_i``
    over the data bank (``genes`` N×9 as in :meth:`PIDGains.as_vector`, states N×3 in rad and
    rad/s, converted to ``units``). Returns ``(schedule, residual_rms (3×3), rank (3))``."""
    units = validation.choice("units", units, set(UNITS))
    genes = validation.finite_array("genes", genes)
    n = genes.shape[0]
    if genes.ndim != 2 or genes.shape[1] != 9:
        raise ValueError(f"genes must be N×9, got shape {genes.shape}")
    angles = validation.finite_array("angles_rad", angles_rad, (n, 3))
    rates = validation.finite_array("rates_rad_s", rates_rad_s, (n, 3))
    if n < 3:
        raise ValueError(f"the meta-model fit needs at least 3 maneuvers (3 coefficients per gain), got {n}")
    scale = 1.0 if units == "rad" else 180.0 / np.pi
    k = genes.reshape(n, 3, 3)  # [maneuver, axis, gain]
    coeffs = np.zeros((3, 3, 3))
    rms = np.zeros((3, 3))
    rank = np.zeros(3, dtype=int)
    for i in range(3):
        design = np.column_stack([np.ones(n), angles[:, i] * scale, rates[:, i] * scale])
        sol, _, rank[i], _ = np.linalg.lstsq(design, k[:, i, :], rcond=None)
        coeffs[:, i, :] = sol.T
        rms[:, i] = np.sqrt(np.mean((design @ sol - k[:, i, :]) ** 2, axis=0))
    return GainSchedule(coeffs, units), rms, rank


def sample_maneuvers(env, n: int, seed: int = 0) -> list[dict]:
    """``n`` maneuvers from the env's own start distribution (reset seeds ``seed .. seed+n−1``),
    pinned as explicit reset options (the true attitude, rate, target) so that every worker
    replays them."""
    if int(n) != n or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    out = []
    for j in range(int(n)):
        _, info = env.reset(seed=int(seed) + j)
        s = info[TRUTH]["state"]
        out.append(
            {
                "seed": int(seed) + j,
                "options": {
                    "attitude": np.asarray(s["attitude"]).tolist(),
                    "rate_rad_s": np.asarray(s["rate_rad_s"]).tolist(),
                    "target_attitude": np.asarray(s["target_attitude"]).tolist(),
                },
            }
        )
    return out


def build_schedule(
    evaluator: Evaluator,
    maneuvers: Sequence[dict],
    config: GAConfig | None = None,
    objective: str = "iae",
    regressor: str = "initial",
    units: str = "rad",
    progress: Callable[[int, int, float], None] | None = None,
) -> ScheduleResult:
    """Steps 2–4 of the paper's pipeline: a GA per maneuver, then the least-squares meta-model.

    ``progress(maneuver_index, generation, best)`` after every generation."""
    regressor = validation.choice("regressor", regressor, set(REGRESSORS))
    units = validation.choice("units", units, set(UNITS))
    config = config or GAConfig()
    tunings, angles, rates = [], [], []
    for j, m in enumerate(maneuvers):
        cb = None if progress is None else (lambda g, b, j=j: progress(j, g, b))
        result = tune_gains(evaluator, [m], config, objective, cb)
        tunings.append(result)
        run = pid_episode(evaluator.env, PIDPolicy(evaluator.env, result.gains), m.get("seed"), m.get("options"))
        which = "initial" if regressor == "initial" else "final"
        angles.append(run[f"{which}_angle_rad"])
        rates.append(run[f"{which}_rate_rad_s"])
    genes = np.array([t.gains.as_vector() for t in tunings])
    schedule, rms, rank = fit_schedule(genes, np.array(angles), np.array(rates), units)
    return ScheduleResult(schedule, genes, np.array(angles), np.array(rates), rms, rank, tunings)


# ---------------------------------------------------------------------------- command line
def _json_ready(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    return value


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="attitude-envs tune-pid",
        description="GA-tune per-axis PID gains (air-bearing PID paper) on an attitude env; writes a JSON gains file",
    )
    p.add_argument("--env", default="attitude_envs/AirBearing-v0", help="env id (any env with info['measured'])")
    p.add_argument("--env-kwargs", default="{}", help="JSON dict of env keyword arguments")
    p.add_argument("--mode", choices=["fixed", "schedule"], default="fixed", help="constant gains or meta-model")
    p.add_argument("--objective", choices=OBJECTIVES, default="iae", help="IAE (deg·s) or the shared cost J")
    p.add_argument("--maneuvers", type=int, default=0, help="random maneuvers from the env (0: the paper's lab test)")
    p.add_argument("--maneuver-seed", type=int, default=0, help="first reset seed of the random maneuvers")
    p.add_argument("--population", type=int, default=GAConfig.population)
    p.add_argument("--generations", type=int, default=GAConfig.generations)
    p.add_argument("--mutation-probability", type=float, default=GAConfig.mutation_probability)
    p.add_argument("--crossover-probability", type=float, default=GAConfig.crossover_probability)
    p.add_argument("--seed", type=int, default=0, help="GA seed")
    for g, b in zip(GAIN_NAMES, (GAConfig.kp_bounds, GAConfig.kd_bounds, GAConfig.ki_bounds), strict=True):
        p.add_argument(f"--{g}-bounds", type=float, nargs=2, default=list(b), metavar=("MIN", "MAX"))
    p.add_argument("--regressor", choices=REGRESSORS, default="initial", help="meta-model states (schedule mode)")
    p.add_argument("--units", choices=UNITS, default="rad", help="schedule argument units (schedule mode)")
    p.add_argument("--workers", type=int, default=2, help="parallel evaluation processes")
    p.add_argument("--out", default="pid_gains.json", help="output JSON file")
    return p


def tune_pid_main(argv: list[str] | None = None) -> int:
    """``attitude-envs tune-pid``: run the GA (and the meta-model with ``--mode schedule``), save the gains.

    Returns 0, or 2 after printing ``error: ...`` for bad input (``ValueError``)."""
    args = build_parser().parse_args(argv)
    try:
        return _tune_pid(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _tune_pid(args: argparse.Namespace) -> int:
    try:
        env_kwargs = json.loads(args.env_kwargs)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}") from exc
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
    config = GAConfig(
        population=args.population,
        generations=args.generations,
        mutation_probability=args.mutation_probability,
        crossover_probability=args.crossover_probability,
        seed=args.seed,
        kp_bounds=tuple(args.kp_bounds),
        kd_bounds=tuple(args.kd_bounds),
        ki_bounds=tuple(args.ki_bounds),
    )
    with Evaluator(args.env, env_kwargs, args.workers) as ev:
        if args.maneuvers > 0:
            maneuvers = sample_maneuvers(ev.env, args.maneuvers, args.maneuver_seed)
        else:
            maneuvers = [{"seed": 0, "options": LAB_MANEUVER}]
        doc: dict[str, Any] = {
            "env": args.env,
            "env_kwargs": env_kwargs,
            "objective": args.objective,
            "config": asdict(config),
            "maneuvers": maneuvers,
        }
        if args.mode == "fixed":
            with Progress(config.generations, "GA generations", "gen") as bar:

                def progress(gen: int, best: float) -> None:
                    bar.update(1)
                    bar.set_postfix(f"best {best:.4g}")

                result = tune_gains(ev, maneuvers, config, args.objective, progress)
            doc.update(gains=result.gains.to_dict(), best_objective=result.objective, history=result.history)
        else:
            total = config.generations * len(maneuvers)
            with Progress(total, "GA generations (all maneuvers)", "gen") as bar:

                def progress(j: int, gen: int, best: float) -> None:
                    bar.update(1)
                    bar.set_postfix(f"maneuver {j}, best {best:.4g}")

                res = build_schedule(ev, maneuvers, config, args.objective, args.regressor, args.units, progress)
            doc.update(
                gains=res.schedule.to_dict(),
                regressor=args.regressor,
                data_bank={"genes": res.genes, "angles_rad": res.angles_rad, "rates_rad_s": res.rates_rad_s},
                residual_rms=res.residual_rms,
                rank=res.rank,
                best_objectives=[t.objective for t in res.tunings],
            )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(_json_ready(doc), indent=2) + "\n", encoding="utf-8")
    print(f"wrote {out} ({args.mode} gains, objective {args.objective})")
    return 0


if __name__ == "__main__":
    sys.exit(tune_pid_main())
