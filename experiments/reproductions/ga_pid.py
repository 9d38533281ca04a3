"""Reproduction of Ahangarani Farahani et al. (GA-tuned state-dependent PID on an air-bearing
simulator).

``python train.py reproduce ga-pid --out DIR`` runs the laboratory test of eq. 25 on
AirBearing-v0 — [φ, θ, ψ] = [10, −10, 10]°, ω = [1, 1, 0] °/s, regulated to zero (assumed: the
paper states neither the setpoint nor the rates' units) —
and writes ``DIR/ga-pid.{json,md}`` and the gains it tuned, ``DIR/ga-pid-gains-*.json``.

Cases: nominal plant over 20 s (the paper's simulation horizon; assumed: the lab test's
duration is not given) and a constant disturbance of 0.01 N·m per axis over 60 s (assumed:
the paper never quantifies its disturbance). Controllers: the fixed PD of Table 3, the
state-dependent PID of eq. 24 with the schedule in rad (default) and in deg (the paper does
not state the units of its arguments), and our own
GA pipeline (:mod:`agents.ga_tuning`): constant gains tuned on the lab maneuver (Table 2
settings) and a meta-model schedule fitted on GA-optimal gains of random maneuvers.

Table 4 is a hardware result: its rows carry a null tolerance, except the fixed-PID yaw IAE,
which an ideal simulation reproduces (an independent one gives 45.2 vs the paper's 47.4):
claimed within 5 %.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.ga_tuning import (
    LAB_MANEUVER,
    GAConfig,
    build_schedule,
    pid_episode,
    sample_maneuvers,
    tune_gains,
)
from baselines.pid import PAPER_FIXED, PIDPolicy, paper_schedule
from experiments.pid_tuning import evaluator
from experiments.reproduction import Row, write_reproduction

PAPER = "ga-pid"
#: the reproduced paper's citation, on the outputs' "Source:" line
SOURCE = (
    "Ahangarani Farahani, A., Adami, A. and Arefkhani, H. (year and journal not in our copy). Laboratory "
    "test of a nonlinear attitude-control algorithm for a satellite simulator based on gain coefficients "
    "dependent on the state variables (in Persian; title translated)"
)
ENV_ID = "attitude_envs/AirBearing-v0"
AXES = ("x", "y", "z")

#: Table 4 (decimals and columns decoded from our garbled copy; the printed improvements
#: 30/47/29 % confirm it): IAE per axis, deg·s.
TABLE_4 = {"proposed": (54.93, 30.83, 33.51), "fixed": (78.79, 57.96, 47.4)}
TABLE_4_IMPROVEMENT_PCT = (30.0, 47.0, 29.0)

CASES = {
    "lab, Td = 0, 20 s": {"episode_duration_s": 20.0},
    "lab, Td = 0.01 N·m/axis, 60 s": {
        "episode_duration_s": 60.0,
        "disturbance": {"kind": "constant", "torque_nm": [0.01, 0.01, 0.01]},
    },
}
NOMINAL = "lab, Td = 0, 20 s"

#: Budget of the meta-model step (the paper gives neither N nor ranges). The full run
#: uses Table 2's population but fewer generations per maneuver than Table 2's 50 (time).
FULL_BUDGET = {"fixed": GAConfig(), "schedule": GAConfig(generations=20), "maneuvers": 8}
QUICK_BUDGET = {
    "fixed": GAConfig(population=3, generations=1),
    "schedule": GAConfig(population=3, generations=1),
    "maneuvers": 3,
}


def lab_iae(gains, env_kwargs: dict) -> dict:
    """One lab-test episode of a PID with ``gains`` on AirBearing-v0 built with ``env_kwargs``."""
    env = gym.make(ENV_ID, **env_kwargs)
    try:
        return pid_episode(env, PIDPolicy(env, gains), seed=0, options=LAB_MANEUVER)
    finally:
        env.close()


def tune(out_dir: Path, quick: bool, workers: int = 2) -> dict:
    """Our GA pipeline on the nominal plant (20 s, IAE objective): constant gains on the lab
    maneuver, and a meta-model schedule (initial-state regressor, rad) on random maneuvers."""
    budget = QUICK_BUDGET if quick else FULL_BUDGET
    env_kwargs = dict(CASES[NOMINAL])
    with evaluator(ENV_ID, env_kwargs, workers=workers) as ev:
        fixed = tune_gains(ev, [{"seed": 0, "options": LAB_MANEUVER}], budget["fixed"], "iae")
        maneuvers = sample_maneuvers(ev.env, budget["maneuvers"], seed=1000)
        sched = build_schedule(ev, maneuvers, budget["schedule"], "iae", "initial", "rad")
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "ga-pid-gains-fixed.json").write_text(
        json.dumps({"gains": fixed.gains.to_dict(), "objective": fixed.objective, "history": fixed.history}, indent=2)
    )
    (out_dir / "ga-pid-gains-schedule.json").write_text(
        json.dumps(
            {
                "gains": sched.schedule.to_dict(),
                "residual_rms": sched.residual_rms.tolist(),
                "data_bank_genes": sched.genes.tolist(),
                "data_bank_initial_angles_rad": sched.angles_rad.tolist(),
                "data_bank_initial_rates_rad_s": sched.rates_rad_s.tolist(),
                "maneuvers": maneuvers,
            },
            indent=2,
        )
    )
    return {
        "ga-fixed": fixed.gains,
        "ga-schedule": sched.schedule,
        "_fixed": fixed,
        "_schedule": sched,
        "_budget": budget,
    }


def reproduce(out_dir: Path, quick: bool = False) -> list[Row]:
    out_dir = Path(out_dir)
    tuned = tune(out_dir, quick, workers=1 if quick else 2)
    controllers = {
        "fixed PD (Table 3)": PAPER_FIXED,
        "state-dependent, eq. 24 (rad)": paper_schedule("rad"),
        "state-dependent, eq. 24 (deg)": paper_schedule("deg"),
        "ours: GA fixed PID": tuned["ga-fixed"],
        "ours: GA + meta-model": tuned["ga-schedule"],
    }
    paper_of = {"fixed PD (Table 3)": TABLE_4["fixed"], "state-dependent, eq. 24 (rad)": TABLE_4["proposed"]}
    rows: list[Row] = []
    results: dict[tuple[str, str], dict] = {}
    for case, kwargs in CASES.items():
        for name, gains in controllers.items():
            r = lab_iae(gains, kwargs)
            results[(case, name)] = r
            paper = paper_of.get(name)
            for i, axis in enumerate(AXES):
                tol = 0.05 if (case == NOMINAL and name == "fixed PD (Table 3)" and axis == "z") else None
                rows.append(
                    Row(case, name, f"IAE {axis} (deg·s)", None if paper is None else paper[i], r["iae_deg_s"][i], tol)
                )
            rows.append(Row(case, name, "peak body torque (N·m)", None, r["peak_motor_torque_nm"], None))
        for label, base, new, paper in (
            ("eq. 24 (rad) vs Table 3", "fixed PD (Table 3)", "state-dependent, eq. 24 (rad)", TABLE_4_IMPROVEMENT_PCT),
            ("ours: meta-model vs GA fixed", "ours: GA fixed PID", "ours: GA + meta-model", (None,) * 3),
        ):
            before, after = results[(case, base)]["iae_deg_s"], results[(case, new)]["iae_deg_s"]
            for i, axis in enumerate(AXES):
                improvement = 100.0 * (before[i] - after[i]) / before[i]
                rows.append(Row(case, label, f"improvement {axis} (%)", paper[i], improvement, None))
    notes = _notes(results, tuned, quick)
    write_reproduction(out_dir, PAPER, SOURCE, rows, notes)
    return rows


def _improvement(results: dict, case: str, name: str, base: str = "fixed PD (Table 3)") -> np.ndarray:
    fixed = results[(case, base)]["iae_deg_s"]
    return 100.0 * (fixed - results[(case, name)]["iae_deg_s"]) / fixed


def _notes(results: dict, tuned: dict, quick: bool) -> str:
    lines = []
    if quick:
        lines.append(
            "QUICK RUN: the GA budget is tiny (population 3, 1 generation, 3 maneuvers); its rows mean nothing."
        )
    ours_nominal = _improvement(results, NOMINAL, "ours: GA + meta-model", "ours: GA fixed PID")
    nominal = _improvement(results, NOMINAL, "state-dependent, eq. 24 (rad)")
    disturbed_case = "lab, Td = 0.01 N·m/axis, 60 s"
    disturbed = _improvement(results, disturbed_case, "state-dependent, eq. 24 (rad)")
    fmt = ", ".join
    sched = tuned["_schedule"]
    kp, kd, _ = paper_schedule("deg").at(np.radians([10.0, -10.0, 10.0]), np.radians([1.0, 1.0, 0.0]))
    lines += [
        "Setup: AirBearing-v0 (Table 1 inertia as the full tensor, offset torque m g r_s = [0.0014, 1.025e-4, 0.3366] "
        "N·m, 3 orthogonal wheels saturating at 0.8 N·m per axis, control and RK4 at 0.01 s), lab test of eq. 25 "
        "regulated to zero; IAE = ∫|e| dt of the 3-2-1 Euler-angle errors in deg·s (eq. 26), trapezoid over the "
        "control samples. Gains in SI with errors in rad (assumed: the paper states no units; with errors in deg "
        "Table 3's gains would demand about 26 N·m).",
        "",
        "Table 4 is a hardware (LabVIEW) test with unknown duration and unmodelled disturbances: only the fixed-PID "
        "yaw IAE is claimed (5 %), as an independent ideal simulation (45.2 deg·s) predicts; the other rows carry "
        "no tolerance.",
        "",
        f"'Up to 30 % better' in simulation: eq. 24 (rad) vs Table 3, IAE improvement per axis x/y/z = "
        f"{fmt(f'{v:.0f} %' for v in nominal)} without disturbance (20 s) and "
        f"{fmt(f'{v:.0f} %' for v in disturbed)} with 0.01 N·m/axis (60 s) (paper: 30 / 47 / 29 %). "
        + _verdict(nominal, disturbed),
        "",
        "eq. 24 with the schedule in deg (the other reading of the unstated units) moves the gains far from k1: at the lab initial state "
        f"Kd_θ = {kd[1]:.3f} (k1 = 4.22) and Kp_φ = {kp[0]:.2f} (k1 = 4.07) (IAE x/y/z nominal: {fmt(f'{v:.1f}' for v in results[(NOMINAL, 'state-dependent, eq. 24 (deg)')]['iae_deg_s'])} "
        f"deg·s; peak wheel torque {results[(NOMINAL, 'state-dependent, eq. 24 (deg)')]['peak_motor_torque_nm']:.3f} "
        "of 0.8 N·m).",
        "",
        "Our GA pipeline (agents/ga_tuning.py, pygad, seeded): 'GA fixed PID' = population "
        f"{tuned['_budget']['fixed'].population}, {tuned['_budget']['fixed'].generations} generations "
        f"({tuned['_fixed'].evaluations} distinct gain vectors evaluated), minimizing the sum of the three IAEs of the nominal lab test; best objective "
        f"{tuned['_fixed'].history[0]:.1f} in the initial population → {tuned['_fixed'].objective:.1f} deg·s. "
        f"'GA + meta-model' = one GA (population {tuned['_budget']['schedule'].population}, "
        f"{tuned['_budget']['schedule'].generations} generations) per maneuver on {len(tuned['_schedule'].genes)} random maneuvers "
        "(AirBearing-v0's start distribution: roll/pitch ±20°, yaw ±45°, rates ±2 °/s), least-squares fit of eq. 23 "
        "on the maneuvers' initial states (assumed: the paper's final states are all ≈ 0 in a regulation test), "
        "schedule in rad; residual RMS of the fit per gain (rows Kp, Kd, KI) "
        f"and axis: {np.round(sched.residual_rms, 3).tolist()}, R² of the fit: {np.round(_r2(sched), 2).tolist()} "
        "(R² near 0: the maneuver's initial state explains little of its GA-optimal gains). On the nominal lab test "
        f"our meta-model schedule vs our GA fixed PID: IAE improvement x/y/z = {fmt(f'{v:.0f} %' for v in ours_nominal)}"
        " (the fixed gains were tuned on this very maneuver; the schedule was fitted on other maneuvers).",
    ]
    return "\n".join(lines)


def _r2(sched) -> np.ndarray:
    """Coefficient of determination of the meta-model fit per gain (rows) and axis (columns)."""
    genes = sched.genes.reshape(len(sched.genes), 3, 3)  # [maneuver, axis, gain]
    var = genes.var(axis=0).T  # [gain, axis]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(var > 0, 1.0 - sched.residual_rms**2 / np.where(var > 0, var, 1.0), np.nan)


def _verdict(nominal: np.ndarray, disturbed: np.ndarray) -> str:
    def says(v: np.ndarray) -> str:
        better = [a for a, x in zip(AXES, v, strict=True) if x > 0]
        return f"better on {' and '.join(better) or 'no axis'}"

    return (
        f"So the claim does not hold as a whole in simulation: the scheduled PID is {says(nominal)} without "
        f"disturbance and {says(disturbed)} with it, while its lightly damped yaw channel (Kd_ψ = 2.8, "
        "ζ ≈ 0.3 on the linearized model) is worse in both."
        if nominal[2] < 0 and disturbed[2] < 0
        else f"Scheduled PID {says(nominal)} without disturbance and {says(disturbed)} with it."
    )
