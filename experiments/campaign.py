"""Benchmark campaigns: agents × envs × scenarios × faults × seeds, from one YAML file.

A campaign file (shipped presets: ``quick``, ``full`` in ``experiments/campaigns/``)::

    name: quick
    seeds: [0, 1, 2, 3, 4]            # evaluation episode seeds (>= 5 for the report's IQM)
    metrics: {settling_band_deg: 1.0}  # episode_metrics keyword arguments
    success_error_deg: 2.0            # success (attitude envs): finite J, not terminated, final error below this
    success_state_fraction: 0.1       # success (other envs): final state norm <= this × the initial one
    optimum: {solve: true}            # J* per episode: shipped table, solver cache, else solve (casadi)
    envs:
      - name: rw                       # short name used in tables and paths
        id: attitude_envs/ReactionWheel-v0
        kwargs: {preset: pyramid-4wheel}
        scenarios:                     # reset options / extra env kwargs
          - {name: random-60deg}
        faults:                        # name → fault list (attitude_envs.faults)
          none: []
          wheel0-outage-10s: [{kind: outage, target: actuator, index: 0, onset_s: 10.0}]
    agents:
      - {name: lqr, policy: lqr, params: {discretization: zoh}}
      - {name: q-lqr, policy: q-learning-lqr, optional: true, envs: [ls]}
      - name: ppo
        policy: sb3
        train: {algo: ppo, timesteps: 8000, seeds: [0], overrides: {n_envs: 2}}
        # evaluated with its best eval snapshot (train.select: best, the default) or final
      - {name: sac-pretrained, policy: sb3, model: path/to/model.zip}

Execution: SB3 agents with ``train`` are trained first (one job per agent × env × training
seed, resumed from its checkpoint if a previous run was killed, skipped when finished),
then every episode is one job. Jobs run on a local process pool (default) or on Ray
(``ray_address``: ``"local"`` starts a local instance; else a cluster address). Results are
appended episode by episode to ``episodes.jsonl`` (one fsynced line each) and ``episodes.csv``
is rewritten atomically, sorted by key, after every episode: a crash leaves a readable
partial table, and a rerun skips the episodes already done. Each run (finished or
interrupted) appends its wall time to ``runs.jsonl``; the report sums them. Episodes are deterministic
functions of their key, so the table does not depend on the executor or the worker count.

J*: before the episodes, each distinct episode key (env id, kwargs with faults, seed, reset
options; shared by all agents) gets its oracle optimum J* (:mod:`experiments.optimum_table`:
the shipped table, the solver's cache, else a solve job on the same pool when
``optimum.solve``), logged to ``optimum.jsonl`` (a rerun resumes it); rows carry ``j_star``,
``j_over_j_star`` = J / J* and ``j_star_source``.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import multiprocessing as mp
import os
import queue
import signal
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401  (registers the env ids, also in pool and Ray workers)
from attitude_envs.evaluation.metrics import episode_metrics, settling_time_s
from attitude_envs.evaluation.runner import write_csv, write_json
from attitude_envs.evaluation.trace import record_episode
from attitude_envs.info import policy_view
from attitude_envs.make import check_env_id, make_checked
from attitude_envs.plants.gyrostat_model import ReactionWheelModel
from experiments.processes import die_with_parent, pin_to_one_core, pool_context
from experiments.progress import Progress, status_interval_s
from experiments.machine_reference import reference_steps_per_s
from experiments.optimum_table import episode_specs, resolve, solve_by_default, solve_job
from experiments.policies import POLICIES, PolicyUnavailable, _import, build_policy, check_policy_name
from experiments.sb3.backends import check_backend
from experiments.sb3.hyperparams import load_hyperparams, read_yaml
from experiments.sb3.registry import algorithm_class, check_algorithm

KEY_COLUMNS = ("env", "scenario", "fault", "agent", "train_seed", "seed")
PLANT_CAMPAIGNS = ("wheel", "air-bearing", "magnetorquer", "slosh", "linear")  # `--config all`, in this order
PRESETS = ("quick", "full", *PLANT_CAMPAIGNS)
SELECT = ("best", "final")  # which snapshot of a trained agent is evaluated


# --------------------------------------------------------------------------- configuration


@dataclass(frozen=True)
class EnvSpec:
    name: str
    id: str
    kwargs: dict[str, Any]
    scenarios: list[dict[str, Any]]
    faults: dict[str, list[dict[str, Any]]]


@dataclass(frozen=True)
class AgentSpec:
    name: str
    spec: dict[str, Any]
    envs: list[str] | None
    optional: bool
    train: dict[str, Any] | None


@dataclass
class Campaign:
    name: str
    seeds: list[int]
    envs: list[EnvSpec]
    agents: list[AgentSpec]
    metrics: dict[str, Any] = field(default_factory=dict)
    success_error_deg: float = 2.0
    success_state_fraction: float = 0.1
    video: bool = False
    source: str = ""
    fingerprint: str = ""
    optimum_solve: bool = True  # solve J* on demand for episodes outside the shipped table (casadi)
    optimum_table: str | None = None  # a J* table in place of the shipped one (tests, private cells)

    def agents_for(self, env: EnvSpec) -> list[AgentSpec]:
        return [a for a in self.agents if a.envs is None or env.name in a.envs]


def preset_path(name: str) -> Path:
    """The shipped campaign file of preset ``name``."""
    return Path(str(resources.files("experiments") / "campaigns" / f"{name}.yml"))


def _require(cond: bool, message: str) -> None:
    if not cond:
        raise ValueError(message)


def _name(where: str, value: Any) -> str:
    _require(
        isinstance(value, str) and value and all(c.isalnum() or c in "-_." for c in value),
        f"{where} must be a non-empty name of letters, digits, '-', '_' or '.', got {value!r}",
    )
    return value


def _fraction(value: Any) -> float:
    _require(
        isinstance(value, int | float) and 0.0 < float(value) <= 1.0,
        f"success_state_fraction must be a number in (0, 1], got {value!r}",
    )
    return float(value)


def load_campaign(config: str | Path | dict, backend: str | None = None) -> Campaign:
    """A campaign from a preset name (:data:`PRESETS`), a YAML path or a dict; ``ValueError``
    naming the offending entry otherwise. ``backend`` (``sb3`` / ``sbx``) replaces every trained
    agent's ``train.backend`` (a different campaign: its own fingerprint)."""
    source = str(config) if not isinstance(config, dict) else "<dict>"
    if isinstance(config, str) and config in PRESETS:
        data = read_yaml(preset_path(config))
    elif isinstance(config, str | Path):
        path = Path(config)
        _require(
            path.suffix in (".yml", ".yaml") or path.is_file(),
            f"--config must be one of {list(PRESETS)} or a YAML file path, got {str(config)!r}"
            " (the command line also takes all: the plant campaigns)",
        )
        data = read_yaml(path)
    else:
        data = copy.deepcopy(config)
    _require(isinstance(data, dict), f"campaign {source!r} must be a mapping, got {type(data).__name__}")
    if backend is not None:
        for agent in data.get("agents") or []:
            if isinstance(agent, dict) and isinstance(agent.get("train"), dict):
                agent["train"]["backend"] = backend
    accepted = ["name", "description", "seeds", "envs", "agents", "metrics", "success_error_deg"]
    accepted += ["success_state_fraction", "video", "optimum"]
    unknown = set(data) - set(accepted)
    _require(not unknown, f"campaign has unknown keys {sorted(unknown)}; accepted: {accepted}")
    seeds = data.get("seeds", list(range(5)))
    if isinstance(seeds, int):
        seeds = list(range(seeds))
    _require(
        isinstance(seeds, list) and seeds and all(isinstance(s, int) and s >= 0 for s in seeds),
        f"seeds must be a non-empty list of integers >= 0 (or a count), got {seeds!r}",
    )
    _require(len(set(seeds)) == len(seeds), f"seeds must be distinct, got {seeds!r}")
    envs = []
    for i, e in enumerate(data.get("envs") or []):
        _require(isinstance(e, dict) and "id" in e, f"envs[{i}] must be a mapping with an 'id', got {e!r}")
        check_env_id(str(e["id"]))
        name = _name(f"envs[{i}].name", e.get("name", str(e["id"]).split("/")[-1]))
        scenarios = e.get("scenarios") or [{"name": "default"}]
        for j, s in enumerate(scenarios):
            _require(isinstance(s, dict), f"envs[{i}].scenarios[{j}] must be a mapping, got {s!r}")
            _name(f"envs[{i}].scenarios[{j}].name", s.get("name"))
            bad = set(s) - {"name", "options", "env_kwargs"}
            _require(
                not bad, f"envs[{i}].scenarios[{j}] has unknown keys {sorted(bad)}; accepted: name, options, env_kwargs"
            )
        faults = e.get("faults") or {"none": []}
        _require(isinstance(faults, dict), f"envs[{i}].faults must map names to fault lists, got {faults!r}")
        for fname, flist in faults.items():
            _name(f"envs[{i}].faults key", fname)
            _require(isinstance(flist, list), f"envs[{i}].faults.{fname} must be a list of fault dicts, got {flist!r}")
        envs.append(EnvSpec(name, str(e["id"]), dict(e.get("kwargs") or {}), list(scenarios), dict(faults)))
    _require(bool(envs), "campaign needs at least one entry under envs")
    _require(len({e.name for e in envs}) == len(envs), "env names must be distinct")
    agents = []
    for i, a in enumerate(data.get("agents") or []):
        _require(isinstance(a, dict) and "policy" in a, f"agents[{i}] must be a mapping with a 'policy', got {a!r}")
        name = _name(f"agents[{i}].name", a.get("name", a["policy"]))
        check_policy_name(str(a["policy"]))
        train = a.get("train")
        if train is not None:
            _require(a["policy"] == "sb3", f"agents[{i}] ({name}): train is only for policy sb3")
            _require(isinstance(train, dict) and "algo" in train, f"agents[{i}].train needs an algo, got {train!r}")
            check_backend(train.get("backend", "sb3"), check_algorithm(train["algo"]))
            tseeds = train.get("seeds", [0])
            _require(
                isinstance(tseeds, list) and tseeds and all(isinstance(s, int) and s >= 0 for s in tseeds),
                f"agents[{i}].train.seeds must be a non-empty list of integers >= 0, got {tseeds!r}",
            )
            select = train.get("select", "best")
            _require(
                select in SELECT,
                f"agents[{i}].train.select must be one of {list(SELECT)}, got {select!r}",
            )
        elif a["policy"] == "sb3":
            _require("model" in a, f"agents[{i}] ({name}): policy sb3 needs model: PATH or train: {{algo: ...}}")
        only = a.get("envs")
        if only is not None:
            unknown_envs = set(only) - {e.name for e in envs}
            _require(
                not unknown_envs,
                f"agents[{i}].envs names unknown envs {sorted(unknown_envs)}; accepted: {[e.name for e in envs]}",
            )
        spec = {k: v for k, v in a.items() if k not in ("envs", "optional", "train")}
        agents.append(AgentSpec(name, spec, only, bool(a.get("optional", False)), train))
    _require(bool(agents), "campaign needs at least one entry under agents")
    _require(len({a.name for a in agents}) == len(agents), "agent names must be distinct")
    opt = data.get("optimum") or {}
    _require(
        isinstance(opt, dict) and not set(opt) - {"solve", "table"},
        f"optimum must be a mapping with keys solve (true/false), table (a J* table path), got {opt!r}",
    )
    _require(isinstance(opt.get("solve", True), bool), f"optimum.solve must be true or false, got {opt.get('solve')!r}")
    return Campaign(
        name=_name("name", data.get("name", "campaign")),
        seeds=list(seeds),
        envs=envs,
        agents=agents,
        metrics=dict(data.get("metrics") or {}),
        success_error_deg=float(data.get("success_error_deg", 2.0)),
        success_state_fraction=_fraction(data.get("success_state_fraction", 0.1)),
        video=bool(data.get("video", False)),
        optimum_solve=bool(opt.get("solve", solve_by_default())),
        optimum_table=str(opt["table"]) if opt.get("table") is not None else None,
        source=source,
        fingerprint=hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16],
    )


