"""Report figures (PNG, matplotlib on the Agg backend) and the episode video: J per agent with
its CI, agent × fault heatmaps, example time histories re-run from the campaign's own jobs."""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import RecordVideo

from attitude_envs import quaternion
from attitude_envs.evaluation.trace import play, record_episode, record_state_trace
from attitude_envs.info import TRUTH, policy_view
from experiments.campaign.jobs import episode_jobs
from experiments.policies import build_policy
from experiments.report.leaderboards import free_drift_agents, history_agents, is_oracle, learned_agents
from experiments.report.markdown import fmt
from experiments.report.statistics import finite_mean


def _plots():
    """:mod:`experiments.plots` (matplotlib.pyplot on the Agg backend), imported on first use."""
    from experiments import plots  # heavy: matplotlib.pyplot (~0.4 s) would slow every command of the CLI

    return plots


def plot_leaderboard(boards, path: str | Path) -> Path:
    """J mean per agent with 95 % CI bars, one panel per env × scenario × fault (log scale)."""
    plt = _plots().plt
    cells = list(boards)
    fig, axes = plt.subplots(len(cells), 1, figsize=(7.5, 2.4 * len(cells) + 0.6), squeeze=False)
    for ax, cell in zip(axes[:, 0], cells, strict=True):
        board = [e for e in boards[cell] if not is_oracle(e)]
        names = [e["agent"] for e in board]
        mean = np.array([e["J_mean"] for e in board])
        err = np.array([[e["J_mean"] - e["J_ci_low"], e["J_ci_high"] - e["J_mean"]] for e in board]).T
        ax.barh(names, mean, xerr=np.nan_to_num(err), color="tab:blue", alpha=0.8, capsize=3)
        ax.set_xscale("log")
        ax.invert_yaxis()
        ax.set_title(" · ".join(cell), fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
    axes[-1, 0].set_xlabel("episode cost J (mean, 95 % bootstrap CI)")
    fig.tight_layout()
    return _save(fig, path)


def plot_fault_heatmap(rows: Sequence[Mapping[str, Any]], env: str, path: str | Path) -> Path | None:
    """Agent × fault heatmap of mean J (colour: log10), for one env; None with a single fault case."""
    rs = [r for r in rows if r["env"] == env]
    faults = list(dict.fromkeys(r["fault"] for r in rs))
    if len(faults) < 2:
        return None
    plt = _plots().plt
    agents = list(dict.fromkeys(r["agent"] for r in rs))
    grid = np.array(
        [[finite_mean([r["J"] for r in rs if r["agent"] == a and r["fault"] == f]) for f in faults] for a in agents]
    )
    fig, ax = plt.subplots(figsize=(1.6 * len(faults) + 3, 0.45 * len(agents) + 1.6))
    im = ax.imshow(np.log10(grid), aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(faults)), faults, rotation=20, ha="right")
    ax.set_yticks(range(len(agents)), agents)
    for i in range(len(agents)):
        for j in range(len(faults)):
            ax.text(j, i, fmt(float(grid[i, j])), ha="center", va="center", color="w", fontsize=8)
    fig.colorbar(im, ax=ax, label="log10 mean J")
    ax.set_title(f"{env}: mean J per agent and fault")
    fig.tight_layout()
    return _save(fig, path)


def _save(fig, path: str | Path) -> Path:
    return _plots().save_figure(fig, path, dpi=100)


def _job_for(jobs: Sequence[dict], cell: tuple[str, str, str], agent: str, seed: int | None = None) -> dict | None:
    """The first episode job of ``agent`` in ``cell`` (env, scenario, fault), on ``seed`` when given."""
    return next(
        (
            j
            for j in jobs
            if (j["key"]["env"], j["key"]["scenario"], j["key"]["fault"], j["key"]["agent"]) == (*cell, agent)
            and (seed is None or int(j["key"]["seed"]) == seed)
        ),
        None,
    )


