"""Samples and wall time of the Q-learning LQR learners to 1e-6 relative gain error vs n.

    PYTHONPATH=. python benchmarks/q_learning_lqr.py [--out results/benchmarks/q_learning_lqr.json] [--sizes 2 4 8 12]

Random systems (seeded): A uniform in [−1, 1] rescaled to ρ(A) = 1.05 (open-loop unstable),
B uniform, m = 2, Q = I, R = I, LinearSystem-v0, noise-free. Learners: on-policy PI
(p fresh samples per iteration, K₀ by pole placement), off-policy LSPI (one batch of p),
value iteration (the paper's method, one batch of p reused), certainty equivalence with
known Q, R (n+m samples). Literature implementations spend 250 to 10⁵ iterations and
10³–10⁶ samples on comparable problems (Heravi & Novinzadeh 2017: about 10⁵ iterations).
Not a test.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents import QLearningLQR  # noqa: E402
from agents.qlqr.certainty_equivalence import ce_gain  # noqa: E402
from agents.qlqr.data import EnvAdapter, collect  # noqa: E402
from agents.qlqr.features import n_features  # noqa: E402
from agents.qlqr.truth import relative_error  # noqa: E402
from attitude_envs.envs.linear_system import LinearSystemEnv  # noqa: E402
from attitude_envs.lqr import dlqr  # noqa: E402

TARGET = 1e-6


def system(n: int, m: int, seed: int):
    rng = np.random.default_rng(seed)
    A = rng.uniform(-1, 1, (n, n))
    A *= 1.05 / np.max(np.abs(np.linalg.eigvals(A)))
    return A, rng.uniform(-1, 1, (n, m)), np.eye(n), np.eye(m)


def first_samples(agent, K_star) -> tuple[int | None, int | None]:
    for i, h in enumerate(agent.history):
        if relative_error(h["gain"], K_star) < TARGET:
            return h["samples_used"], i + 1
    return None, None


def run(sizes: list[int], m: int = 2, seed: int = 0) -> list[dict]:
    rows = []
    for n in sizes:
        A, B, Q, R = system(n, m, seed + n)
        K_star, _, _ = dlqr(A, B, Q, R)
        K0 = scipy.signal.place_poles(A, B, np.linspace(-0.5, 0.5, n)).gain_matrix
        p = n_features(n + m)
        env = LinearSystemEnv(preset=None, A=A, B=B, Q=Q, R=R, action_scale=1e6)
        for label, kw in (
            ("PI (on-policy)", dict(method="policy_iteration", initial_gain=K0)),
            ("LSPI (one batch)", dict(method="lspi", initial_gain=K0)),
            ("VI (one batch, paper's method)", dict(method="value_iteration")),
        ):
            start = time.perf_counter()
            agent = QLearningLQR(env, seed=seed, exploration_std=1.0, **kw).learn(samples_per_iteration=p)
            wall = time.perf_counter() - start
            samples, iters = first_samples(agent, K_star)
            rows.append(
                dict(
                    n=n,
                    m=m,
                    p=p,
                    learner=label,
                    samples_to_target=samples,
                    iterations_to_target=iters,
                    final_error=relative_error(agent.gain, K_star),
                    wall_s=wall,
                )
            )
        start = time.perf_counter()
        data = collect(
            EnvAdapter(env), n + m, np.zeros((m, n)), np.ones(m), np.ones(n), np.random.default_rng(seed), seed, "reset"
        )
        K_ce = ce_gain(data, Q=Q, R=R)
        wall = time.perf_counter() - start
        err = relative_error(K_ce, K_star)
        rows.append(
            dict(
                n=n,
                m=m,
                p=p,
                learner="CE (known Q, R)",
                samples_to_target=n + m if err < TARGET else None,
                iterations_to_target=1,
                final_error=err,
                wall_s=wall,
            )
        )
    rows += spacecraft()
    return rows


def spacecraft(seed: int = 0) -> list[dict]:
    """Heravi & Novinzadeh 2017's slow plant (Euler, Δt = 0.01 s, J ≈ 10³ kg·m²): ρ(A − BK*) = 0.99984."""
    env = LinearSystemEnv(preset="heravi-2017")
    A, B, Q, R = env.model.A, env.model.B, env.model.Q, env.model.R
    K_star, _, _ = dlqr(A, B, Q, R)
    std = [1.0, 1.0, 1.0, 0.05, 0.05, 0.05]
    K0 = np.hstack([0.1 * np.eye(3), 10.0 * np.eye(3)])
    rows = []
    for label, kw in (
        ("heravi-2017: PI (on-policy)", dict(method="policy_iteration", initial_gain=K0)),
        ("heravi-2017: LSPI (one batch)", dict(method="lspi", initial_gain=K0)),
        ("heravi-2017: VI (one batch)", dict(method="value_iteration")),
    ):
        start = time.perf_counter()
        agent = QLearningLQR(env, seed=seed, exploration_std=1.0, state_std=std, **kw).learn(samples_per_iteration=90)
        wall = time.perf_counter() - start
        samples, iters = first_samples(agent, K_star)
        rows.append(
            dict(
                n=6,
                m=3,
                p=45,
                learner=label,
                samples_to_target=samples,
                iterations_to_target=iters,
                final_error=relative_error(agent.gain, K_star),
                wall_s=wall,
            )
        )
    return rows


def rows(quick: bool = False) -> list[dict]:
    """Rows for ``python -m benchmarks``: samples and seconds to 1e-6 gain error."""
    out = []
    for r in run([2, 6] if quick else [2, 4, 6, 8, 10, 12]):
        out.append(
            {
                "benchmark": "q-learning lqr",
                "env": f"n={r['n']} {r['learner']}",
                "samples_to_1e-6": r["samples_to_target"],
                "wall_s": r["wall_s"],
            }
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--out", default="results/benchmarks/q_learning_lqr.json", help="output JSON file (git-ignored)"
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 4, 6, 8, 10, 12])
    args = parser.parse_args(argv)
    rows = run(args.sizes)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(rows, indent=2) + "\n")
    print(f"{'n':>3} {'p':>4}  {'learner':<32}{'samples':>9}{'iters':>7}{'final err':>11}{'wall [s]':>10}")
    for r in rows:
        print(
            f"{r['n']:>3} {r['p']:>4}  {r['learner']:<32}{r['samples_to_target']!s:>9}{r['iterations_to_target']!s:>7}"
            f"{r['final_error']:>11.1e}{r['wall_s']:>10.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
