"""Held-out episodes: what training sees is not what a campaign scores.

For every training job of the plant campaigns of ``--config all`` (the campaign's own
:func:`~experiments.campaign.jobs.training_jobs`, turned into a run plan by ``train`` itself,
stopped before it writes anything), an episode is identified by its observation at reset (these
envs observe their true state without noise in the campaigns' kwargs, so two seeds with the same
reset observation play the same start; the evaluation episodes of a seed-dependent cell all differ,
which the tests check first):

* ``test_validation_episodes_are_not_evaluation_episodes``: the validation episodes that choose
  the best snapshot (``train``'s eval env, seeds ``eval_seed`` + i, 10000+) start nowhere a
  campaign episode of the same env starts. On LinearSystem-v1 every evaluation seed plays the
  paper's x₀; its agents train and validate on random starts around it (the campaign's
  ``train.env_kwargs``), so no validation episode is the evaluated one.
* ``test_training_episodes_are_not_evaluation_episodes`` (SB3/SBX jobs): the first episode of
  every training sub-env, seeded as SB3's model seeds it (``venv.seed(seed)``), starts nowhere a
  campaign episode starts: ``make_training_env`` maps the training seed to the training stream
  (seeds 2³⁰+, :func:`experiments.seeds.training_env_seed`). SB3's convention, sub-env i seeded
  s + i, made the first training episode of sub-env i evaluation episode s + i. The fused JAX
  trainer draws its starts from ``jax.random.PRNGKey(seed)`` on the JAX plant, not from numpy
  seeds, and is not covered here.
"""

from __future__ import annotations

import warnings
from functools import cache
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)
from experiments.campaign.jobs import episode_jobs, training_jobs
from experiments.campaign.spec import load_campaign
from experiments.training import training
from experiments.training.algorithm import Algorithm
from experiments.training.hyperparams import split_hyperparams
from experiments.training.vec_envs import batched_supported, make_eval_env, make_training_env

#: the campaigns of ``--config all``, the full campaign and the quick one
CAMPAIGNS = ("wheel", "air-bearing", "magnetorquer", "slosh", "linear", "slew", "full", "quick")
#: campaigns whose cell starts every seed from the same state (the paper's x₀)
DETERMINISTIC = {"linear"}
NOWHERE = Path("/nonexistent")


def _jobs() -> list[tuple[str, dict]]:
    out = []
    for name in CAMPAIGNS:
        for job in training_jobs(load_campaign(name), NOWHERE):
            out.append((f"{name}:{job['out_dir'].split('models/')[1]}", {**job, "campaign": name}))
    return out


JOBS = _jobs()


class _Stop(Exception):
    pass


def _plan(job: dict, monkeypatch):
    """The run plan ``train`` makes of the campaign's training job (as the campaign worker calls it)."""
    captured = {}

    def capture(out_dir, plan, saved, resume):
        captured["plan"] = plan
        raise _Stop

    monkeypatch.setattr(training, "RunDir", capture)
    with warnings.catch_warnings(), pytest.raises(_Stop):
        warnings.simplefilter("ignore")
        training.train(
            job["algo"],
            job["env_id"],
            NOWHERE,
            env_kwargs=job["env_kwargs"],
            seed=job["seed"],
            hyperparams_file=job["hyperparams_file"],
            overrides=job["overrides"],
            total_timesteps=job["timesteps"],
            checkpoint_freq=job["checkpoint_freq"],
            eval_freq=job["eval_freq"],
            eval_episodes=job["eval_episodes"],
        )
    return captured["plan"]


def _obs(o) -> bytes:
    return np.asarray(o, dtype=float).tobytes()


@cache
def _evaluation_starts(campaign: str, env_id: str) -> frozenset[bytes]:
    """The reset observations of every episode the campaign plays on ``env_id``."""
    starts = set()
    for job in episode_jobs(load_campaign(campaign), NOWHERE):
        if job["env_id"] == env_id:
            env = gym.make(job["env_id"], **job["env_kwargs"])
            obs, _ = env.reset(seed=job["key"]["seed"], options=job["options"] or None)
            starts.add(_obs(obs))
    return frozenset(starts)


def _seeds(campaign: str) -> list[int]:
    return list(load_campaign(campaign).seeds)


def _validation_starts(plan) -> list[bytes]:
    probe = gym.make(plan.env_id, **plan.eval_kwargs)
    batched = batched_supported(plan.env_id, probe)
    env = make_eval_env(plan.env_id, plan.eval_kwargs, plan.eval_episodes, batched)
    if batched:  # as experiments.training.callbacks.episode_costs_batched resets it
        obs, _ = env.reset(seed=list(plan.eval_seeds))
        return [_obs(o) for o in obs]
    return [_obs(env.reset(seed=s)[0]) for s in plan.eval_seeds]