# --------------------------------------------------------------------------- jobs


def _train_dir(out_dir: Path, env: str, agent: str, seed: int) -> Path:
    return out_dir / "models" / env / agent / f"seed{seed}"


def _trained_model(train_dir: Path, select: str) -> Path:
    """The snapshot a trained agent is evaluated with: ``best`` (lowest J on the training's
    own eval env, seeds 10000+, disjoint from the campaign's) when one was saved, else ``final``."""
    best = train_dir / "best" / "model.zip"
    return best if select == "best" and best.is_file() else train_dir / "final" / "model.zip"


def _backend_override(train: dict[str, Any]) -> dict[str, Any]:
    """``train.backend`` of an agent as a hyperparameter override (absent: the entry's own)."""
    return {"backend": train["backend"]} if "backend" in train else {}


def training_jobs(campaign: Campaign, out_dir: Path, skip_agents: Iterable[str] = ()) -> list[dict[str, Any]]:
    """One job per SB3 agent with ``train`` × env × training seed."""
    skip = set(skip_agents)
    jobs = []
    for env in campaign.envs:
        for agent in campaign.agents_for(env):
            if agent.train is None or agent.name in skip:
                continue
            t = agent.train
            for seed in t.get("seeds", [0]):
                jobs.append(
                    {
                        "kind": "train",
                        "algo": t["algo"],
                        "env_id": env.id,
                        "env_kwargs": {**env.kwargs, **dict(t.get("env_kwargs") or {})},
                        "seed": int(seed),
                        "timesteps": t.get("timesteps"),
                        "overrides": {**dict(t.get("overrides") or {}), **_backend_override(t)},
                        "hyperparams_file": t.get("hyperparams_file"),
                        "checkpoint_freq": int(t.get("checkpoint_freq", 10_000)),
                        "eval_freq": int(t.get("eval_freq", 10_000)),
                        "out_dir": str(_train_dir(out_dir, env.name, agent.name, seed)),
                    }
                )
    return jobs


