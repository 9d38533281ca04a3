"""The machine's speed, measured next to every campaign run so that its wall time can be read.

A campaign's wall time is only as meaningful as the machine it ran on, and shared machines are
not steady: on the same 2-core VM type the training-throughput benchmark measured SB3 PPO at
5,667 env steps/s one day and 2,244 the next (SAC 69.9 and 36.6). So each run of
``runs.jsonl`` carries the rate of a fixed workload, measured on one core when the run starts
and when it ends: Gymnasium's ``Pendulum-v1`` stepped with a constant action, code that this
package does not own, so a change in the rate is the machine's and not ours. The rate tells a
slow day from a fast one but does not scale a wall time exactly (on one slow day it fell
1.5-2.9x while the campaigns took 1.4-1.6x as long): compare two wall times when their
references agree.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

REFERENCE_ENV = "Pendulum-v1"
DEFAULT_SECONDS = 0.2


def seconds_per_call(call: Callable[[], object], seconds: float, batch: int = 1) -> float:
    """Mean wall seconds per ``call()``, timed in batches of ``batch`` calls for at least ``seconds``."""
    n, start = 0, time.perf_counter()
    while True:
        for _ in range(batch):
            call()
        n += batch
        elapsed = time.perf_counter() - start
        if elapsed > seconds:
            return elapsed / n


def seconds_per_step(env: gym.Env, action: np.ndarray, seconds: float) -> float:
    """Mean wall seconds per step of a single env (wrapped as ``gym.make`` returns it), stepped
    with a constant ``action`` for at least ``seconds`` after 100 warm-up steps."""

    def step() -> None:
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()

    env.reset(seed=0)
    for _ in range(100):  # warm-up: a short episode ends (and resets) here too
        step()
    return seconds_per_call(step, seconds, batch=500)


def reference_steps_per_s(seconds: float = DEFAULT_SECONDS) -> float:
    """Env steps/s of ``Pendulum-v1`` as ``gym.make`` wraps it, constant action, in this process,
    for at least ``seconds`` of wall time (> 0): :func:`seconds_per_step`, the loop with which
    ``benchmarks.env_speed`` times its ``Pendulum-v1`` reference row."""
    if not seconds > 0.0:
        raise ValueError(f"seconds must be > 0, got {seconds!r}")
    env = gym.make(REFERENCE_ENV)
    try:
        return 1.0 / seconds_per_step(env, np.zeros(env.action_space.shape, env.action_space.dtype), seconds)
    finally:
        env.close()
