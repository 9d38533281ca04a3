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
from typing import Any

import gymnasium as gym
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnv, VecFrameStack, VecMonitor

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


def make_training_env(env_id: str, env_kwargs: dict[str, Any], n_envs: int, seed: int, batched: bool) -> VecEnv:
    """``n_envs`` envs seeded ``seed + i`` (SB3's convention) with episode statistics."""
    kwargs = {k: v for k, v in env_kwargs.items() if k != "render_mode"}
    if batched:
        venv = SB3VecEnv(env_id, num_envs=int(n_envs), **kwargs)
        venv.seed(int(seed))
        return PicklableVecMonitor(venv)
    # make_vec_env asks for render_mode="rgb_array", which envs without a renderer refuse
    return make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs={"render_mode": None, **kwargs})


def make_eval_env(env_id: str, env_kwargs: dict[str, Any], n_episodes: int, batched: bool):
    """The evaluation env: one batched env with a sub-env per episode (next-step autoreset, so
    a sub-env whose episode ended is simply ignored), or a single env episodes run one by one."""
    kwargs = {k: v for k, v in env_kwargs.items() if k != "render_mode"}
    if batched:
        return gym.make_vec(
            env_id,
            num_envs=int(n_episodes),
            vectorization_mode="vector_entry_point",
            autoreset_mode="next_step",
            **kwargs,
        )
    return gym.make(env_id, **kwargs)