def episode_jobs(campaign: Campaign, out_dir: Path, skip_agents: Iterable[str] = ()) -> list[dict[str, Any]]:
    """One job per env × scenario × fault × agent (× training seed) × seed, in key order."""
    skip = set(skip_agents)
    jobs = []
    for env in campaign.envs:
        for scenario in env.scenarios:
            for fault_name, faults in env.faults.items():
                kwargs = {**env.kwargs, **dict(scenario.get("env_kwargs") or {})}
                if faults:
                    kwargs["faults"] = copy.deepcopy(faults)
                for agent in campaign.agents_for(env):
                    if agent.name in skip:
                        continue
                    train_seeds = agent.train.get("seeds", [0]) if agent.train else [None]
                    for tseed in train_seeds:
                        spec = dict(agent.spec)
                        if tseed is not None:
                            train_dir = _train_dir(out_dir, env.name, agent.name, tseed)
                            spec["model"] = str(_trained_model(train_dir, agent.train.get("select", "best")))
                        for seed in campaign.seeds:
                            key = {
                                "env": env.name,
                                "scenario": scenario["name"],
                                "fault": fault_name,
                                "agent": agent.name,
                                "train_seed": tseed,
                                "seed": int(seed),
                            }
                            jobs.append(
                                {
                                    "kind": "episode",
                                    "key": key,
                                    "env_id": env.id,
                                    "env_kwargs": kwargs,
                                    "options": dict(scenario.get("options") or {}),
                                    "policy": spec,
                                    "metrics": dict(campaign.metrics),
                                    "success_error_deg": campaign.success_error_deg,
                                    "success_state_fraction": campaign.success_state_fraction,
                                }
                            )
    return jobs