@pytest.mark.parametrize("job", [pytest.param(j, id=i) for i, j in JOBS])
def test_validation_episodes_are_not_evaluation_episodes(job, monkeypatch):
    plan = _plan(job, monkeypatch)
    assert plan.eval_seeds and min(plan.eval_seeds) >= 10_000
    evaluation = _evaluation_starts(job["campaign"], plan.env_id)
    if job["campaign"] not in DETERMINISTIC:  # the cell's start depends on the seed: the test can see a repeat
        assert len(evaluation) >= len(_seeds(job["campaign"])), "the cell's starts should differ by seed"
    shared = [s for s, o in zip(plan.eval_seeds, _validation_starts(plan), strict=True) if o in evaluation]
    assert not shared, f"validation seeds {shared} of {plan.env_id} start where a campaign episode starts"


# the fused JAX trainer's jobs (those campaigns' entries, and a train.backend of jax) draw their
# starts from JAX keys on the twin (the module docstring)
SB3_JOBS = [
    (i, j)
    for i, j in JOBS
    if not i.startswith(("magnetorquer:", "slosh:", "linear:")) and (j.get("overrides") or {}).get("backend") != "jax"
]


@pytest.mark.parametrize("job", [j for _, j in SB3_JOBS], ids=[i for i, _ in SB3_JOBS])
def test_training_episodes_are_not_evaluation_episodes(job, monkeypatch):
    plan = _plan(job, monkeypatch)
    algorithm = Algorithm(job["algo"], plan.entry.get("backend", "sb3")).trainable()
    assert algorithm.backend in ("sb3", "sbx")
    probe = gym.make(plan.env_id, **plan.env_kwargs)
    n_actions = int(np.prod(probe.action_space.shape))
    hp = split_hyperparams(plan.entry, n_actions, algorithm)
    venv = make_training_env(
        plan.env_id, plan.env_kwargs, hp["n_envs"], plan.seed, batched_supported(plan.env_id, probe)
    )
    venv.seed(plan.seed)  # as the model's seed= does (BaseAlgorithm.set_random_seed)
    first = venv.reset()  # the first episode of every sub-env, as SB3's learn() starts it
    evaluation = _evaluation_starts(job["campaign"], plan.env_id)
    assert len(evaluation) >= len(_seeds(job["campaign"]))
    shared = [plan.seed + i for i, o in enumerate(first) if _obs(o) in evaluation]
    assert not shared, (
        f"the first training episodes of sub-envs seeded {shared} ({len(shared)} of {hp['n_envs']}) start where "
        f"campaign episodes of {plan.env_id} start"
    )


def test_training_seeds_are_a_stream_of_their_own():
    """Sub-env seeds of training seeds 0–999 with up to TRAINING_SEED_STRIDE sub-envs lie in
    [TRAINING_SEED_BASE, MAX_SEED], and two training seeds' blocks never overlap."""
    from experiments.seeds import MAX_SEED, TRAINING_SEED_BASE, TRAINING_SEED_STRIDE, training_env_seed

    firsts = [training_env_seed(s) for s in range(1000)] + [training_env_seed(MAX_SEED)]
    assert min(firsts) >= TRAINING_SEED_BASE and max(firsts) + TRAINING_SEED_STRIDE - 1 <= MAX_SEED
    blocks = sorted(firsts[:1000])
    assert all(b - a >= TRAINING_SEED_STRIDE for a, b in zip(blocks, blocks[1:], strict=False))


def test_the_models_seed_keeps_the_training_stream():
    """SB3 reseeds its env with the model's ``seed`` (``set_random_seed``): after the model is built
    the first training episodes are still the training stream's, not seeds s + i."""
    from stable_baselines3 import PPO

    from experiments.seeds import training_env_seed

    env_id, kwargs = "attitude_envs/AirBearing-v1", {"preset": "air-bearing-85kg"}
    for batched in (True, False):
        venv = make_training_env(env_id, kwargs, 4, 1, batched)
        PPO("MlpPolicy", venv, seed=1, n_steps=8, batch_size=8, device="cpu")
        first = venv.reset()
        for i, obs in enumerate(first):
            expected, _ = gym.make(env_id, **kwargs).reset(seed=training_env_seed(1) + i)
            np.testing.assert_array_equal(obs, expected)
            evaluated, _ = gym.make(env_id, **kwargs).reset(seed=1 + i)
            assert not np.array_equal(obs, evaluated)
        venv.close()
