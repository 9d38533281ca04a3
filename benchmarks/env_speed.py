"""Env step throughput: single envs vs Pendulum-v1, batched envs vs CartPole's native vector
env and vs SyncVectorEnv of the same env, SB3 PPO steps/s, evaluator episodes/s.

Every row is the median of repeated rounds in which the compared cases alternate (so that
machine noise, e.g. another job starting, hits both alike), with its spread: ``<key>_range``
is [min, max] over the rounds and ``rounds`` their number. One sample is not a measurement."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401
from experiments.machine_reference import seconds_per_call, seconds_per_step

SINGLE_ENV_IDS = (
    "attitude_envs/ReactionWheel-v0",
    "attitude_envs/AirBearing-v0",
    "attitude_envs/LinearSystem-v0",
    "attitude_envs/Magnetorquer-v0",
    "attitude_envs/FuelSlosh-v0",
)


def _time_vector(env, actions, seconds: float) -> float:
    """Env-steps per second of a vector env."""
    env.reset(seed=0)
    for _ in range(3):
        env.step(actions)
    return actions.shape[0] / seconds_per_call(lambda: env.step(actions), seconds)


def _median_range(values) -> tuple[float, list[float]]:
    """Median and [min, max] of per-round values."""
    x = np.asarray(values, dtype=float)
    return float(np.median(x)), [float(x.min()), float(x.max())]


def _with_spread(row: dict, key: str, values) -> dict:
    """``row`` with ``key`` = the median of ``values``, ``key_range`` = [min, max]."""
    row[key], row[f"{key}_range"] = _median_range(values)
    row["rounds"] = len(values)
    return row


def single_env(seconds: float = 1.0, rounds: int = 5) -> list[dict]:
    """Per-step time of each single env and its ratio to Pendulum-v1, measured alternately
    in ``rounds`` rounds (median ratio), so that machine noise hits both alike."""
    pendulum = gym.make("Pendulum-v1")
    pendulum_action = pendulum.action_space.sample()
    rows = []
    ref_times = []
    for env_id in SINGLE_ENV_IDS:
        env = gym.make(env_id)
        action = np.zeros(env.action_space.shape, np.float32)
        pairs = [
            (
                seconds_per_step(pendulum, pendulum_action, seconds / rounds),
                seconds_per_step(env, action, seconds / rounds),
            )
            for _ in range(rounds)
        ]
        ref_times += [p[0] for p in pairs]
        row = {"benchmark": "single step", "env": env_id}
        _with_spread(row, "us_per_step", [p[1] * 1e6 for p in pairs])
        rows.append(_with_spread(row, "ratio_to_reference", [t / r for r, t in pairs]))
    ref = {"benchmark": "single step", "env": "Pendulum-v1 (reference)"}
    _with_spread(ref, "us_per_step", [t * 1e6 for t in ref_times])
    return [dict(ref, ratio_to_reference=1.0), *rows]


BATCHED_ENV_IDS = (
    "attitude_envs/ReactionWheel-v0",
    "attitude_envs/AirBearing-v0",
    "attitude_envs/LinearSystem-v0",
    "attitude_envs/FuelSlosh-v0",
    "attitude_envs/Magnetorquer-v0",
)


def batched(sizes=(1, 64, 1024, 4096), seconds: float = 1.0, rounds: int = 3) -> list[dict]:
    """Env-steps/s of each native batched env at ``sizes`` and its ratio to CartPole's
    native vector env (4096 envs), and the speed-up over ``SyncVectorEnv`` at N = 64: in each
    of ``rounds`` rounds the reference and every case are timed in turn (``seconds / rounds``
    each); rows give the medians over the rounds and their [min, max]."""
    cart = gym.make_vec("CartPole-v1", num_envs=4096, vectorization_mode="vector_entry_point")
    cart_actions = np.zeros(4096, dtype=np.int64)
    cases = []  # (env id, n, env, actions)
    for env_id in BATCHED_ENV_IDS:
        for n in sizes:
            env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
            cases.append((env_id, n, env, np.zeros((n, *env.single_action_space.shape))))
    syncs = {}
    for env_id in BATCHED_ENV_IDS:
        sync = gym.make_vec(env_id, num_envs=64, vectorization_mode="sync")
        native = gym.make_vec(env_id, num_envs=64, vectorization_mode="vector_entry_point")
        syncs[env_id] = (sync, native, np.zeros((64, *sync.single_action_space.shape)))
    t = seconds / rounds
    cart_rates, rates = [], {(c[0], c[1]): [] for c in cases}
    sync_rates, speedups = {e: [] for e in syncs}, {e: [] for e in syncs}
    for _ in range(rounds):
        cart_rates.append(_time_vector(cart, cart_actions, t))
        for env_id, n, env, actions in cases:
            rates[(env_id, n)].append(_time_vector(env, actions, t))
        for env_id, (sync, native, actions) in syncs.items():
            s, nat = _time_vector(sync, actions, t), _time_vector(native, actions, t)
            sync_rates[env_id].append(s)
            speedups[env_id].append(nat / s)
    ref = {"benchmark": "batched step", "env": "CartPole-v1 native (reference)", "num_envs": 4096}
    rows = [_with_spread(ref, "steps_per_s", cart_rates)]
    for env_id in BATCHED_ENV_IDS:
        for n in sizes:
            row = {"benchmark": "batched step", "env": env_id, "num_envs": n}
            _with_spread(row, "steps_per_s", rates[(env_id, n)])
            ratios = [r / c for r, c in zip(rates[(env_id, n)], cart_rates, strict=True)]
            rows.append(_with_spread(row, "ratio_to_cartpole_4096", ratios))
        row = {"benchmark": "batched step", "env": f"{env_id} SyncVectorEnv", "num_envs": 64}
        _with_spread(row, "steps_per_s", sync_rates[env_id])
        rows.append(_with_spread(row, "native_speedup", speedups[env_id]))
    return rows


def sb3_ppo(steps: int = 4096, rounds: int = 3) -> list[dict]:
    """PPO training throughput on the native batched env vs DummyVecEnv (16 envs): after one
    warm-up rollout each, ``rounds`` rounds of ``steps / rounds`` steps alternate between the
    two; medians of steps/s and of the per-round speed-up, with [min, max]."""
    try:
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import DummyVecEnv
    except ImportError:  # the sb3 extra is not installed
        return []
    from experiments.training.sb3_vec_env import SB3VecEnv
    from experiments.training.training import log_without_folder

    env_id = "attitude_envs/ReactionWheel-v0"
    variants = {
        "native (SB3VecEnv)": SB3VecEnv(env_id, num_envs=16),
        "DummyVecEnv": DummyVecEnv([lambda: gym.make(env_id) for _ in range(16)]),
    }
    models = {
        name: PPO("MlpPolicy", venv, n_steps=128, batch_size=512, n_epochs=1, seed=0, device="cpu", verbose=0)
        for name, venv in variants.items()
    }
    per_round = max(16 * 128, steps // rounds)
    for model in models.values():
        log_without_folder(model)
        model.learn(16 * 128)  # warm-up: first rollout, compiled kernels, torch's first calls
    rates: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(rounds):
        for name, model in models.items():
            start = time.perf_counter()
            model.learn(per_round, reset_num_timesteps=False)
            rates[name].append(per_round / (time.perf_counter() - start))
    rows = []
    for name in models:
        rows.append(_with_spread({"benchmark": "sb3 ppo", "env": f"{env_id} {name}"}, "steps_per_s", rates[name]))
    speedup = [n / d for n, d in zip(rates["native (SB3VecEnv)"], rates["DummyVecEnv"], strict=True)]
    _with_spread(rows[0], "native_speedup", speedup)
    return rows


def evaluator(episodes: int = 5, rounds: int = 3) -> list[dict]:
    """Episodes/s of the evaluator (LQR, 60 s episodes): median of ``rounds`` rounds of ``episodes``."""
    from attitude_envs.evaluation import rollout
    from baselines.lqr import LQRPolicy

    env = gym.make("attitude_envs/ReactionWheel-v0")
    policy = LQRPolicy(env)
    rollout(env, policy, seed=0)  # warm-up
    rates = []
    for r in range(rounds):
        start = time.perf_counter()
        for seed in range(episodes):
            rollout(env, policy, seed=r * episodes + seed)
        rates.append(episodes / (time.perf_counter() - start))
    row = {"benchmark": "evaluator", "env": "ReactionWheel-v0 LQR 60 s episodes"}
    return [_with_spread(row, "episodes_per_s", rates)]