def key_of(row: dict[str, Any]) -> tuple:
    return tuple(row.get(k) for k in KEY_COLUMNS)


def _sort_key(key: tuple) -> tuple:
    return tuple((v is None, v if v is not None else 0) if not isinstance(v, str) else (False, v) for v in key)


# --------------------------------------------------------------------------- workers

_CACHE: dict[str, tuple[Any, Any]] = {}


def _fault_onset_s(faults: list[dict[str, Any]], env) -> float | None:
    """Earliest onset of the episode's faults as realized (drawn onsets included), s; None without faults."""
    if not faults:
        return None
    layer = getattr(env.unwrapped, "_faults", None)  # the env's ActuatorFaults: its realized draws
    realized = layer.info(0.0) if layer is not None else faults
    onsets = [float(f.get("onset_s") or 0.0) for f in realized if isinstance(f.get("onset_s", 0.0), int | float | None)]
    return min(onsets) if onsets else None


def run_job(job: dict[str, Any]) -> dict[str, Any]:
    """Run one job (``kind`` ``train``, ``optimum`` or ``episode``) in this process; returns its result row."""
    if job["kind"] == "optimum":  # J* of one episode key (experiments.optimum_table)
        return solve_job(job)
    if job["kind"] == "train" or job.get("policy", {}).get("policy") == "sb3":
        import torch  # only for jobs that need it: importing torch costs seconds per worker

        torch.set_num_threads(1)  # episodes and small networks: threads only contend
    if job["kind"] == "train":
        return _run_training(job)
    return _run_episode(job)


def _run_training(job: dict[str, Any]) -> dict[str, Any]:
    # optional: the sb3 extra (importing stable-baselines3 and torch costs seconds; episode workers skip it)
    from experiments.sb3.checkpoint import latest_checkpoint
    from experiments.sb3.training import train

    out_dir = Path(job["out_dir"])
    final = out_dir / "final" / "model.zip"
    if final.is_file():
        return {"kind": "train", "out_dir": str(out_dir), "status": "done-before"}
    result = train(
        job["algo"],
        job["env_id"],
        out_dir,
        env_kwargs=job["env_kwargs"],
        seed=job["seed"],
        hyperparams_file=job["hyperparams_file"],
        overrides=job["overrides"],
        total_timesteps=job["timesteps"],
        checkpoint_freq=job["checkpoint_freq"],
        eval_freq=job["eval_freq"],
        resume=latest_checkpoint(out_dir) is not None,
        progress=job.get("progress", False),
    )
    return {
        "kind": "train",
        "out_dir": str(out_dir),
        "status": "trained",
        "timesteps": result.timesteps,
        "wall_time_s": result.wall_time_s,
        "J_eval": (result.last_eval or {}).get("J_mean"),
    }


def _env_and_policy(job: dict[str, Any]):
    group = json.dumps(
        [job["env_id"], job["env_kwargs"], job["policy"], job["key"]["agent"]], sort_keys=True, default=str
    )
    if group not in _CACHE:
        for old in list(_CACHE)[:-3]:
            _CACHE.pop(old)[0].close()
        env = gym.make(job["env_id"], **job["env_kwargs"])
        _CACHE[group] = (env, build_policy(job["policy"], env, name=job["key"]["agent"]))
    return _CACHE[group]


