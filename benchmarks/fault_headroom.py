"""How much better than the LQR can any controller do under a single-wheel outage?

    PYTHONPATH=. python benchmarks/fault_headroom.py [--seeds 20] [--shooting-seeds 5]

ReactionWheel-v0, pyramid-4wheel, body-torque actions, random targets within 60°, wheel 0 out from
``onset_s`` (2 s: the packaged ``wheel-failure`` scenario's onset; 10 s: the RL-quality test's).
Measured on the true (nonlinear, RK4) env, J = Σ info["cost"]:

- ``lqr``: the fault-unaware exact-ZOH LQR, the baseline an agent must beat;
- ``lqr x alpha``: the same gain scaled, fault-unaware (the best *linear* policy an agent of
  the LQR's class could find);
- ``oracle``: the LQR gain, told which wheel fails and when, re-allocating the demand over the
  three healthy wheels from the onset (applied torque = the LQR's demand) — the optimum of the
  linearized problem with perfect fault knowledge, since the cost weights the *applied* torque;
- ``oracle + shooting``: the oracle plus an open-loop torque correction (piecewise constant over
  5 s for the first 30 s, where most of J accrues (printed): 3 axes × 6 pieces) optimized by L-BFGS-B
  on the true nonlinear episode — the best found nonlinear improvement, seed by seed.

The gap lqr − min(everything) bounds, empirically, what a fault-randomized agent could gain over
the LQR on this scenario. Writes ``results/benchmarks/fault_headroom.json`` (``--out``; the README cites
the committed ``benchmarks/fault_headroom.json``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import scipy.optimize

import attitude_envs  # noqa: F401
from baselines.lqr import LQRPolicy

ENV = "attitude_envs/ReactionWheel-v0"
ALPHAS = (0.8, 0.9, 1.1, 1.25, 1.5)
PIECE_S = 5.0
PIECES = 6  # the correction acts over the first PIECE_S · PIECES seconds


def make(onset_s: float | None):
    faults = [] if onset_s is None else [{"kind": "outage", "target": "actuator", "index": 0, "onset_s": onset_s}]
    return gym.make(ENV, preset="pyramid-4wheel", action_frame="body", faults=faults)


def episode_cost(env, seed: int, gain: np.ndarray, remap=None, correction=None, until_s: float = np.inf) -> float:
    """J of ``T = −K x (+ correction)``, re-mapped by ``remap(t)`` (the oracle's allocation),
    accrued until ``until_s`` (default: the whole episode)."""
    u = env.unwrapped
    limit = u.model.params.max_wheel_torque_nm
    obs, _ = env.reset(seed=seed)
    total, step = 0.0, 0
    while True:
        t = step * u.control_dt_s
        demand = -gain @ np.asarray(obs, float)[: gain.shape[1]]
        if correction is not None and t < PIECE_S * len(correction):
            demand = demand + correction[int(t // PIECE_S)]
        if remap is not None:
            demand = remap(t) @ demand
        obs, _, terminated, truncated, info = env.step((demand / limit).astype(np.float32))
        total += info["cost"] if t < until_s else 0.0
        step += 1
        if terminated or truncated:
            return total


def oracle_remap(env, onset_s: float, failed: int = 0):
    """Body-torque command that makes the *applied* torque equal the demand once ``failed`` is out:
    applied = M T with M = −A H A_alloc (H zeroes the failed wheel), so command M⁻¹ T."""
    u = env.unwrapped
    health = np.ones(u.model.params.wheel_axes.shape[1])
    health[failed] = 0.0
    M = -u.model.params.wheel_axes @ np.diag(health) @ u.model.allocation
    inverse = np.linalg.inv(M)
    eye = np.eye(3)
    return lambda t: inverse if t >= onset_s else eye


def shooting(env, seed: int, gain: np.ndarray, remap, start: float) -> tuple[float, int]:
    pieces = PIECES
    scale = 1e-3  # N·m per unit of the optimizer's variable

    def f(z: np.ndarray) -> float:
        return episode_cost(env, seed, gain, remap, z.reshape(pieces, 3) * scale)

    res = scipy.optimize.minimize(f, np.zeros(pieces * 3), method="L-BFGS-B", options={"maxiter": 30, "eps": 1e-4})
    return min(float(res.fun), start), int(res.nfev)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--shooting-seeds", type=int, default=5)
    parser.add_argument("--onsets", default="2,10")
    # results/ is git-ignored; benchmarks/fault_headroom.json (cited in the README) is committed on purpose
    parser.add_argument("--out", default="results/benchmarks/fault_headroom.json", help="output JSON file")
    args = parser.parse_args()
    seeds = range(args.seeds)
    nominal = make(None)
    gain = LQRPolicy(nominal).gain
    results: dict = {
        "seeds": args.seeds,
        "J_lqr_nominal": float(np.mean([episode_cost(nominal, s, gain) for s in seeds])),
    }
    early = np.mean([episode_cost(nominal, s, gain, until_s=PIECE_S * PIECES) for s in seeds])
    results["share_of_J_in_correction_window"] = float(early / results["J_lqr_nominal"])
    print(
        f"nominal: LQR J = {results['J_lqr_nominal']:.2f} (mean over {args.seeds} seeds), "
        f"{100 * early / results['J_lqr_nominal']:.1f} % of it in the first {PIECE_S * PIECES:g} s"
    )
    for onset in (float(x) for x in args.onsets.split(",")):
        env = make(onset)
        remap = oracle_remap(env, onset)
        lqr = np.array([episode_cost(env, s, gain) for s in seeds])
        oracle = np.array([episode_cost(env, s, gain, remap) for s in seeds])
        scaled = {a: float(np.mean([episode_cost(env, s, a * gain) for s in seeds]) / lqr.mean()) for a in ALPHAS}
        case = {
            "onset_s": onset,
            "J_lqr": float(lqr.mean()),
            "J_oracle": float(oracle.mean()),
            "oracle_ratio": float(oracle.mean() / lqr.mean()),
            "scaled_gain_ratio": scaled,
        }
        print(
            f"wheel 0 out at {onset:g} s: LQR J = {lqr.mean():.2f}, oracle {oracle.mean():.2f} "
            f"({oracle.mean() / lqr.mean():.4f}); best scaled gain {min(scaled.values()):.4f}"
        )
        shots = []
        for s in range(args.shooting_seeds):
            best, nfev = shooting(env, s, gain, remap, float(oracle[s]))
            shots.append({"seed": s, "J_lqr": float(lqr[s]), "J_oracle": float(oracle[s]), "J_shooting": best})
            print(f"  seed {s}: LQR {lqr[s]:.3f}, oracle {oracle[s]:.3f}, oracle+shooting {best:.3f} ({nfev} episodes)")
        if shots:
            case["shooting"] = shots
            case["shooting_ratio"] = sum(r["J_shooting"] for r in shots) / sum(r["J_lqr"] for r in shots)
            print(f"  shooting seeds: ΣJ oracle+shooting / ΣJ LQR = {case['shooting_ratio']:.4f}")
        results[f"outage_{onset:g}s"] = case
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
