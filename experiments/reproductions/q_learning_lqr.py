"""Reproduction of Heravi & Novinzadeh 2017: model-free Q-learning (value
iteration on a quadratic Q-function) vs. discrete LQR for a 1000 kg·m² satellite.

``python train.py reproduce q-learning-lqr --out DIR [--quick]`` writes
``DIR/q-learning-lqr.json``/``.md`` and the figures ``DIR/q-learning-lqr-*.png``.

The paper prints no gains or tables; its only numbers are "converges in 3–4×10⁴
iterations" and "peak wheel-4 torque ≈ 0.8 N·m" (Fig. 15). Rows whose reference is not the
paper but an independent computation or prototype measurement say so in the case name.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from agents import QLearningLQR
from agents.qlqr.truth import hewer_iterations, relative_error, riccati_gains
from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.info import policy_view
from attitude_envs.lqr import dlqr
from experiments.reproduction import Row, write_reproduction
from experiments.reproductions import q_learning_lqr_plots as plots
from experiments.reproductions.q_learning_lqr_nonlinear import nonlinear_rows

PAPER = "q-learning-lqr"
#: the reproduced paper's citation, on the outputs' "Source:" line
SOURCE = (
    "Taji Heravi, F. and Basohbat Novinzadeh, A. (2017). Design of satellite attitude control using a "
    "model-free optimal control method. Journal of Space Science and Technology 10(3) (in Persian; title translated)"
)
STATE_STD = np.array(
    [1.0, 1.0, 1.0, 0.05, 0.05, 0.05]
)  # assumed (the paper's sample points): q ~ N(0,1), ω ~ N(0, 0.05²)
BETA_DEG = 20.0  # the paper's eq. 75


def wheel_torques(u_body: np.ndarray, beta_deg: float = BETA_DEG) -> np.ndarray:
    """Heravi & Novinzadeh 2017, eq. 66: ``T = D⁺ [u_x/cos β, u_y/cos β, u_z/sin β]`` (rows of ``u_body``, N·m)."""
    D = np.array([[1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, -1.0], [1.0, 1.0, 1.0, 1.0]])
    b = np.radians(beta_deg)
    scaled = np.atleast_2d(u_body) / np.array([np.cos(b), np.cos(b), np.sin(b)])
    return scaled @ np.linalg.pinv(D).T


class GainSchedule:
    """Policy ``u_k = −K_k x_k`` with ``K_k`` the k-th gain of a list (the last one after
    it ends): the paper's controller, which applies the gain of VI iteration k at step k."""

    def __init__(self, gains: np.ndarray, action_scale: float, name: str) -> None:
        self.gains, self.scale, self.name, self.k = gains, action_scale, name, 0

    def reset(self, seed: int | None = None) -> None:
        self.k = 0

    def act(self, obs: np.ndarray, info: dict) -> np.ndarray:
        K = self.gains[min(self.k, len(self.gains) - 1)]
        self.k += 1
        return np.clip(-K @ np.asarray(info["measured"], dtype=float) / self.scale, -1.0, 1.0)


def simulate(policy, steps: int) -> dict[str, np.ndarray]:
    """Run ``policy`` on LinearSystem-v0 (heravi-2017 preset: Euler plant, paper's x₀) for ``steps``."""
    env = LinearSystemEnv(preset="heravi-2017", episode_steps=steps, divergence_threshold=1e9)
    obs, info = env.reset(seed=0)
    policy.reset(0)
    X, U, J = [info["truth"]["state"]], [], 0.0
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        X.append(info["truth"]["state"])
        U.append(info["truth"]["applied"])
        J += info["cost"]
        if terminated or truncated:
            break
    X, U = np.array(X), np.array(U)
    norms = np.linalg.norm(X, axis=1)
    above = np.nonzero(norms >= 0.01 * norms[0])[0]
    return {"X": X, "U": U, "J": J, "settle_s": 0.01 * (above[-1] + 1), "T": wheel_torques(U)}


