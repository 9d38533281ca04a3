"""The envs ``train`` trains and evaluates on: the natively batched env where there is one.

Every env id with a vector entry point (``-v0`` and ``-v1``: :mod:`attitude_envs.registration`)
trains on :class:`~experiments.training.sb3_vec_env.SB3VecEnv` (one compiled call steps all
sub-envs, bitwise the single envs, no per-step deep copies of infos) under
:class:`PicklableVecMonitor` (the episode statistics SB3 logs); kwargs the batched env does not
support (sensors, ``fault_hint``, non-lab ``conditions``) fall back to SB3's ``make_vec_env``
(one Monitor per env).
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecFrameStack, VecMonitor

from experiments.seeds import TRAINING_SEED_STRIDE, training_env_seed
from experiments.training.hyperparams import import_dotted
from experiments.training.sb3_vec_env import SB3VecEnv


class _PicklableWrapper:
    """Makes a ``VecEnvWrapper`` pickle: the checkpoint pickles the training env whole, and
    ``VecEnvWrapper`` keeps a dict of its class's members (an ABC's internals among them) that
    cloudpickle refuses; it is rebuilt on load."""

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("class_attributes", None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.class_attributes = dict(inspect.getmembers(self.__class__))


class PicklableVecMonitor(_PicklableWrapper, VecMonitor):
    """SB3's ``VecMonitor`` (``infos[i]["episode"]`` at episode ends) that pickles."""


class PicklableVecFrameStack(_PicklableWrapper, VecFrameStack):
    """SB3's ``VecFrameStack`` (the Zoo's ``frame_stack``) that pickles."""


class TrainingSeeds(_PicklableWrapper, VecEnvWrapper):
    """Maps a training seed to the training stream: ``seed(s)`` seeds sub-env ``i`` with
    ``training_env_seed(s) + i`` (:func:`experiments.seeds.training_env_seed`), so that the first
    episode of a training sub-env is never an evaluation or validation episode. It sits under
    every other wrapper, where SB3's ``set_random_seed`` (the model's ``seed=``) reaches it."""

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        return self.venv.step_wait()

    def seed(self, seed: int | None = None):
        return self.venv.seed(None if seed is None else training_env_seed(seed))


def batched_supported(env_id: str, env: gym.Env) -> bool:
    """True where ``env_id`` has a natively batched env that supports ``env``'s options.

    The batched envs run the lab conditions only (:mod:`attitude_envs.conditions`; they refuse
    any other), so an env under flight or custom conditions trains and evaluates on single envs
    (SB3's ``make_vec_env``: one flight env per sub-env, each drawing its own plant per episode)."""
    base = env.unwrapped
    sensors = getattr(base, "sensor_layer", None)
    conditions = getattr(base, "conditions", None)
    return gym.spec(env_id).vector_entry_point is not None and not (
        (sensors is not None and sensors.enabled)
        or getattr(base, "fault_hint", False)
        or (conditions is not None and not conditions.is_lab)
    )


Wrappers = Sequence[tuple[str, dict[str, Any]]]


class ZooWrappers:
    """The Zoo's ``env_wrapper`` list (``[(dotted path, kwargs)]``,
    :func:`experiments.training.hyperparams.zoo_objects`) as one callable ``env → wrapped env``,
    applied in order (the first innermost). It pickles (the classes are imported on use)."""

    def __init__(self, wrappers: Wrappers) -> None:
        self.wrappers = [(str(path), dict(kwargs)) for path, kwargs in wrappers]
        for path, _ in self.wrappers:
            import_dotted(path)  # a bad path fails here, before any env is built

    def __call__(self, env: gym.Env) -> gym.Env:
        for path, kwargs in self.wrappers:
            env = import_dotted(path)(env, **kwargs)
        return env


def make_training_env(
    env_id: str, env_kwargs: dict[str, Any], n_envs: int, seed: int, batched: bool, wrappers: Wrappers = ()
) -> VecEnv:
    """``n_envs`` envs with episode statistics, sub-env ``i`` seeded ``training_env_seed(seed) + i``
    (:class:`TrainingSeeds`: the training stream, disjoint from every evaluation seed), each
    wrapped by the Zoo's ``env_wrapper`` list ``wrappers`` (single envs only: the batched env
    has no per-env wrappers)."""
    if not 1 <= int(n_envs) <= TRAINING_SEED_STRIDE:
        raise ValueError(f"n_envs must be in [1, {TRAINING_SEED_STRIDE}], got {n_envs}")
    if batched and wrappers:
        raise ValueError("env_wrapper needs single envs: pass batched=False")
    kwargs = {k: v for k, v in env_kwargs.items() if k != "render_mode"}
    if batched:
        venv = PicklableVecMonitor(SB3VecEnv(env_id, num_envs=int(n_envs), **kwargs))
    else:  # make_vec_env asks for render_mode="rgb_array", which envs without a renderer refuse
        wrapper_class = ZooWrappers(wrappers) if wrappers else None
        venv = make_vec_env(
            env_id, n_envs=n_envs, env_kwargs={"render_mode": None, **kwargs}, wrapper_class=wrapper_class
        )
    venv = TrainingSeeds(venv)
    venv.seed(int(seed))
    return venv


def make_eval_env(env_id: str, env_kwargs: dict[str, Any], n_episodes: int, batched: bool, wrappers: Wrappers = ()):
    """The evaluation env: one batched env with a sub-env per episode (next-step autoreset, so
    a sub-env whose episode ended is simply ignored), or a single env episodes run one by one
    (wrapped by ``wrappers``, the Zoo's ``env_wrapper`` list, as the training envs are)."""
    if batched and wrappers:
        raise ValueError("env_wrapper needs single envs: pass batched=False")
    kwargs = {k: v for k, v in env_kwargs.items() if k != "render_mode"}
    if wrappers:
        return ZooWrappers(wrappers)(gym.make(env_id, **kwargs))
    if batched:
        return gym.make_vec(
            env_id,
            num_envs=int(n_episodes),
            vectorization_mode="vector_entry_point",
            autoreset_mode="next_step",
            **kwargs,
        )
    return gym.make(env_id, **kwargs)