def _run_episode(job: dict[str, Any]) -> dict[str, Any]:
    env, policy = _env_and_policy(job)
    key = job["key"]
    start = time.perf_counter()
    if isinstance(getattr(env.unwrapped, "model", None), ReactionWheelModel):
        metrics = _attitude_metrics(env, policy, job)
    else:
        metrics = _generic_metrics(env, policy, job)
    metrics["episode_wall_s"] = time.perf_counter() - start
    return {**key, **{k: (v.item() if isinstance(v, np.generic) else v) for k, v in metrics.items()}}


def _attitude_metrics(env, policy, job: dict[str, Any]) -> dict[str, Any]:
    trace = record_episode(env, policy, seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    m = episode_metrics(trace, **job["metrics"])
    final_error = float(trace.error_angle_deg[-1])
    m["final_error_deg"] = final_error
    m["success"] = bool(np.isfinite(m["J"]) and not trace.terminated and final_error <= job["success_error_deg"])
    onset = _fault_onset_s(job["env_kwargs"].get("faults") or [], env)
    if onset is not None:
        band = float(job["metrics"].get("settling_band_deg", 1.0))
        after = trace.time_s >= onset
        t_settle = settling_time_s(trace.time_s[after], trace.error_angle_deg[after], band) if after.any() else np.nan
        m["recovery_time_s"] = float(t_settle - onset) if np.isfinite(t_settle) else float("nan")
    else:
        m["recovery_time_s"] = float("nan")
    return m


def _state_norm(info: dict[str, Any]) -> float:
    """Norm of the true state the cost weighs: ``truth["x"]`` where the env has one (FuelSlosh-v0's
    reduced states), else ``truth["state"]`` (an array, or a mapping of arrays, flattened)."""
    truth = info["truth"]
    state = truth["x"] if "x" in truth else truth["state"]
    if isinstance(state, dict):
        state = np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in state.values()])
    return float(np.linalg.norm(np.asarray(state, dtype=float)))


def success_criterion(env_id: str, env_kwargs: dict[str, Any], campaign: Campaign) -> str:
    """The success criterion of an episode of ``env_id`` (as the report states it)."""
    env = gym.make(env_id, **env_kwargs)
    try:
        _, info = env.reset(seed=0)
        attitude = "error_angle_deg" in info["truth"]
    finally:
        env.close()
    if attitude:
        return f"final attitude error ≤ {campaign.success_error_deg:g}°, not terminated, J finite"
    return (
        f"final state norm ≤ {campaign.success_state_fraction:g} × the initial state norm (true state), "
        "not terminated, J finite"
    )


def _generic_metrics(env, policy, job: dict[str, Any]) -> dict[str, Any]:
    """Any env: J, and success by the final attitude error where the env reports one
    (``truth["error_angle_deg"]``), else by the final state norm relative to the initial one."""
    obs, info = env.reset(seed=job["key"]["seed"], options=copy.deepcopy(job["options"]) or None)
    policy.reset(job["key"]["seed"])
    initial = _state_norm(info)
    total, steps, terminated, truncated = 0.0, 0, False, False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        total += float(info["cost"])
        steps += 1
    final = _state_norm(info)
    ok = bool(np.isfinite(total) and not terminated)
    m = {"J": total, "steps": steps, "terminated": bool(terminated)}
    if "error_angle_deg" in info["truth"]:
        m["final_error_deg"] = float(info["truth"]["error_angle_deg"])
        ok = ok and m["final_error_deg"] <= job["success_error_deg"]
    else:
        ok = ok and final <= job.get("success_state_fraction", 0.1) * initial
    m |= {"initial_state_norm": initial, "final_state_norm": final, "success": ok, "recovery_time_s": float("nan")}
    return m


# --------------------------------------------------------------------------- executors


def _init_worker(parent_pid: int, counter) -> None:
    """Pool-worker initializer: Ctrl-C is the parent's and the worker dies with it
    (:func:`die_with_parent`); with a ``counter``, worker ``i`` runs on CPU ``i`` of the allowed
    ones (:func:`pin_to_one_core`: one JAX thread pool per worker, no contention between workers)."""
    die_with_parent(parent_pid)
    if counter is not None:
        with counter.get_lock():
            index = counter.value
            counter.value += 1
        pin_to_one_core(index)


