"""Running a campaign: :func:`prepare_campaign` checks everything before any work,
:func:`run_campaign` trains, resolves J*, runs the episodes not yet done and returns the rows."""

from __future__ import annotations

import contextlib
import copy
import json
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.evaluation.runner import write_json
from attitude_envs.files import atomic_write
from attitude_envs.info import TRUTH
from attitude_envs.make import make_checked
from experiments.campaign.episode import run_job
from experiments.campaign.executors import executor_name, make_executor, trains_with_sbx
from experiments.campaign.jobs import episode_jobs, key_of, training_jobs
from experiments.campaign.spec import AgentSpec, Campaign, EnvSpec, load_campaign, play_env, resumable
from experiments.campaign.store import (
    RUN_STATUSES,
    CampaignResult,
    ResultStore,
    RunLog,
    for_table,
    read_lines,
    read_runs,
)
from experiments.optimum_table import episode_specs, resolve
from experiments.policies import POLICIES, PolicyUnavailable, build_policy, import_target
from experiments.progress import Progress
from experiments.training.algorithm import algorithm_class


def _n_trained(trained: list[dict[str, Any]]) -> int:
    return sum(r["status"] == "trained" for r in trained)


def available(agent: AgentSpec) -> str | None:
    """None if the agent's code imports here, else the reason."""
    try:
        for target in POLICIES[agent.spec["policy"]].targets:
            import_target(target)
        if agent.train is not None:
            algorithm_class(agent.train["algo"], agent.train.get("backend", "sb3"))  # checks the name too
    except (PolicyUnavailable, ValueError) as exc:
        return str(exc)
    return None


def probe_models(campaign: Campaign, skipped: dict[str, str]) -> None:
    """Build every env × scenario × fault once and load every given (not campaign-trained) SB3
    model against its envs before any job runs, so bad env kwargs, faults or a model for
    another env fail at once with a one-line error."""
    for env in campaign.envs:
        for scenario in env.scenarios:
            for faults in env.faults.values():
                kwargs = {**env.kwargs, **dict(scenario.get("env_kwargs") or {})}
                if faults:
                    kwargs["faults"] = copy.deepcopy(faults)
                make_checked(env.id, **kwargs).close()
        for agent in campaign.agents_for(env):
            if agent.name not in skipped and (agent.env_id is not None or agent.env_kwargs):
                check_same_episodes(campaign, env, agent)
            if agent.name in skipped or agent.spec["policy"] != "sb3" or campaign.trained_by(agent) is not None:
                continue
            play_id, play_kwargs = play_env(agent, env.id, env.kwargs)
            instance = gym.make(play_id, **play_kwargs)
            try:
                build_policy(agent.spec, instance, name=agent.name)
            finally:
                instance.close()


def _episode_signature(env: gym.Env, seed: int, options: dict[str, Any] | None) -> tuple[np.ndarray, float]:
    """The true start state of episode ``seed`` and the episode's length (s, or model steps)."""
    _, info = env.reset(seed=seed, options=copy.deepcopy(options) or None)
    state = info[TRUTH]["state"]
    if isinstance(state, dict):
        state = np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in state.values()])
    base = env.unwrapped
    length = getattr(base, "episode_duration_s", None)
    if length is None:
        length = base.episode_steps * base.model.dt_s
    return np.ravel(np.asarray(state, dtype=float)), float(length)


def check_same_episodes(campaign: Campaign, env: EnvSpec, agent: AgentSpec) -> None:
    """``ValueError`` unless ``agent``'s own env (:func:`play_env`) plays ``env``'s episodes:
    the same true start state on the campaign's first seed and the same episode length in
    every scenario and fault (an agent's task may change how often it decides and what a
    limit crossing costs, never the episode it is scored on against the cell's J*)."""
    seed = campaign.seeds[0]
    for scenario in env.scenarios:
        for faults in env.faults.values():
            kwargs = {**env.kwargs, **dict(scenario.get("env_kwargs") or {})}
            if faults:
                kwargs["faults"] = copy.deepcopy(faults)
            play_id, play_kwargs = play_env(agent, env.id, kwargs)
            cell, own = make_checked(env.id, **kwargs), make_checked(play_id, **play_kwargs)
            try:
                options = scenario.get("options")
                (x0, t0), (x1, t1) = _episode_signature(cell, seed, options), _episode_signature(own, seed, options)
            finally:
                cell.close()
                own.close()
            if x0.shape != x1.shape or not np.array_equal(x0, x1) or t0 != t1:
                raise ValueError(
                    f"agent {agent.name!r} plays env {env.name!r} on {play_id} {play_kwargs}, whose episodes differ "
                    f"from the cell's (start state or length {t1:g} vs {t0:g}): set the episode's keywords "
                    f"(episode length, start) in envs[{env.name}].kwargs so both versions play the same episodes"
                )


def prepare_campaign(
    config: str | Path | dict,
    out_dir: str | Path,
    backend: str | None = None,
    say: Callable[[str], None] | None = None,
) -> tuple[Campaign, dict[str, str]]:
    """Everything checked before a campaign does any work (nothing is written): its definition,
    that ``out_dir`` holds no other campaign, that every non-optional agent can run here, and
    that every env, fault and given model builds. Returns the campaign and the skipped
    optional agents with their reasons."""
    campaign = load_campaign(config, backend)
    marker = Path(out_dir) / "campaign.json"
    if marker.is_file():
        previous = json.loads(marker.read_text(encoding="utf-8"))
        differs = resumable(previous, campaign)
        if differs is not None:
            raise ValueError(
                f"--out {str(out_dir)!r} holds results of a different campaign definition "
                f"({previous.get('name')!r}: {differs}); choose another --out or delete it"
            )
    skipped: dict[str, str] = {}
    for agent in campaign.agents:
        reason = available(agent)
        if reason is None and agent.models_of in skipped:  # its models are never trained
            reason = f"the agent whose models it plays ({agent.models_of}) is skipped"
        if reason is not None:
            if not agent.optional:
                raise ValueError(f"campaign {campaign.name!r}: agent {agent.name!r} cannot run: {reason}")
            skipped[agent.name] = reason
            if say is not None:
                say(f"skipping optional agent {agent.name}: {reason}")
    probe_models(campaign, skipped)
    return campaign, skipped


