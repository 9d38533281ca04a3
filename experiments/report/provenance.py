"""Where a report's results came from: the package version and git revision, each campaign
run (``runs.jsonl``), each trained agent's budget, task and chosen snapshot, and the
definitions of the campaign's envs, scenarios, faults and agent tasks."""

from __future__ import annotations

import json
import subprocess
import zipfile
from collections.abc import Mapping
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import gymnasium as gym

from experiments.campaign.episode import success_criterion
from experiments.campaign.jobs import episode_jobs
from experiments.machine_reference import REFERENCE_ENV
from experiments.report.leaderboards import campaign_thresholds
from experiments.report.markdown import env_label, fmt


def git_revision(root: str | Path | None = None) -> str:
    """``git rev-parse HEAD`` of the source tree (``"unknown"`` outside a checkout)."""
    root = Path(root or Path(__file__).resolve().parents[2])
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 else "unknown"


def package_version() -> str:
    """The installed attitude-envs version (``"unknown"`` when it is not installed)."""
    try:
        return importlib_metadata.version("attitude-envs")
    except importlib_metadata.PackageNotFoundError:
        return "unknown"


def _training_runs(result, agent) -> list[Path]:
    """The run directories of a trained agent (one per training seed), sorted."""
    jobs = episode_jobs(result.campaign, result.out_dir)
    return sorted({Path(j["policy"]["model"]).parent.parent for j in jobs if j["key"]["agent"] == agent.name})


def _training_summary(result, agent) -> str:
    """A trained agent's budget (``config.json`` of each run) and the snapshot its episodes
    ran: ``best snapshot at N steps`` (per run, from ``best/best.json``; ``0 (the untrained
    policy)`` when training never beat it) or ``final snapshot``, with the validation J
    (the run's own eval episodes, their count and first seed, and the training env's own kwargs
    where the agent trains on other episodes than the cells') of the best and of the final policy."""
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
            validation.append(f"{fmt(j_best)}/{fmt(j_final)}")
    t = agent.train
    steps = ", ".join(map(str, sorted(budgets))) or t.get("timesteps", "file default")
    snapshot = f"best snapshot at {', '.join(best_steps)} steps" if best_steps else "final snapshot"
    if validation:
        n = ""
        if len(episodes) == 1 and None not in next(iter(episodes)):
            count, first = next(iter(episodes))
            n = f" ({count} episodes, seeds {first}+"
            n += f" of the training env {json.dumps(t['env_kwargs'])})" if t.get("env_kwargs") else ")"
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


def all_runs_summary(result) -> str:
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


def campaign_metadata(result, command: str | None = None) -> dict[str, Any]:
    """What a campaign report states of a :class:`~experiments.campaign.CampaignResult` beside
    its leaderboards: the campaign, ``command`` (the command line), package and git revision,
    seeds, executor, wall times (s), each trained agent's budget and task, the given models,
    success criteria and thresholds, the definitions of envs, scenarios, faults and agent tasks."""
    budget = {a.name: _training_summary(result, a) for a in result.campaign.agents if a.train is not None}
    tasks = {a.name: _training_task(result, a) for a in result.campaign.agents if a.train is not None}
    for a in result.campaign.agents:
        if a.models_of is not None:
            budget[a.name] = (
                f"the models {a.models_of} trained (its budget), played with params {json.dumps(a.spec.get('params') or {})}"
            )
            tasks[a.name] = tasks.get(a.models_of, "")
    models = {
        a.name: f"{a.spec['model']} ({snapshot_description(a.spec['model'])})"
        for a in result.campaign.agents
        if result.campaign.trained_by(a) is None
        and a.spec.get("policy") == "sb3"
        and a.name not in result.skipped_agents
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
        "episodes": len(result.rows),
        "wall_time_s": round(result.wall_time_s, 1),
        "wall_time_all_runs_s": all_runs_summary(result),
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
    if result.campaign.layers:
        metadata["layers"] = result.campaign.layers
    return metadata
