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

Evaluations of a generation can run in parallel on an executor (:class:`Evaluator`); every worker
builds its env once. Episodes that end early (the air bearing's tilt stop, tumbling) are
charged the remaining time at the last error (IAE) or, for J, the env's own termination cost
(``termination_cost="hold"``; the last step's cost rate with ``"none"``), so the GA avoids them.

The command line ``attitude-envs tune-pid`` (:mod:`experiments.pid_tuning`) runs the pipeline in a
process pool and writes a JSON gains file that :func:`baselines.pid.load_gains` / ``PIDPolicy.from_file`` read.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
import pygad

import attitude_envs  # noqa: F401  (registers the env ids, also in the pool's workers)
from attitude_envs import validation
from attitude_envs.info import TRUTH, policy_view
from baselines.pid import UNITS, GainSchedule, PIDGains, PIDPolicy, euler_error

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


def init_worker(env_id: str, env_kwargs: dict[str, Any]) -> None:
    """Builds the env a process evaluates gains on: the ``initializer`` of an :class:`Evaluator`'s executor."""
    _WORKER["env"] = gym.make(env_id, **env_kwargs).unwrapped


def _worker_eval(task: tuple[np.ndarray, list[dict], str]) -> float:
    genes, maneuvers, objective = task
    return maneuver_objective(_WORKER["env"], PIDGains.from_vector(genes), maneuvers, objective)


class Evaluator:
    """Evaluates gain vectors on a set of maneuvers, in this process or on ``executor`` (any
    :class:`concurrent.futures.Executor` whose workers ran :func:`init_worker` with the same
    env; the caller owns its lifetime)."""

    def __init__(self, env_id: str, env_kwargs: dict[str, Any] | None = None, executor: Executor | None = None) -> None:
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs or {})
        self.executor = executor
        self.env = gym.make(env_id, **self.env_kwargs).unwrapped  # validates the env here, and serves no executor

    def evaluate(self, genes: np.ndarray, maneuvers: list[dict], objective: str) -> np.ndarray:
        tasks = [(np.asarray(g, dtype=float), maneuvers, objective) for g in genes]
        if self.executor is None:
            return np.array(
                [maneuver_objective(self.env, PIDGains.from_vector(t[0]), maneuvers, objective) for t in tasks]
            )
        return np.array(list(self.executor.map(_worker_eval, tasks)))


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
