"""J* of ConstrainedSlew-v0's default episodes, and the env's baselines against it.

For each seed (``reset(seed=s)``, no options: the env's own slew and one to three drawn
keep-out cones) the ``optimum`` part solves

* **J*** (:func:`experiments.optimum.solve_episode`): the gyrostat problem with the cones, the
  body-rate and the wheel-speed limits as path constraints at every decision time
  (:mod:`attitude_envs.symbolic.constrained_slew`, with its back-off), warm-started from the
  CBF-filtered eigenaxis slew (registry ``eigenaxis+cbf``) rolled out on the same episode, and
  replays the optimal actions through the env, counting the violating steps (0 expected) and
  the least cone margin (deg);
* **J*_unc**: the plain ReactionWheel-v0 problem of the same episode
  (:func:`attitude_envs.symbolic.gyrostat.build_reaction_wheel`: no cone, no rate limit, no
  wheel-speed constraint, only the env's own tumble and wheel-stop rows) from the same warm
  start, its actions replayed through the env (its violations recorded too: how much the
  constraints cost).

The ``baselines`` part rolls out each of :data:`BASELINES` (registry names) on the same
seeds and records J, the violating steps, the violations by constraint, the least cone margin
(deg), the final error (deg), the wall and CPU time; the summary gives ΣJ/ΣJ* over the seeds that
both have.

Both parts write ``--out`` (JSON) after every seed and skip the seeds it already holds, so an
interrupted run resumes::

    python -m benchmarks.constrained_slew_optimum --part optimum --seeds 0-19
    python -m benchmarks.constrained_slew_optimum --part baselines --seeds 0-19

Requires CasADi and Clarabel (``pip install 'attitude-envs[optimal,safety]'``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the envs)
from attitude_envs.constraints import episode_summary
from attitude_envs.evaluation.trace import play
from attitude_envs.symbolic import problem_for
from attitude_envs.symbolic.gyrostat import build_reaction_wheel
from benchmarks.results_file import write_results
from experiments import optimum
from experiments.jsonable import json_ready
from experiments.policies import build_policy
from experiments.seeds import SYNTAX, seeds_arg

ENV = "ConstrainedSlew-v0"
#: the baselines evaluated against J* (registry names)
BASELINES = ("eigenaxis", "eigenaxis+cbf", "mpc-constrained")
#: the registry name of J*'s warm start
WARM_START = "eigenaxis+cbf"
DEFAULT_OUT = Path(__file__).parent / "results" / "constrained_slew_optimum.json"
LOAD_NOTE = (
    "timings taken on a 2-core machine shared with a long benchmark run (niced): "
    "wall times are upper bounds, not an idle machine's"
)


def _constraint_outcome(summary: dict[str, Any]) -> dict[str, Any]:
    """The record's constraint columns from :func:`attitude_envs.constraints.episode_summary`'s
    (its least margin is inf for an episode without cones, as the record has always kept it)."""
    prefix = "violations_"
    margin = float(summary["min_margin_deg"])
    return {
        "violations": int(summary["violations"]),
        "violations_by_constraint": {k[len(prefix) :]: int(v) for k, v in summary.items() if k.startswith(prefix)},
        "min_cone_margin_deg": margin if math.isfinite(margin) else math.inf,
    }


def rollout(env, policy, seed: int, options: dict | None = None) -> dict[str, Any]:
    """One closed-loop episode of ``policy`` from ``env.reset(seed=seed, options=options)``
    (:func:`attitude_envs.evaluation.trace.play`: the policy sees
    :func:`~attitude_envs.info.policy_view` of each info): its actions and the episode's J,
    violations, least cone margin (deg), final error (deg), wall time and this process's CPU
    time (s; on a shared machine the CPU time is the cost, the wall time also counts the waits)."""
    start, cpu_start = time.perf_counter(), time.process_time()
    infos, actions, terminated = play(env, policy, seed, options)
    return {
        "actions": np.array(actions),
        "J": float(sum(float(i["cost"]) for i in infos[1:])),
        **_constraint_outcome(episode_summary(infos)),
        **{k: float(v) for k, v in env.unwrapped.success_metric.measurements(infos[0], infos[-1]).items()},
        "terminated": terminated,
        "wall_s": time.perf_counter() - start,
        "cpu_s": time.process_time() - cpu_start,
    }


def replay(env, actions: np.ndarray, seed: int) -> dict[str, Any]:
    """The open-loop ``actions`` through the env from ``reset(seed=seed)``
    (:func:`experiments.optimum.replay_measured`): J, violations and the least cone margin (deg)."""
    r = optimum.replay_measured(env, actions, seed, None)
    return {"J": r.J, **_constraint_outcome(r.measurements), "terminated": r.terminated}


def solve_seed(seed: int, max_iter: int = 1000, tol: float = 1e-10) -> dict[str, Any]:
    """The ``optimum`` row of one seed (see the module)."""
    env = gym.make(f"attitude_envs/{ENV}")
    try:
        problem = problem_for(env, seed=seed)
        warm = rollout(env, build_policy({"policy": WARM_START}, env), seed)
        actions0 = np.zeros((problem.n_steps, problem.n_u))
        actions0[: len(warm["actions"])] = warm["actions"]
        r = optimum.solve_episode(ENV, {}, seed, None, warm_start=actions0, max_iter=max_iter, tol=tol, cache=False)
        constrained = replay(env, r.actions, seed)
        env.reset(seed=seed)
        plain = build_reaction_wheel(env.unwrapped)
        start = time.perf_counter()
        a_unc, j_unc_nlp, status_unc, it_unc, solve_unc = optimum.solve_problem(plain, actions0, max_iter, tol)
        total_unc = time.perf_counter() - start
        unconstrained = replay(env, np.clip(a_unc, plain.a_lb, plain.a_ub), seed)
        base = env.unwrapped
        cones = [{"name": c.name, "half_angle_deg": math.degrees(math.acos(c.cos_half_angle))} for c in base.cones]
    finally:
        env.close()
    return {
        "seed": seed,
        "cones": cones,
        "warm_start": {"policy": WARM_START, "J": warm["J"], "violations": warm["violations"]},
        "solved": r.solved,
        "status": r.status,
        "iterations": r.iterations,
        "J_star": r.j_star,
        "J_nlp": r.j_nlp,
        "violations": constrained["violations"],
        "violations_by_constraint": constrained["violations_by_constraint"],
        "min_cone_margin_deg": constrained["min_cone_margin_deg"],
        "terminated": constrained["terminated"],
        "solve_s": r.solve_s,
        "total_s": r.total_s,
        "unconstrained": {
            "solved": status_unc in optimum.SOLVED,
            "status": status_unc,
            "iterations": it_unc,
            "J_star_unc": unconstrained["J"],
            "J_nlp": j_unc_nlp,
            "violations": unconstrained["violations"],
            "violations_by_constraint": unconstrained["violations_by_constraint"],
            "min_cone_margin_deg": unconstrained["min_cone_margin_deg"],
            "solve_s": solve_unc,
            "total_s": total_unc,
        },
    }


def evaluate_seed(name: str, seed: int) -> dict[str, Any]:
    """The ``baselines`` row of one seed for the registry policy ``name`` (default parameters)."""
    env = gym.make(f"attitude_envs/{ENV}")
    try:
        policy = build_policy({"policy": name}, env)
        row = rollout(env, policy, seed)
    finally:
        env.close()
    row.pop("actions")
    row["seed"] = seed
    for attr in ("failures", "held_steps", "filtered_steps", "slack_steps"):
        if hasattr(policy, attr):
            row[attr] = int(getattr(policy, attr))
    times = getattr(policy, "solve_times_s", None)
    if times:
        row["solve_s_median"] = float(np.median(times))
        row["solve_s_max"] = float(np.max(times))
    return row


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def summary(data: dict[str, Any]) -> dict[str, Any]:
    """Per-part totals: J* solve successes, violations and times; per baseline ΣJ/ΣJ* over
    the seeds both hold (J* solved), violating episodes, violation steps, least margin."""
    opt = {int(k): v for k, v in data.get("optimum", {}).items()}
    solved = {s: r for s, r in opt.items() if r["solved"]}
    out: dict[str, Any] = {
        "optimum": {
            "seeds": len(opt),
            "solved": len(solved),
            "unconstrained_solved": sum(r["unconstrained"]["solved"] for r in opt.values()),
            "replay_violations": sum(r["violations"] for r in solved.values()),
            "sum_J_star": sum(r["J_star"] for r in solved.values()),
            "sum_J_star_unc": sum(r["unconstrained"]["J_star_unc"] for r in solved.values()),
            "solve_s_median": float(np.median([r["solve_s"] for r in opt.values()])) if opt else None,
            "solve_s_max": max((r["solve_s"] for r in opt.values()), default=None),
            "total_s_sum": sum(r["total_s"] for r in opt.values()),
        }
    }
    for name, rows in data.get("baselines", {}).items():
        rows = {int(k): v for k, v in rows.items()}
        both = [s for s in rows if s in solved]
        sum_j_star = sum(solved[s]["J_star"] for s in both)
        margins = [r["min_cone_margin_deg"] for r in rows.values() if r["min_cone_margin_deg"] is not None]
        out[name] = {
            "seeds": len(rows),
            "seeds_with_J_star": len(both),
            "sum_J_over_sum_J_star": sum(rows[s]["J"] for s in both) / sum_j_star if sum_j_star > 0 else None,
            "violating_episodes": sum(r["violations"] > 0 for r in rows.values()),
            "violation_steps": sum(r["violations"] for r in rows.values()),
            "min_cone_margin_deg": min(margins, default=None),
            "wall_s_mean": float(np.mean([r["wall_s"] for r in rows.values()])) if rows else None,
            "cpu_s_mean": float(np.mean(cpu)) if (cpu := [r["cpu_s"] for r in rows.values() if "cpu_s" in r]) else None,
        }
    return out


def _load(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    data = json.loads(path.read_text(encoding="utf-8"))
    return {k: data.get(k, {}) for k in ("optimum", "baselines")}


def _save(path: Path, data: dict[str, Any], argv: Sequence[str] | None) -> None:
    payload = {
        "env": ENV,
        "note": LOAD_NOTE,
        "optimum": data.get("optimum", {}),
        "baselines": data.get("baselines", {}),
        "summary": summary(data),
    }
    write_results(path, list(argv) if argv is not None else None, **_json(payload))


def _json(value: Any) -> Any:
    """``value`` as strict JSON: :func:`~experiments.jsonable.json_ready` with non-finite floats
    as None."""
    return json_ready(value, lambda v: _finite(v) if isinstance(v, float) else v)


def run(
    part: str,
    seeds: Sequence[int],
    out: Path,
    policies: Sequence[str] = BASELINES,
    argv: Sequence[str] | None = None,
    solve: Callable[[int], dict[str, Any]] = solve_seed,
    evaluate: Callable[[str, int], dict[str, Any]] = evaluate_seed,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Run ``part`` (``"optimum"`` or ``"baselines"``) on ``seeds``, skipping the seeds ``out``
    already holds and writing ``out`` after each new one; returns the data. ``solve`` and
    ``evaluate`` compute one row (replaceable in tests)."""
    data = _load(out)
    data.setdefault("optimum", {})
    data.setdefault("baselines", {})
    if part == "optimum":
        for seed in seeds:
            if str(seed) in data["optimum"]:
                continue
            row = solve(seed)
            data["optimum"][str(seed)] = _json(row)
            _save(out, data, argv)
            log(f"optimum seed {seed}: solved={row['solved']} J*={row['J_star']:.4g} violations={row['violations']}")
    elif part == "baselines":
        for name in policies:
            rows = data["baselines"].setdefault(name, {})
            for seed in seeds:
                if str(seed) in rows:
                    continue
                row = evaluate(name, seed)
                rows[str(seed)] = _json(row)
                _save(out, data, argv)
                log(f"{name} seed {seed}: J={row['J']:.4g} violations={row['violations']} wall={row['wall_s']:.1f}s")
    else:
        raise ValueError(f"part must be 'optimum' or 'baselines', got {part!r}")
    return data


def build_parser() -> argparse.ArgumentParser:
    """The script's options; ``--seeds`` in the suite's seed syntax (:mod:`experiments.seeds`)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("optimum", "baselines"), required=True)
    parser.add_argument("--seeds", type=seeds_arg, default="0-19", help=f"seeds: {SYNTAX} (default 0-19)")
    parser.add_argument("--policies", default=",".join(BASELINES), help="baselines part: registry names")
    parser.add_argument("--out", default=str(DEFAULT_OUT))
    return parser


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = build_parser().parse_args(argv)
    policies = [p for p in args.policies.split(",") if p]
    return run(args.part, args.seeds, Path(args.out), policies, argv)


if __name__ == "__main__":
    main()