class LocalExecutor:
    """Runs jobs in a local process pool (``workers`` > 1) or inline (``workers`` = 1).

    The workers die with this process, also on SIGKILL (:func:`experiments.processes.die_with_parent`). On an interrupt
    (Ctrl-C) or any other exception, and on :meth:`close`, pending jobs are cancelled and the
    workers terminated at once instead of finishing their jobs."""

    def __init__(self, workers: int | None = None, pin: bool = False) -> None:
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self.pin = bool(pin)  # each worker on its own CPU (campaigns that train with SBX)
        self.name = f"local-pool[{self.workers}]"
        self._pool: ProcessPoolExecutor | None = None
        self._children: list = []

    def map_unordered(self, fn: Callable, jobs: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
        if self.workers == 1 or len(jobs) <= 1:
            for job in jobs:
                yield fn(job)
            return
        before = {p.pid for p in mp.active_children()}
        context = pool_context()
        self._pool = pool = ProcessPoolExecutor(
            max_workers=min(self.workers, len(jobs)),
            mp_context=context,
            initializer=_init_worker,
            initargs=(os.getpid(), context.Value("i", 0) if self.pin else None),
        )
        try:
            # Results arrive through done-callbacks, not concurrent.futures.wait: wait() takes every
            # pending future's lock in a Python loop, a Ctrl-C inside that loop leaves some of them
            # held, the pool's manager thread then blocks for ever in set_result, and interpreter
            # exit (which joins that thread) hangs after the interrupt message
            # (once in 47 Ctrl-Cs of a stress loop with 2 workers).
            finished: queue.SimpleQueue = queue.SimpleQueue()
            futures = [pool.submit(fn, job) for job in jobs]
            self._children = [p for p in mp.active_children() if p.pid not in before]
            for fut in futures:
                fut.add_done_callback(finished.put)
            for _ in futures:
                yield finished.get().result()
        except BaseException:  # interrupt, a failed job, or the consumer stopped (GeneratorExit)
            self._terminate()
            raise
        pool.shutdown(wait=True)
        self._pool = None

    def _terminate(self) -> None:
        """Cancel what is queued and end the workers now (SIGTERM, then SIGKILL after 1 s)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        pool.shutdown(wait=False, cancel_futures=True)
        for p in self._children:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + 1.0
        for p in self._children:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(0.5)
        self._children = []

    def close(self) -> None:
        self._terminate()


class RayExecutor:
    """Runs jobs as Ray tasks (``address="local"`` starts a local instance on loopback)."""

    def __init__(self, address: str, num_cpus: int | None = None) -> None:
        try:
            import ray  # optional: the ray extra
        except ImportError as exc:
            raise ValueError("--ray needs the optional extra 'ray' (pip install attitude-envs[ray])") from exc
        root = str(Path(__file__).resolve().parents[1])
        runtime_env = {"env_vars": {"PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}}
        self._started = not ray.is_initialized()
        if self._started:
            if address == "local":
                ray.init(
                    num_cpus=num_cpus or os.cpu_count(),
                    include_dashboard=False,
                    runtime_env=runtime_env,
                    log_to_driver=False,
                    _node_ip_address="127.0.0.1",
                )
            else:
                ray.init(address=address, runtime_env=runtime_env, log_to_driver=False)
        self._ray = ray
        self.name = f"ray[{address}]"

    def map_unordered(self, fn: Callable, jobs: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
        ray = self._ray
        remote = ray.remote(num_cpus=1)(fn)
        pending = [remote.remote(job) for job in jobs]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    yield ray.get(ref)
        except BaseException:  # interrupt or a failed job: cancel what is still queued or running
            for ref in pending:
                ray.cancel(ref, force=True)
            raise

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()


def make_executor(ray_address: str | None = None, workers: int | None = None, pin: bool = False):
    """Ray (``ray_address``) or the local pool; ``pin``: each local worker on its own CPU."""
    return LocalExecutor(workers, pin) if not ray_address else RayExecutor(ray_address, workers)


def trains_with_sbx(campaign: Campaign) -> bool:
    """Whether any training job of ``campaign`` runs on SBX (its ``train.backend``, else its
    hyperparameter entry's)."""
    for env in campaign.envs:
        for agent in campaign.agents_for(env):
            t = agent.train
            if t is None:
                continue
            entry = load_hyperparams(t["algo"], env.id, t.get("hyperparams_file"), t.get("overrides"))
            if str(t.get("backend", entry.get("backend", "sb3"))).lower() == "sbx":
                return True
    return False


# --------------------------------------------------------------------------- results store


def _append_line(path: Path, record: dict[str, Any]) -> None:
    """Append one JSON line and fsync it (a crash can cut at most this line; a line a crash
    cut before is ended first, so this one stays readable)."""
    with path.open("a+b") as fh:
        size = fh.seek(0, os.SEEK_END)
        cut = False
        if size:
            fh.seek(size - 1)
            cut = fh.read(1) != b"\n"
        fh.write((("\n" if cut else "") + json.dumps(record, allow_nan=True) + "\n").encode("utf-8"))
        fh.flush()
        os.fsync(fh.fileno())


def _read_lines(path: Path) -> list[dict[str, Any]]:
    """The JSON lines of an append log, skipping a line cut by a crash."""
    if not path.is_file():
        return []
    records = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return records


RUN_STATUSES = ("completed", "interrupted", "failed", "killed")


class RunLog:
    """One run of a campaign in ``runs.jsonl``: an fsynced ``start`` line before any work,
    ``progress`` lines at most every ``ATTITUDE_ENVS_PROGRESS_S`` seconds (default 30) and an
    ``end`` line with the status (``completed``, ``interrupted`` by Ctrl-C, ``failed``). A run
    killed with SIGKILL leaves its start line (and progress lines) without an end:
    :func:`read_runs` counts it as ``killed``. The start and end lines carry the machine's speed
    then (``reference_steps_per_s``, ``reference_steps_per_s_end``:
    :func:`~experiments.machine_reference.reference_steps_per_s`, 0.2 s each)."""

    def __init__(self, path: Path, executor: str) -> None:
        self.path = Path(path)
        self.run = uuid.uuid4().hex[:12]
        reference = reference_steps_per_s()  # before the clock starts: not part of the run's wall time
        self.start = self.last = time.perf_counter()
        self.interval_s = status_interval_s()
        record = {"event": "start", "run": self.run, "started_at": round(time.time(), 3), "executor": executor}
        _append_line(self.path, record | {"pid": os.getpid(), "reference_steps_per_s": round(reference, 1)})

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.start

    def progress(self) -> None:
        """A progress line (the wall time so far) if the last one is an interval old."""
        now = time.perf_counter()
        if now - self.last >= self.interval_s:
            self.last = now
            _append_line(self.path, {"event": "progress", "run": self.run, "wall_time_s": round(now - self.start, 3)})

    def end(self, status: str, **counts: Any) -> float:
        """The end line; returns the run's wall time, s."""
        elapsed = self.elapsed_s()
        reference = round(reference_steps_per_s(), 1)
        _append_line(
            self.path,
            {"event": "end", "run": self.run, "status": status, "wall_time_s": round(elapsed, 3)}
            | counts
            | {"reference_steps_per_s_end": reference},
        )
        return elapsed


def read_runs(path: str | Path) -> list[dict[str, Any]]:
    """The runs of ``runs.jsonl`` (start, progress and end lines paired by run id), in start
    order: ``run``, ``status`` (one of :data:`RUN_STATUSES`; ``killed``: a start line without
    an end), ``wall_time_s`` (of a killed run: up to its last progress line, a lower bound)
    and the end line's counts. A line of the older one-line-per-run format is one run."""
    runs: dict[str, dict[str, Any]] = {}
    for i, rec in enumerate(_read_lines(Path(path))):
        event = rec.pop("event", None)
        rid = str(rec.get("run", f"line-{i}"))
        run = runs.setdefault(rid, {"run": rid, "status": "killed", "wall_time_s": 0.0})
        if event == "progress":
            run["wall_time_s"] = max(run["wall_time_s"], float(rec.get("wall_time_s", 0.0)))
        elif event == "end" or event is None:
            if event is None:  # the older format: one line per finished or interrupted run
                rec.setdefault("status", "completed" if rec.get("completed") else "interrupted")
            run.update(rec)
        else:
            run.update({k: v for k, v in rec.items() if k not in run})
    return list(runs.values())


class ResultStore:
    """``episodes.jsonl`` (append log, one fsynced line per episode) + ``episodes.csv`` (sorted, atomic)."""

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = Path(out_dir)
        self.log = self.out_dir / "episodes.jsonl"
        self.csv = self.out_dir / "episodes.csv"
        self.rows: dict[tuple, dict[str, Any]] = {}
        self.logged_before = 0  # lines in the log when this store opened it
        if self.log.is_file():
            good = _read_lines(self.log)  # an episode whose line a crash cut is simply run again
            self.rows = {key_of(row): row for row in good}
            # Drop the cut line so the next append starts on a fresh line.
            tmp = self.log.with_name(self.log.name + ".tmp")
            tmp.write_text("".join(json.dumps(row, allow_nan=True) + "\n" for row in good), encoding="utf-8")
            os.replace(tmp, self.log)
            self.logged_before = len(good)
        # J* per episode key (experiments.optimum_table): its own append log, joined into the rows
        self.optimum_log = self.out_dir / "optimum.jsonl"
        self.optimum: dict[str, dict[str, Any]] = {}
        self._optimum_cells: dict[tuple, dict[str, Any]] = {}  # (env, scenario, fault, seed) → J* row
        for r in _read_lines(self.optimum_log):
            self._add_optimum(r)

    def done(self, key: dict[str, Any]) -> bool:
        return key_of(key) in self.rows

    def append(self, row: dict[str, Any]) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        _append_line(self.log, row)
        self.rows[key_of(row)] = row
        self.write_csv()

    def optimum_done(self, key_hash: str) -> bool:
        return key_hash in self.optimum

    def optimum_row(self, key_hash: str) -> dict[str, Any]:
        return self.optimum[key_hash]

    def _add_optimum(self, row: dict[str, Any]) -> None:
        self.optimum[row["hash"]] = row
        for cell in row["cells"]:
            self._optimum_cells[tuple(cell)] = row

    def append_optimum(self, row: dict[str, Any]) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        _append_line(self.optimum_log, row)
        self._add_optimum(row)

    def with_optimum(self, row: dict[str, Any]) -> dict[str, Any]:
        """``row`` with ``j_star`` (its episode's oracle optimum; NaN when unknown),
        ``j_over_j_star`` (J / J*) and ``j_star_source`` (table, cache, solved, unsupported, missing)."""
        found = self._optimum_cells.get((row["env"], row["scenario"], row["fault"], row["seed"]))
        j_star = float(found["j_star"]) if found is not None else float("nan")
        J = float(row["J"])
        ratio = J / j_star if np.isfinite(j_star) and j_star > 0 and not np.isnan(J) else float("nan")
        source = found["source"] if found is not None else "missing"
        return {**row, "j_star": j_star, "j_over_j_star": ratio, "j_star_source": source}

    def sorted_rows(self) -> list[dict[str, Any]]:
        return [self.with_optimum(self.rows[k]) for k in sorted(self.rows, key=_sort_key)]

    def write_csv(self) -> Path:
        tmp = self.csv.with_name(self.csv.name + ".tmp")
        write_csv([_for_table(r) for r in self.sorted_rows()], tmp)
        os.replace(tmp, self.csv)
        return self.csv


def _for_table(row: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in row.items() if k != "episode_wall_s"}


# --------------------------------------------------------------------------- driver


@dataclass
class CampaignResult:
    campaign: Campaign
    out_dir: Path
    rows: list[dict[str, Any]]
    trained: list[dict[str, Any]]
    skipped_agents: dict[str, str]
    episodes_run: int
    episodes_skipped: int
    wall_time_s: float
    executor: str
    total_wall_time_s: float = 0.0  # this run and every earlier one logged in runs.jsonl
    optimum_notes: list[str] = field(default_factory=list)  # episodes without J* (why), for the report
    runs: int = 1
    run_statuses: dict[str, int] = field(default_factory=dict)  # status → count over runs.jsonl
    run_log: list[dict[str, Any]] = field(default_factory=list)  # every run of runs.jsonl (read_runs)


def executor_name(ray_address: str | None = None, workers: int | None = None) -> str:
    """The name :func:`make_executor` gives its executor (without starting it)."""
    return f"ray[{ray_address}]" if ray_address else LocalExecutor(workers).name


def _n_trained(trained: list[dict[str, Any]]) -> int:
    return sum(r["status"] == "trained" for r in trained)


def available(agent: AgentSpec) -> str | None:
    """None if the agent's code imports here, else the reason."""
    try:
        _import(POLICIES[agent.spec["policy"]])
        if agent.train is not None:
            algorithm_class(agent.train["algo"], agent.train.get("backend", "sb3"))  # checks the name too
    except (PolicyUnavailable, ValueError) as exc:
        return str(exc)
    return None


def _probe_models(campaign: Campaign, skipped: dict[str, str]) -> None:
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
            if agent.name in skipped or agent.spec["policy"] != "sb3" or agent.train is not None:
                continue
            instance = gym.make(env.id, **env.kwargs)
            try:
                build_policy(agent.spec, instance, name=agent.name)
            finally:
                instance.close()


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
        if previous.get("fingerprint") != campaign.fingerprint:
            raise ValueError(
                f"--out {str(out_dir)!r} holds results of a different campaign definition "
                f"({previous.get('name')!r}); choose another --out or delete it"
            )
    skipped: dict[str, str] = {}
    for agent in campaign.agents:
        reason = available(agent)
        if reason is not None:
            if not agent.optional:
                raise ValueError(f"campaign {campaign.name!r}: agent {agent.name!r} cannot run: {reason}")
            skipped[agent.name] = reason
            if say is not None:
                say(f"skipping optional agent {agent.name}: {reason}")
    _probe_models(campaign, skipped)
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
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = marker.with_name(marker.name + ".tmp")
    tmp.write_text(
        json.dumps({"name": campaign.name, "fingerprint": campaign.fingerprint, "source": campaign.source}) + "\n"
    )
    os.replace(tmp, marker)
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
        if not todo:
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
            ran = len(_read_lines(store.log)) - store.logged_before
        counts = {"executor": executor.name if executor is not None else executor_name(ray_address, workers)}
        counts |= {"trained": _n_trained(trained), "episodes_run": ran, "completed": status == "completed"}
        elapsed = log.end(status, **counts)  # also when interrupted or failed: the report sums all runs
        if status == "interrupted" and sigint is not None:
            signal.signal(signal.SIGINT, sigint)
    wanted = {key_of(j["key"]) for j in jobs}
    rows = [r for r in store.sorted_rows() if key_of(r) in wanted]
    write_json([_for_table(r) for r in rows], out_dir / "episodes.json")
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