def _example_traces(result, env_spec, scenario: dict, fault: str, agents: Sequence[str], record=record_episode) -> dict:
    """Re-run seed ``campaign.seeds[0]`` of ``agents`` (first training seed) and record their
    traces with ``record`` (:func:`record_episode` for wheel envs, :func:`record_state_trace` for any)."""
    jobs = episode_jobs(result.campaign, result.out_dir, skip_agents=result.skipped_agents)
    traces = {}
    for agent in agents:
        job = _job_for(jobs, (env_spec.name, scenario["name"], fault), agent)
        if job is None:
            continue
        env = gym.make(job["env_id"], **job["env_kwargs"])
        try:
            policy = build_policy(job["policy"], env, name=agent)
            traces[agent] = record(env, policy, seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
        finally:
            env.close()
    return traces


def _boresight_figure(result, env_spec, cell: tuple[str, str, str], board, out_dir: Path) -> str | None:
    """The star tracker boresight's path on the sphere around the keep-out cones, for every agent
    of a constrained ``cell`` (free drift left out; trained agents' first training seed), on the
    cell's first seed on which some agent enters a cone, else violates another constraint, else
    on its first seed. Returns
    the figure's path relative to ``out_dir``, None for an env without cones."""
    from attitude_envs.envs.constrained_slew import CONE_KINDS

    env_name, scenario, fault = cell
    rows = [r for r in result.rows if (r["env"], r["scenario"], r["fault"]) == cell]
    if not rows or not any("violations" in r for r in rows):
        return None
    seeds = sorted({int(r["seed"]) for r in rows})
    inside = sorted({int(r["seed"]) for r in rows if float(r.get("min_margin_deg", "nan") or "nan") < 0.0})
    violated = sorted({int(r["seed"]) for r in rows if float(r.get("violations") or 0) > 0})
    seed = (inside or violated or seeds)[0]
    drift = free_drift_agents(result.campaign)
    agents = [e["agent"] for e in board if not is_oracle(e) and e["agent"] not in drift]
    jobs = episode_jobs(result.campaign, result.out_dir, skip_agents=result.skipped_agents)
    paths, cones = {}, []
    for agent in agents:
        job = _job_for(jobs, cell, agent, seed)
        if job is None:
            continue
        env = gym.make(job["env_id"], **job["env_kwargs"])
        try:
            base = env.unwrapped
            boresight = base.boresights[CONE_KINDS[0][1]]
            policy = build_policy(job["policy"], env, name=agent)
            infos, _, _ = play(env, policy, seed, copy.deepcopy(job["options"]) or None)  # as the campaign's episode
            track = [quaternion.to_matrix(i[TRUTH]["state"]["attitude"]) @ boresight for i in infos]
            paths[f"{agent} ({int(infos[-1]['violations'])} violating steps)"] = np.array(track)
            if not cones:
                cones = [
                    (c.inertial_direction, c.half_angle_deg, c.name)
                    for c in base.cones
                    if np.allclose(c.body_axis, boresight)
                ]
        finally:
            env.close()
    if not paths:
        return None
    name = f"figures/boresight-{env_name}-{scenario}-{fault}.png"
    title = f"{env_name} · {scenario} · {fault} · seed {seed}: star tracker boresight around its keep-out cones"
    _plots().plot_boresight_paths(paths, cones, out_dir / name, title=title)
    return name


def _record_video(result, env_spec, agent: str, path_dir: Path) -> Path | None:
    """An episode of ``agent`` through gymnasium's ``RecordVideo`` (None when moviepy is missing)."""
    try:
        import moviepy  # noqa: F401  (optional: the video extra; RecordVideo needs it)
    except ImportError:
        return None
    job = next(
        j
        for j in episode_jobs(result.campaign, result.out_dir, skip_agents=result.skipped_agents)
        if j["key"]["env"] == env_spec.name and j["key"]["agent"] == agent
    )
    base = gym.make(job["env_id"], render_mode="rgb_array", **job["env_kwargs"])
    policy = build_policy(job["policy"], base, name=agent)
    prefix = f"{env_spec.name}-{agent}"
    env = RecordVideo(base, str(path_dir), name_prefix=prefix, episode_trigger=lambda e: e == 0, disable_logger=True)
    obs, info = env.reset(seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    policy.reset(job["key"]["seed"])
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        done = terminated or truncated
    env.close()
    videos = sorted(Path(path_dir).glob(f"{prefix}-episode-0.mp4"))
    return videos[0] if videos else None


def campaign_figures(
    result, boards: Mapping[tuple[str, str, str], list[dict[str, Any]]], out_dir: Path, video: bool
) -> tuple[dict[str, str], list[str]]:
    """Every figure of a campaign report, drawn under ``out_dir``: the J-with-CI plot, per env its
    fault heatmap, per cell the time histories of its best analytic controller and best learned
    agent, and (wheel envs, ``video``, with moviepy) an episode video of the env's best agent.
    Returns caption → path relative to ``out_dir``, and the notes on what was not drawn."""
    rows = result.rows
    figures: dict[str, str] = {}
    notes: list[str] = []
    plot_leaderboard(boards, out_dir / "figures" / "leaderboard.png")
    figures["J per agent (mean, 95 % CI)"] = "figures/leaderboard.png"
    for env_spec in result.campaign.envs:
        heat = plot_fault_heatmap(rows, env_spec.name, out_dir / "figures" / f"faults-{env_spec.name}.png")
        if heat is not None:
            figures[f"{env_spec.name}: fault campaign"] = f"figures/faults-{env_spec.name}.png"
        cell = next((c for c in boards if c[0] == env_spec.name), None)
        if cell is None:
            continue
        probe = gym.make(env_spec.id, **env_spec.kwargs)
        is_rw = probe.unwrapped.wheel_trace
        probe.close()
        best = boards[cell][0]["agent"]
        for scenario in env_spec.scenarios:  # every cell: its best analytic controller and best learned agent
            for fault in env_spec.faults:
                board = boards.get((env_spec.name, scenario["name"], fault), [])
                agents = history_agents(board, learned_agents(result.campaign), free_drift_agents(result.campaign))
                if not agents:
                    continue
                record = record_episode if is_rw else record_state_trace
                traces = _example_traces(result, env_spec, scenario, fault, agents, record)
                if not traces:
                    continue
                name = f"figures/history-{env_spec.name}-{scenario['name']}-{fault}.png"
                plot = _plots().plot_episodes if is_rw else _plots().plot_state_histories
                plot(
                    traces,
                    out_dir / name,
                    title=f"{env_spec.name} · {scenario['name']} · {fault} · seed {result.campaign.seeds[0]}",
                )
                label = f"{env_spec.name}: time histories, best analytic vs best learned ({scenario['name']}, {fault})"
                figures[label] = name
                cell = (env_spec.name, scenario["name"], fault)
                boresight = _boresight_figure(result, env_spec, cell, board, out_dir)
                if boresight is not None:
                    figures[f"{env_spec.name}: the star tracker's boresight around the keep-out cones ({fault})"] = (
                        boresight
                    )
        if is_rw:
            if video:
                path = _record_video(result, env_spec, best, out_dir / "videos")
                if path is not None:
                    figures[f"{env_spec.name}: episode video of the best agent ({best})"] = f"videos/{path.name}"
                else:
                    notes.append("no episode video: gymnasium's RecordVideo needs the optional package moviepy")
            else:
                notes.append(
                    "episode videos off for this campaign (video: false; rendering a 60 s episode takes minutes)"
                )
    return figures, notes
