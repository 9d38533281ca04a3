"""FDI benchmark: detection delay and false-alarm rate of the IMM bank on the
``wheel-degraded`` scenario (50 % loss of effectiveness, noisy gyro / star tracker /
tachometer, LQR on the measured state), over many seeds and every wheel.

    PYTHONPATH=. python benchmarks/fdi_detection.py [--seeds 40] [--duration 20]

Prints a markdown table; the delay bound asserted in tests/test_fdi.py comes from it.
"""

from __future__ import annotations

import argparse

import numpy as np

from attitude_envs.estimation.fdi import ActuatorFDI, run_fdi_episode
from attitude_envs.scenarios import load_scenario, make_scenario_env
from baselines.lqr import LQRPolicy


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--tachometer", type=int, default=1)
    args = parser.parse_args()
    sc = load_scenario("wheel-degraded")
    base = sc["faults"][0]
    env = make_scenario_env(dict(sc, faults=[]), episode_duration_s=args.duration)
    policy = LQRPolicy(env)
    healthy, faulty = [], []
    for seed in range(args.seeds):
        fdi = ActuatorFDI.for_env(env, use_tachometer=bool(args.tachometer))
        healthy.append(run_fdi_episode(env, policy, fdi, seed=seed))
        fault = dict(base, index=seed % 4)
        faulty.append(run_fdi_episode(env, policy, fdi, seed=seed, options={"faults": [fault]}))
    delays = np.array([r["delay_s"] for r in faulty if r["correct"]])
    print(f"| quantity | value ({args.seeds} seeds, {args.duration:g} s episodes, onset {base['onset_s']} s) |")
    print("|---|---|")
    print(f"| healthy runs with an alarm | {sum(r['detected_index'] is not None for r in healthy)} / {len(healthy)} |")
    print(f"| faulty runs: alarm before onset | {sum(r['false_alarm'] for r in faulty)} / {len(faulty)} |")
    print(f"| faulty runs: correct isolation | {sum(r['correct'] for r in faulty)} / {len(faulty)} |")
    wrong = sum(r["detected_index"] is not None and not r["correct"] and not r["false_alarm"] for r in faulty)
    print(f"| faulty runs: wrong actuator | {wrong} / {len(faulty)} |")
    if delays.size:
        print(
            f"| delay median / p90 / max [s] | {np.median(delays):.1f} / {np.percentile(delays, 90):.1f} / {delays.max():.1f} |"
        )
    print("per-seed delays:", [None if r["delay_s"] is None else round(r["delay_s"], 1) for r in faulty])


if __name__ == "__main__":
    main()
