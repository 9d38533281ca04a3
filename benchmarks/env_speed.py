"""Env step throughput: single envs vs Pendulum-v1, batched envs vs CartPole's native vector
env and vs SyncVectorEnv of the same env, SB3 PPO steps/s, evaluator episodes/s."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401

SINGLE_ENV_IDS = (
    "attitude_envs/ReactionWheel-v0",
    "attitude_envs/AirBearing-v0",
    "attitude_envs/LinearSystem-v0",
    "attitude_envs/Magnetorquer-v0",
    "attitude_envs/FuelSlosh-v0",
)


def _seconds_per_call(call, seconds: float, batch: int = 1) -> float:
    """Mean wall seconds per ``call()``, timed in batches of ``batch`` calls for at least ``seconds``."""
    n, start = 0, time.perf_counter()
    while True:
        for _ in range(batch):
            call()
        n += batch
        elapsed = time.perf_counter() - start
        if elapsed > seconds:
            return elapsed / n


def _time_single(env, action, seconds: float) -> float:
    """Mean seconds per step of a single env (wrapped as gym.make returns it)."""
    env.reset(seed=0)
    for _ in range(100):
        env.step(action)

    def step() -> None:
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()

    return _seconds_per_call(step, seconds, batch=500)


def _time_vector(env, actions, seconds: float) -> float:
    """Env-steps per second of a vector env."""
    env.reset(seed=0)
    for _ in range(3):
        env.step(actions)
    return actions.shape[0] / _seconds_per_call(lambda: env.step(actions), seconds)


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
            (_time_single(pendulum, pendulum_action, seconds / rounds), _time_single(env, action, seconds / rounds))
            for _ in range(rounds)
        ]
        ref_times += [p[0] for p in pairs]
        ratio = float(np.median([t / r for r, t in pairs]))
        t = float(np.median([p[1] for p in pairs]))
        rows.append({"benchmark": "single step", "env": env_id, "us_per_step": t * 1e6, "ratio_to_reference": ratio})
    ref = {
        "benchmark": "single step",
        "env": "Pendulum-v1 (reference)",
        "us_per_step": float(np.median(ref_times)) * 1e6,
    }
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
    native vector env (4096 envs); the speed-up over ``SyncVectorEnv`` at N = 64 is the
    median of ``rounds`` alternating measurements of both."""
    rows = []
    cart = gym.make_vec("CartPole-v1", num_envs=4096, vectorization_mode="vector_entry_point")
    cart_rate = _time_vector(cart, np.zeros(4096, dtype=np.int64), seconds)
    rows.append(
        {
            "benchmark": "batched step",
            "env": "CartPole-v1 native (reference)",
            "num_envs": 4096,
            "steps_per_s": cart_rate,
        }
    )
    for env_id in BATCHED_ENV_IDS:
        for n in sizes:
            env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
            rate = _time_vector(env, np.zeros((n, *env.single_action_space.shape)), seconds)
            rows.append(
                {
                    "benchmark": "batched step",
                    "env": env_id,
                    "num_envs": n,
                    "steps_per_s": rate,
                    "ratio_to_cartpole_4096": rate / cart_rate,
                }
            )
        sync = gym.make_vec(env_id, num_envs=64, vectorization_mode="sync")
        native = gym.make_vec(env_id, num_envs=64, vectorization_mode="vector_entry_point")
        actions = np.zeros((64, *sync.single_action_space.shape))
        pairs = [
            (_time_vector(sync, actions, seconds / rounds), _time_vector(native, actions, seconds / rounds))
            for _ in range(rounds)
        ]
        rows.append(
            {
                "benchmark": "batched step",
                "env": f"{env_id} SyncVectorEnv",
                "num_envs": 64,
                "steps_per_s": float(np.median([p[0] for p in pairs])),
                "native_speedup": float(np.median([n / s for s, n in pairs])),
            }
        )
    return rows


def sb3_ppo(steps: int = 4096) -> list[dict]:
    """PPO training throughput on the native batched env vs DummyVecEnv (16 envs)."""
    try:
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import DummyVecEnv
    except ImportError:  # the sb3 extra is not installed
        return []
    from attitude_envs.envs.sb3_vec_env import SB3VecEnv

    env_id = "attitude_envs/ReactionWheel-v0"
    rows = []
    for name, make in [
        ("native (SB3VecEnv)", lambda: SB3VecEnv(env_id, num_envs=16)),
        ("DummyVecEnv", lambda: DummyVecEnv([lambda: gym.make(env_id) for _ in range(16)])),
    ]:
        model = PPO("MlpPolicy", make(), n_steps=128, batch_size=512, n_epochs=1, seed=0, device="cpu", verbose=0)
        start = time.perf_counter()
        model.learn(steps)
        rows.append(
            {"benchmark": "sb3 ppo", "env": f"{env_id} {name}", "steps_per_s": steps / (time.perf_counter() - start)}
        )
    return rows


def evaluator(episodes: int = 5) -> list[dict]:
    from attitude_envs.evaluation import rollout
    from baselines.lqr import LQRPolicy

    env = gym.make("attitude_envs/ReactionWheel-v0")
    policy = LQRPolicy(env)
    start = time.perf_counter()
    for seed in range(episodes):
        rollout(env, policy, seed=seed)
    return [
        {
            "benchmark": "evaluator",
            "env": "ReactionWheel-v0 LQR 60 s episodes",
            "episodes_per_s": episodes / (time.perf_counter() - start),
        }
    ]
