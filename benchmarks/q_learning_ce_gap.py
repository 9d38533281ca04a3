"""Gap of the model-free Q-learner to certainty equivalence (CE) on the same noisy data.

    PYTHONPATH=. python benchmarks/q_learning_ce_gap.py [--out results/benchmarks/q_learning_ce_gap.json]
        [--seeds 8] [--systems krauth3x2 dean3x3 rand10x2] [--sigma 0.1 1] [--T 1000 10000 100000]

Set-up (off-policy, single batch): one trajectory of T steps of ``x⁺ = Ax + Bu + w``,
``w ~ N(0, σ_w² I)``, behaviour ``u = −K₀x + η``, σ_η = 1, from x₀ = 0 (K₀ = 0 for stable A,
pole placement otherwise), stage cost ``xᵀQx + uᵀRu``. Every learner is fitted to the *same*
batch per seed (``learn(data=...)``): off-policy LSPI with plain LSTD-Q + constant
(``td_estimator="lstd"``) and with feasible-GLS LSTD-Q (``"lstd_gls"``), and CE
(least-squares model + Riccati, costs fitted from the data). Reported per cell: median
relative gain error of each, the median over seeds of the per-seed ratio error/CE error
(the "CE gap"), and failures (``H_uu`` not positive definite, or an unstable gain).
The trajectory is simulated with NumPy (the same equations as LinearSystem-v0) for speed.
Not a test.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the benchmark instances live with the tests

from qlqr_systems import benchmark_systems, linear_env, random_system, stabilizing_gain  # noqa: E402

from agents import QLearningLQR  # noqa: E402
from agents.qlqr.data import Transitions  # noqa: E402
from agents.qlqr.estimators import InsufficientExcitationError, NotPositiveDefiniteError  # noqa: E402
from agents.qlqr.truth import relative_error  # noqa: E402
from attitude_envs.lqr import dlqr  # noqa: E402

LEARNERS = {"lstd": {"td_estimator": "lstd"}, "lstd_gls": {"td_estimator": "lstd_gls"}}


def systems() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Test instances krauth3x2 and dean3x3 of ``tests/qlqr_systems.py`` and rand10x2 (ρ(A) = 1.05, seed 0)."""
    out = {k: v for k, v in benchmark_systems().items() if k in ("krauth3x2", "dean3x3")}
    out["rand10x2"] = random_system(0, 10, 2, 1.05)
    return out


def trajectory(A, B, Q, R, K0, sigma_w: float, T: int, seed: int) -> Transitions:
    """One trajectory of T transitions under ``u = −K₀x + η`` (σ_η = 1) from x₀ = 0."""
    rng = np.random.default_rng(seed)
    n, m = B.shape
    eta = rng.standard_normal((T, m))
    w = sigma_w * rng.standard_normal((T, n))
    X, U, Xn = np.empty((T, n)), np.empty((T, m)), np.empty((T, n))
    x = np.zeros(n)
    for k in range(T):
        u = eta[k] - K0 @ x
        X[k], U[k] = x, u
        x = A @ x + B @ u + w[k]
        Xn[k] = x
    r = np.einsum("ki,ij,kj->k", X, Q, X) + np.einsum("ki,ij,kj->k", U, R, U)
    return Transitions(X, U, r, Xn)


def one_cell(name: str, system, sigma_w: float, T: int, seeds: int) -> dict:
    A, B, Q, R = system
    K0 = stabilizing_gain(A, B)
    K_star, _, _ = dlqr(A, B, Q, R)
    env = linear_env(A, B, Q, R)  # only for the agent's interface; the data are given
    errors: dict[str, list[float]] = {k: [] for k in (*LEARNERS, "ce")}
    wall = dict.fromkeys(errors, 0.0)
    for seed in range(seeds):
        data = trajectory(A, B, Q, R, K0, sigma_w, T, seed)
        for label, kw in LEARNERS.items():
            agent = QLearningLQR(env, method="lspi", seed=seed, initial_gain=K0, sampling="trajectory", tol=1e-9, **kw)
            start = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    agent.learn(data=data)
                stable = np.max(np.abs(np.linalg.eigvals(A - B @ agent.gain))) < 1.0
                errors[label].append(relative_error(agent.gain, K_star) if stable else np.nan)
            except (NotPositiveDefiniteError, InsufficientExcitationError):
                errors[label].append(np.nan)
            wall[label] += time.perf_counter() - start
        start = time.perf_counter()
        ref = agent.compare_with_certainty_equivalence(optimal_gain=K_star)
        wall["ce"] += time.perf_counter() - start
        errors["ce"].append(ref["ce_error"])
    e = {k: np.array(v) for k, v in errors.items()}
    row = {"system": name, "sigma_w": sigma_w, "T": T, "seeds": seeds}
    for k, v in e.items():
        row[f"median_error_{k}"] = float(np.median(v[np.isfinite(v)])) if np.any(np.isfinite(v)) else None
        row[f"failures_{k}"] = int(np.sum(~np.isfinite(v)))
        row[f"wall_s_{k}"] = wall[k] / seeds
    for k in LEARNERS:
        ratio = e[k] / e["ce"]
        ok = np.isfinite(ratio)
        row[f"gap_{k}"] = float(np.median(ratio[ok])) if np.any(ok) else None
    both = np.isfinite(e["lstd"]) & np.isfinite(e["lstd_gls"])
    row["gls_better_fraction"] = float(np.mean(e["lstd_gls"][both] < e["lstd"][both])) if np.any(both) else None
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    # results/ is git-ignored; benchmarks/q_learning_ce_gap.json (cited in the README) is committed on purpose
    parser.add_argument("--out", default="results/benchmarks/q_learning_ce_gap.json", help="output JSON file")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--systems", nargs="+", default=["krauth3x2", "dean3x3", "rand10x2"])
    parser.add_argument("--sigma", nargs="+", type=float, default=[0.1, 1.0])
    parser.add_argument("--T", nargs="+", type=int, default=[1_000, 10_000, 100_000])
    args = parser.parse_args(argv)
    table = systems()
    rows = []
    for name in args.systems:
        for sigma_w in args.sigma:
            for T in args.T:
                row = one_cell(name, table[name], sigma_w, T, args.seeds)
                rows.append(row)
                print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}), flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump({"rows": rows}, fh, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