def run_campaign(
    config: str | Path | dict,
    out_dir: str | Path,
    ray_address: str | None = None,
    workers: int | None = None,
    progress: Callable[[str], None] | None = None,
    backend: str | None = None,
) -> CampaignResult:
    """Train what needs training, run every episode not yet in ``out_dir``, return all rows.
    ``backend`` overrides the training backend of every trained agent (:func:`load_campaign`)."""
    out_dir = Path(out_dir)
    say = progress or (lambda _msg: None)
    campaign, skipped = prepare_campaign(config, out_dir, backend, say)
    marker = out_dir / "campaign.json"
    recorded = json.loads(marker.read_text(encoding="utf-8")) if marker.is_file() else {}
    # every agent the folder ever recorded: one removed and then added back changed is refused
    agents = {**(recorded.get("parts") or {}).get("agents", {}), **campaign.parts["agents"]}
    atomic_write(
        marker,
        json.dumps(
            {
                "name": campaign.name,
                "fingerprint": campaign.fingerprint,
                "parts": {"setup": campaign.parts["setup"], "agents": agents},
                "source": campaign.source,
            }
        )
        + "\n",
    )
    log = RunLog(out_dir / "runs.jsonl", executor_name(ray_address, workers))  # first: a killed run leaves it
    trained: list[dict[str, Any]] = []
    todo: list[dict[str, Any]] = []
    ran, status, executor, sigint, store, optimum_notes = 0, "failed", None, None, None, []
    try:
        executor = make_executor(ray_address, workers, pin=trains_with_sbx(campaign))
        train_jobs = training_jobs(campaign, out_dir, skip_agents=skipped)
        if train_jobs:
            say(f"training {len(train_jobs)} agent run(s)")
            for job in train_jobs:  # each training reports its steps (status lines from the workers)
                job["progress"] = progress is not None and f"train {Path(job['out_dir']).relative_to(out_dir)}"
            with (
                Progress(len(train_jobs), "campaign training runs", "run", enabled=progress is not None) as bar,
                contextlib.closing(executor.map_unordered(run_job, train_jobs)) as results,
            ):
                for res in results:
                    trained.append(res)
                    bar.update()
                    log.progress()
                    say(f"  {res['status']}: {res['out_dir']}")
        store = ResultStore(out_dir)
        jobs = episode_jobs(campaign, out_dir, skip_agents=skipped)
        store.wanted = {key_of(j["key"]) for j in jobs}  # the table and the result: this definition's rows
        # J* once per episode key (not per agent): table, solver cache, else solved on the pool
        optimum_notes = resolve(
            episode_specs(jobs), store, executor, campaign.optimum_solve, campaign.optimum_table, progress
        )
        todo = [j for j in jobs if not store.done(j["key"])]
        say(f"{len(jobs)} episodes, {len(jobs) - len(todo)} already done, running {len(todo)} on {executor.name}")
        with (
            Progress(len(todo), "campaign episodes", "episode", enabled=progress is not None and bool(todo)) as bar,
            contextlib.closing(executor.map_unordered(run_job, todo)) as results,
        ):
            for row in results:
                store.append(row)
                bar.update()
                log.progress()
        if not todo:  # each append rewrote it; else an agent removed since leaves it here
            store.write_csv()
        status = "completed"
    except KeyboardInterrupt:
        status = "interrupted"
        with contextlib.suppress(ValueError):  # a second Ctrl-C must not cut the shutdown (main thread only)
            sigint = signal.signal(signal.SIGINT, signal.SIG_IGN)
        raise
    finally:
        if executor is not None:
            executor.close()
        if store is not None:  # from the log itself: exact also when an interrupt cut the bookkeeping
            ran = len(read_lines(store.log)) - store.logged_before
        counts = {"executor": executor.name if executor is not None else executor_name(ray_address, workers)}
        counts |= {"trained": _n_trained(trained), "episodes_run": ran, "completed": status == "completed"}
        elapsed = log.end(status, **counts)  # also when interrupted or failed: the report sums all runs
        if status == "interrupted" and sigint is not None:
            signal.signal(signal.SIGINT, sigint)
    rows = store.sorted_rows()
    write_json([for_table(r) for r in rows], out_dir / "episodes.json")
    past_runs = read_runs(out_dir / "runs.jsonl")
    return CampaignResult(
        campaign=campaign,
        out_dir=out_dir,
        rows=rows,
        trained=sorted(trained, key=lambda r: r["out_dir"]),
        skipped_agents=skipped,
        episodes_run=len(todo),
        episodes_skipped=len(jobs) - len(todo),
        wall_time_s=elapsed,
        executor=executor.name,
        total_wall_time_s=sum(r["wall_time_s"] for r in past_runs),
        runs=len(past_runs),
        run_statuses={s: n for s in RUN_STATUSES if (n := sum(r["status"] == s for r in past_runs))},
        run_log=past_runs,
        optimum_notes=optimum_notes,
    )