def reproduce(out_dir: Path, quick: bool = False) -> list:
    """Run the reproduction; returns the rows written (``quick``: shorter runs, no nonlinear case)."""
    out_dir = Path(out_dir)
    env = LinearSystemEnv(preset="heravi-2017")
    A, B, Q, R = env.model.A, env.model.B, env.model.Q, env.model.R
    K_star, _, _ = dlqr(A, B, Q, R)
    iterations = 40_000 if quick else 100_000
    rows: list[Row] = []

    # --- the paper's method: value iteration from H = 0, one batch of 90 one-step samples reused
    vi = QLearningLQR(env, method="value_iteration", seed=0, state_std=STATE_STD, exploration_std=1.0, tol=1e-12)
    vi.learn(max_iterations=iterations, samples_per_iteration=90)
    gains = np.array([h["gain"] for h in vi.history])
    ric = riccati_gains(A, B, Q, R, len(gains))
    err = np.array([relative_error(k, K_star) for k in gains])
    ric_err = np.array([relative_error(k, K_star) for k in ric])
    track = max(relative_error(gains[j], ric[j]) for j in range(1, len(gains)))
    case = "linear Euler plant, Q=I6, R=I3"
    vi_name = "Q-learning VI (90 samples, σ_η=1 N·m)"
    rows += [
        Row(
            f"{case}; ref: Riccati recursion from P = 0 (computed)",
            vi_name,
            "rel. gain error vs DARE at 3e4 iterations",
            1.2e-4,
            float(err[29_999]),
            0.05,
        ),
        Row(
            f"{case}; ref: Riccati recursion from P = 0 (computed)",
            vi_name,
            "rel. gain error vs DARE at 4e4 iterations",
            1.7e-5,
            float(err[39_999]),
            0.05,
        ),
        Row(
            f"{case}; ref: acceptance bound (≤ 1e-5)",
            vi_name,
            "max rel. difference from Riccati recursion (all iterations)",
            None,
            track,
            None,
        ),
        Row(case, vi_name, "env samples used", None, float(vi.samples_used), None),
    ]
    first = int(np.argmax(err < 1e-8)) + 1 if np.any(err < 1e-8) else None
    if first is not None:
        rows.append(
            Row(
                f"{case}; ref: independent prototype (measured)",
                vi_name,
                "iterations to rel. gain error 1e-8",
                63_613,
                float(first),
                0.01,
            )
        )
    rows.append(Row(case, vi_name, "final rel. gain error vs DARE", None, float(err[-1]), None))

    # --- the paper's own probe (σ = 1e-3 N·m: its n = (0, 10⁻³) read as a standard deviation)
    small = QLearningLQR(env, method="value_iteration", seed=1, state_std=STATE_STD, exploration_std=1e-3, tol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the agent warns that this probe is small: that is the point here
        small.learn(max_iterations=30_000, samples_per_iteration=90)
    rows.append(
        Row(
            f"{case}; paper's probe",
            "Q-learning VI (90 samples, σ_η=1e-3 N·m)",
            "rel. gain error vs DARE at 3e4 iterations",
            1.2e-4,
            relative_error(small.history[29_999]["gain"], K_star),
            0.05,
        )
    )

    # --- improvements: LSTD-Q policy iteration (off-policy, one batch) and CE, same plant
    K0 = np.hstack([0.1 * np.eye(3), 10.0 * np.eye(3)])  # small stabilizing PD gain (u = −Kx; K = 0 is not)
    lspi = QLearningLQR(env, method="lspi", seed=2, initial_gain=K0, state_std=STATE_STD, exploration_std=1.0)
    lspi.learn(samples_per_iteration=90)
    pi = QLearningLQR(env, method="policy_iteration", seed=3, initial_gain=K0, state_std=STATE_STD, exploration_std=1.0)
    pi.learn(samples_per_iteration=90)
    ce_err = relative_error(lspi.certainty_equivalence_gain(), K_star)
    rows += [
        Row(
            f"{case}; ref: Hewer PI from K0",
            "Q-learning LSPI (90 samples)",
            "PI iterations to 1e-8",
            float(hewer_iterations(A, B, Q, R, K0)),
            float(next(i + 1 for i, h in enumerate(lspi.history) if relative_error(h["gain"], K_star) < 1e-8)),
            0.0,
        ),
        Row(
            case,
            "Q-learning LSPI (90 samples)",
            "final rel. gain error vs DARE",
            None,
            relative_error(lspi.gain, K_star),
            None,
        ),
        Row(
            case,
            "certainty equivalence (same 90 samples)",
            "rel. gain error vs DARE",
            None,
            ce_err,
            None,
        ),
    ]

    # --- closed loop from the paper's initial condition (eq. 74 read scalar-first: it gives the paper's peak torque)
    steps = 10_000 if quick else 100_000  # the peak torques occur near t = 59 s
    sim = {
        "DLQR (DARE K*)": simulate(GainSchedule(K_star[None], 2.0, "dlqr"), steps),
        "Riccati recursion from P=0": simulate(GainSchedule(ric, 2.0, "riccati"), steps),
        "Q-learning VI (learned, model-free)": simulate(GainSchedule(gains, 2.0, "q-vi"), steps),
    }
    ref_j = {
        "DLQR (DARE K*)": 9.91e3,
        "Riccati recursion from P=0": 2.103e4,
        "Q-learning VI (learned, model-free)": 2.103e4,
    }
    ref_t4 = {
        "DLQR (DARE K*)": 1.260,
        "Riccati recursion from P=0": 0.760,
        "Q-learning VI (learned, model-free)": 0.761,
    }
    traj_case = "paper x0 (scalar-first q), linear plant"
    for name, s in sim.items():
        if name.startswith("Q-learning"):
            rows.append(
                Row(
                    traj_case,
                    name,
                    "peak wheel-4 torque [N·m] (paper Fig. 15)",
                    0.8,
                    float(np.max(np.abs(s["T"][:, 3]))),
                    0.10,
                )
            )
        rows.append(
            Row(
                f"{traj_case}; ref: independent simulation (computed)",
                name,
                "peak wheel-4 torque [N·m]",
                ref_t4[name],
                float(np.max(np.abs(s["T"][:, 3]))),
                0.02,
            )
        )
        if not quick:
            rows.append(
                Row(
                    f"{traj_case}; ref: independent simulation (computed)",
                    name,
                    "J = Σ xᵀQx + uᵀRu (1e5 steps)",
                    ref_j[name],
                    float(s["J"]),
                    0.02,
                )
            )
            rows.append(
                Row(
                    f"{traj_case}; ref: independent simulation (computed)",
                    name,
                    "time to ‖x‖ < 1% ‖x0‖ [s]",
                    {"DLQR (DARE K*)": 309.0}.get(name, 364.0),
                    float(s["settle_s"]),
                    0.02,
                )
            )

    # --- nonlinear env (ReactionWheel-v0, heravi-2017 preset)
    if not quick:
        rows += nonlinear_rows(
            episode_duration_s=600.0
        )  # the nonlinear maneuver settles in ≈ 500 s (independent simulation)

    out_dir.mkdir(parents=True, exist_ok=True)
    plots.convergence(out_dir / f"{PAPER}-convergence.png", err, ric_err, pi, ce_err, K_star)
    plots.trajectories(out_dir / f"{PAPER}-trajectories.png", sim)
    notes = _notes(quick)
    write_reproduction(out_dir, PAPER, SOURCE, rows, notes)
    return rows


def _notes(quick: bool) -> str:
    return (
        "Plant: the paper's forward-Euler model (eqs. 60–62, Δt = 0.01 s, J = diag(1000, 1000, 800) kg·m², Q = I6, R = I3), "
        "LinearSystem-v0 preset 'heravi-2017'. The learner is `agents.QLearningLQR`; it sees only (x, applied u, cost, x⁺).\n\n"
        "* The paper prints no gains, kernels or tables. Its only numbers are the convergence in 3–4×10⁴ iterations and "
        "the peak wheel-4 torque ≈ 0.8 N·m (read off Fig. 15, hence the 10 % tolerance). Rows marked '(computed)' "
        "compare with an independent model-based simulation of the same setup, rows marked 'independent prototype "
        "(measured)' with a measurement on an independent prototype learner.\n"
        "* Our value iteration reuses ONE batch of 90 one-step samples for every iteration (fitted-Q iteration); the "
        "paper used ≥ 45 fresh samples per iteration for ~10⁵ iterations (≈ 4.5×10⁶ samples). Both follow the Riccati "
        "recursion from P = 0 exactly, so the iteration counts are the same; the data are 5×10⁴ times fewer.\n"
        "* The learned controller is applied as the paper does: the gain of VI iteration k at step k (time-varying, "
        "starting from K = 0). That is why its peak torque (≈ 0.76 N·m) is below the steady DLQR's (1.26 N·m) and "
        "matches the paper's 0.8 N·m. The simulation applies the gains without exploration noise.\n"
        "* With the paper's probe σ_η = 10⁻³ N·m the regression is less well conditioned; the gain error at 3×10⁴ "
        "iterations still matches the Riccati recursion.\n"
        "* LSTD-Q policy iteration is numerically ill-posed on this plant without scaling (an independent "
        "prototype measured cond ≈ 10¹³); with per-coordinate feature scaling and a QR-projected LSTD solve it converges in the Hewer "
        "iteration count from K0 = [0.1 I, 10 I] on 90 samples.\n"
        "* The paper's claim that the method fails on the nonlinear model is not reproduced: on "
        "ReactionWheel-v0 (exact gyrostat, RK4) the agent learns the ZOH-discretized LQR gain from near-target data "
        "and completes the maneuver with the LQR baseline's cost (rows 'ReactionWheel-v0')."
        + (" Quick mode: shortened runs, nonlinear rows omitted." if quick else "")
    )
