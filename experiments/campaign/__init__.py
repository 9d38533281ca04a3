"""Benchmark campaigns: agents × envs × scenarios × faults × seeds, from one YAML file.

A campaign file (shipped presets: ``quick``, ``full`` in ``experiments/campaigns/``)::

    name: quick
    seeds: [0, 1, 2, 3, 4]            # evaluation episode seeds: a count, "0-4", "0,3,7-9" or a list (>= 5 for the IQM)
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
      - {name: sac-pretrained, policy: sb3, model: path/to/model.zip, note: "a one-line note for the report"}

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

Success is the env's own (``env.unwrapped.success_metric``,
:mod:`attitude_envs.evaluation.success`) at the campaign's threshold, with J finite and the
episode not terminated. An agent's optional ``note`` (one line) is shown beside it in the
report's leaderboards.

Modules, each importing only those listed before it: :mod:`~experiments.campaign.spec` (the YAML
schema, checked at load), :mod:`~experiments.campaign.jobs` (training and episode jobs),
:mod:`~experiments.campaign.episode` (running one job in a worker),
:mod:`~experiments.campaign.executors` (local pool, Ray), :mod:`~experiments.campaign.store`
(the append logs and tables) and :mod:`~experiments.campaign.run` (the driver).
"""

from experiments.campaign.episode import run_job, success_criterion
from experiments.campaign.executors import LocalExecutor, RayExecutor, executor_name, make_executor, trains_with_sbx
from experiments.campaign.jobs import KEY_COLUMNS, episode_jobs, key_of, training_jobs
from experiments.campaign.run import available, prepare_campaign, probe_models, run_campaign
from experiments.campaign.spec import (
    ALL_CAMPAIGNS,
    PLANT_CAMPAIGNS,
    PRESETS,
    SELECT,
    AgentSpec,
    Campaign,
    EnvSpec,
    load_campaign,
    preset_path,
)
from experiments.campaign.store import RUN_STATUSES, CampaignResult, ResultStore, RunLog, read_runs

__all__ = [
    "KEY_COLUMNS",
    "ALL_CAMPAIGNS",
    "PLANT_CAMPAIGNS",
    "PRESETS",
    "RUN_STATUSES",
    "SELECT",
    "AgentSpec",
    "Campaign",
    "CampaignResult",
    "EnvSpec",
    "LocalExecutor",
    "RayExecutor",
    "ResultStore",
    "RunLog",
    "available",
    "episode_jobs",
    "executor_name",
    "key_of",
    "load_campaign",
    "make_executor",
    "prepare_campaign",
    "preset_path",
    "probe_models",
    "read_runs",
    "run_campaign",
    "run_job",
    "success_criterion",
    "trains_with_sbx",
    "training_jobs",
]
