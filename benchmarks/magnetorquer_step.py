"""Speed of Magnetorquer-v0 (env step alone and with the AMNFTSMC controller).

    PYTHONPATH=. python benchmarks/magnetorquer_step.py [--steps 5000]

Prints microseconds per control step (dt 0.1 s, one RK4 sub-step); a two-orbit episode is
120 380 steps. Not a test: timings depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import attitude_envs  # noqa: F401
from attitude_envs.info import policy_view
from baselines.sliding_mode import AMNFTSMCPolicy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=5000)
    args = parser.parse_args()
    env = gym.make("attitude_envs/Magnetorquer-v0", preset="sadigh-2022-faults").unwrapped
    obs, info = env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(args.steps):
        obs, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    env_us = (time.perf_counter() - start) / args.steps * 1e6
    policy = AMNFTSMCPolicy(env)
    obs, info = env.reset(seed=0)
    policy.reset(0)
    start = time.perf_counter()
    for _ in range(args.steps):
        obs, _, _, _, info = env.step(policy.act(obs, policy_view(info)))
    both_us = (time.perf_counter() - start) / args.steps * 1e6
    print(f"Magnetorquer-v0 step: {env_us:.0f} µs; step + AMNFTSMC: {both_us:.0f} µs")
    print(f"two-orbit episode (120 380 steps) with AMNFTSMC: {both_us * 120380 / 1e6:.0f} s")


if __name__ == "__main__":
    main()
