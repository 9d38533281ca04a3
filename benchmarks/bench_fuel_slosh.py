"""Speed of FuelSlosh-v0 and its baselines (prints; never asserted in tests).

PYTHONPATH=. python benchmarks/bench_fuel_slosh.py
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from attitude_envs.envs.fuel_slosh import FuelSloshEnv
from attitude_envs.info import policy_view
from baselines.fuzzy_slosh import FuzzySloshPDPolicy
from baselines.slosh import SloshLQRPolicy, SloshLyapunovPolicy, SloshPDPolicy


def steps_per_second(env, policy=None, n: int = 2000) -> float:
    obs, info = env.reset(seed=0)
    if policy is not None:
        policy.reset(0)
    zero = np.zeros(2, np.float32)
    start = time.perf_counter()
    for _ in range(n):
        action = zero if policy is None else policy.act(obs, policy_view(info))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            obs, info = env.reset(seed=0)
    return n / (time.perf_counter() - start)


def main() -> None:
    warnings.simplefilter("ignore")
    env = FuelSloshEnv()
    print(f"zero action          : {steps_per_second(env):8.0f} steps/s (0.1 s control, 2 RK4 sub-steps)")
    for policy in (SloshPDPolicy(env), SloshLQRPolicy(env), SloshLyapunovPolicy(env), FuzzySloshPDPolicy(env)):
        print(f"{policy.name:21s}: {steps_per_second(env, policy):8.0f} steps/s")


if __name__ == "__main__":
    main()
