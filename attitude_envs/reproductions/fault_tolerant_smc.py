"""Reproduction of spec 002 (Sadigh et al., fault-tolerant AMNFTSMC), Table 2 and claims.

``python train.py reproduce fault-tolerant-smc --out DIR [--quick]`` runs the three
controllers (AMNFTSMC, MNFTSMC, FTSMC stand-in) over two orbits (12 038 s, dt 0.1 s,
magnetorquer effectiveness diag(0.9, 0.7, 0.6) from 50 s through the shared fault layer)
in two configurations:

* ``as-printed`` — every printed number: sign(S) switching, Ĥ(0) = 0.605, ρ = 0.0015,
  the paper's allocation (16)–(17) on the whole demand, eq. (9) as printed, full eq. (39)
  disturbance, ΔJ(t) of eq. (35), circular orbit at ω0 (the paper's model). Spec §7 found
  that x/z control is lost: the run reports what happens.
* ``consistent`` — the spec's physically consistent choice (§6 items 2, 8, 9, §7): the
  physical dipole field (Wertz form), disturbance × 0.1, the "xz" allocation (the wheel
  alone takes the y demand), a boundary layer δ = 1e-3 rad/s, and switching gains sized to
  the actuators (see ``CONSISTENT_GAINS``);
* ``consistent-eq9`` — the same with eq. (9) as printed (y and z of the field flipped
  relative to the physical dipole in the LVLH frame of ω_oi = [0, −ω0, 0]): the field the
  spec's prototype used, to show how much the x/z outcome depends on the field geometry.

Metrics: eqs. (42)–(44) on applied signals (ASM also on commanded dipoles), chattering
(total variation of the normalized command), time to recover ‖q_e‖ ≤ 0.01 after the
fault, final/max error. Paper values carry a null tolerance: spec §5.4/§7 show Table 2
cannot be reached (its ASM exceeds what saturated dipoles can give).
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from attitude_envs.evaluation.reproduction import Row, write_reproduction

PAPER = "fault-tolerant-smc"
SEED_FILE = "seeds/002_7b19fb18a362e12d.txt"
CONTROLLERS = ("AMNFTSMC", "MNFTSMC", "FTSMC")
# Table 2 as reconstructed in spec 002 §5.4: RMS (√s), AST (N·m·s), ASM (A·m²·s)
TABLE2 = {
    "FTSMC": {"RMS": 2.0739, "AST": 2.9656, "ASM": 8.4347e4},
    "MNFTSMC": {"RMS": 3.9257, "AST": 2.9980, "ASM": 8.6391e4},
    "AMNFTSMC": {"RMS": 1.6075, "AST": 2.6037, "ASM": 6.8464e4},
}
PAPER_ENV = {
    "orbit": {"model": "circular", "mean_anomaly_deg": 0.0},
    "control_dt_s": 0.1,
}
CONFIGS = {
    "as-printed": {
        "env": {**PAPER_ENV, "field_model": "dipole-printed", "disturbance_scale": 1.0},
        "gains": {},
    },
    "consistent": {
        "env": {**PAPER_ENV, "field_model": "dipole", "disturbance_scale": 0.1},
        "gains": {"boundary_layer": 1e-3, "allocation": "xz"},
    },
    # sensitivity: `consistent` with eq. (9) exactly as printed (the spec's own prototype field)
    "consistent-eq9": {
        "env": {**PAPER_ENV, "field_model": "dipole-printed", "disturbance_scale": 0.1},
        "gains": {"boundary_layer": 1e-3, "allocation": "xz"},
    },
}
# Consistent switching gains (spec §6 item 2): the printed (ρ1 + 1)Ĥ(0) = 0.606 N·m is
# ~2600× the wheel's 2.3e-4 N·m. AMNFTSMC starts from the same switching gain as MNFTSMC,
# (ρ1 + 1)Ĥ(0) = ρ2, and adapts at the spec's default rate μ = 0.1 (§4.8), so any
# difference between the two laws comes from the adaptation.
CONSISTENT_GAINS = {"h0": 0.0015 / 1.0015, "mu": 0.1}
RECOVER_THRESHOLD = 0.01
FAULT_TIME_S = 50.0


def _policy(name: str, env, gains: dict):
    from baselines.sliding_mode import AMNFTSMCPolicy, FTSMCStandInPolicy, MNFTSMCPolicy

    cls = {"AMNFTSMC": AMNFTSMCPolicy, "MNFTSMC": MNFTSMCPolicy, "FTSMC": FTSMCStandInPolicy}[name]
    return cls(env, record=True, **gains)


def run_case(config: str, controller: str, duration_s: float, seed: int = 0) -> dict:
    """One episode; returns metrics and down-sampled histories for the plots."""
    import gymnasium as gym

    import attitude_envs  # noqa: F401
    from attitude_envs.envs.magnetorquer import PAPER_FAULTS
    from attitude_envs.evaluation.tracking_metrics import run_traced, tracking_metrics

    cfg = CONFIGS[config]
    env = gym.make("attitude_envs/Magnetorquer-v0", faults=PAPER_FAULTS, episode_duration_s=duration_s, **cfg["env"])
    gains = dict(cfg["gains"])
    if config.startswith("consistent") and controller == "AMNFTSMC":
        gains.update(CONSISTENT_GAINS)
    policy = _policy(controller, env, gains)
    trace = run_traced(env, policy, seed=seed)
    p = env.unwrapped.model.params
    met = tracking_metrics(trace, p.max_dipole_am2, p.max_wheel_torque_nm, FAULT_TIME_S, RECOVER_THRESHOLD)
    t_f = env.unwrapped.model.reference.t_final_s
    err = np.linalg.norm(trace.q_e, axis=1)
    hold = trace.time_s >= t_f
    met["max_error_after_slew"] = float(np.max(err[hold])) if np.any(hold) else float(np.max(err))
    met["final_gain"] = float(policy.gain)
    met["terminated"] = float(trace.terminated)
    stride = max(1, len(trace.time_s) // 4000)
    return {
        "config": config,
        "controller": controller,
        "metrics": met,
        "t": trace.time_s[::stride],
        "q_e": trace.q_e[::stride],
        "dipole": trace.dipole_am2[::stride],
        "wheel": trace.wheel_torque_nm[::stride],
        "gain": np.asarray(policy.history.gain)[::stride],
    }


def _plot(results: list[dict], out_dir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for config in CONFIGS:
        rs = [r for r in results if r["config"] == config]
        if not rs:
            continue
        fig, ax = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
        for r in rs:
            ax[0].semilogy(r["t"], np.maximum(np.linalg.norm(r["q_e"], axis=1), 1e-6), label=r["controller"])
            ax[2].plot(r["t"], r["wheel"] * 1e6, label=r["controller"], lw=0.6)
            if r["controller"] == "AMNFTSMC":
                for i, axis in enumerate("xyz"):
                    ax[1].plot(r["t"], r["dipole"][:, i], label=f"m_{axis} (AMNFTSMC)", lw=0.6)
                ax[3].plot(r["t"], r["gain"], label="Ĥ (AMNFTSMC)")
        ax[0].axvline(FAULT_TIME_S, color="k", ls=":", lw=0.8)
        ax[0].set_ylabel("‖q_e‖ = ‖q − q_d‖")
        ax[1].set_ylabel("applied dipole [A·m²]")
        ax[2].set_ylabel("wheel torque [µN·m]")
        ax[3].set_ylabel("adaptive gain Ĥ")
        ax[3].set_xlabel("time [s]")
        for a in ax:
            a.legend(fontsize=7, loc="upper right")
            a.grid(alpha=0.3)
        fig.suptitle(f"spec 002 reproduction, {config}: fault E = diag(0.9, 0.7, 0.6) at 50 s", fontsize=10)
        fig.tight_layout()
        path = out_dir / f"{PAPER}-{config}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def reproduce(out_dir: Path, quick: bool = False) -> list[Row]:
    """Run both configurations × three controllers; write JSON, markdown and plots."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    duration = 100.0 if quick else None
    jobs = [(c, k) for c in CONFIGS for k in CONTROLLERS]
    if duration is None:
        import gymnasium as gym

        import attitude_envs  # noqa: F401

        duration = gym.make("attitude_envs/Magnetorquer-v0", **PAPER_ENV).unwrapped.episode_duration_s
    with ProcessPoolExecutor(max_workers=min(len(jobs), os.cpu_count() or 1)) as pool:
        results = list(pool.map(run_case, *zip(*jobs, strict=True), [duration] * len(jobs)))
    rows: list[Row] = []
    for r in results:
        met = r["metrics"]
        paper = TABLE2[r["controller"]]
        name = "FTSMC (stand-in)" if r["controller"] == "FTSMC" else r["controller"]
        for metric in ("RMS", "AST", "ASM"):
            rows.append(Row(r["config"], name, metric, None if quick else paper[metric], met[metric], None))
        for metric in (
            "ASM_commanded",
            "chattering",
            "time_to_recover_s",
            "max_error_after_slew",
            "final_error_deg",
            "J",
            "final_gain",
            "terminated",
        ):
            if metric == "final_gain" and r["controller"] != "AMNFTSMC":
                continue  # only the adaptive law has a gain Ĥ
            rows.append(Row(r["config"], name, metric, None, met[metric], None))
    by = {(r["config"], r["controller"]): r["metrics"] for r in results}
    claims = []
    for config in CONFIGS:
        a, m = by[(config, "AMNFTSMC")], by[(config, "MNFTSMC")]
        checks = {
            "claim: AMNFTSMC RMS < MNFTSMC RMS": a["RMS"] < m["RMS"],
            "claim: AMNFTSMC chattering < MNFTSMC chattering": a["chattering"] < m["chattering"],
            "claim: both track after the fault (max ‖q_e‖ after the slew < 0.05)": max(
                a["max_error_after_slew"], m["max_error_after_slew"]
            )
            < 0.05,
        }
        for label, ok in checks.items():
            rows.append(Row(config, "AMNFTSMC vs MNFTSMC", label, 1.0, float(ok), 0.0))
            claims.append(f"{config}: {label}: {'holds' if ok else 'does NOT hold'}")
    plots = _plot(results, out_dir)
    notes = _notes(duration, claims, plots, by)
    write_reproduction(out_dir, PAPER, SEED_FILE, rows, notes)
    return rows


def _observations(by: dict) -> list[str]:
    """Sentences computed from this run's numbers (what happened, per configuration)."""
    lines = []
    printed = [by[("as-printed", c)] for c in CONTROLLERS if ("as-printed", c) in by]
    if printed:
        ast = [m["AST"] for m in printed]
        asm = [m["ASM"] for m in printed]
        lines.append(
            f"- as-printed: AST = {min(ast):.3f}–{max(ast):.3f} N·m·s (Table 2: 2.60–3.00; the wheel alone at "
            f"±2.3e-4 N·m for the whole run gives {2.3e-4 * 12037.9:.2f}): sign(S) keeps the wheel bang-bang. "
            f"ASM = {min(asm):.4g}–{max(asm):.4g} A·m²·s, near Table 2's values divided by 10 (6.8–8.6 × 10³), "
            "which supports the spec's reading that the printed exponent should be 10³."
        )
    for config in CONFIGS:
        ms = [by[(config, c)] for c in CONTROLLERS if (config, c) in by]
        if ms:
            worst = max(m["max_error_after_slew"] for m in ms)
            lost = worst > 0.05
            lines.append(
                f"- {config}: largest ‖q_e‖ after the slew {worst:.3g} → "
                + ("x/z tracking is lost (the magnetorquers cannot make torque along b)." if lost else "tracking kept.")
            )
    return lines


def _notes(duration: float, claims: list[str], plots: list[Path], by: dict) -> str:
    return "\n".join(
        [
            f"Episodes of {duration:.1f} s (dt 0.1 s, RK4), seed 0, circular orbit (the paper's constant ω0), "
            "reference: spec §5.1 defaults Δθ = [10°, 20°, 10°], t_f = 1200 s. Fault: magnetorquer "
            "effectiveness diag(0.9, 0.7, 0.6) from 50 s (shared fault layer).",
            "",
            "Paper values: Table 2 as reconstructed by spec 002 §5.4. Tolerances are null because the spec "
            "shows they cannot be reached: the printed ASM (6.8–8.6 × 10⁴ A·m²·s) exceeds the maximum "
            "3 × 0.5 A·m² × 12 038 s = 1.81 × 10⁴ that saturated dipoles can give, the controller parameters "
            "γ1, γ2, r, ϵ, κ, μ, p, q and the trajectory are not printed, and with the printed disturbance "
            "the x/z magnetic authority is marginal (spec §6 item 8).",
            "",
            "`as-printed`: all printed numbers (sign(S), Ĥ(0) = 0.605, ρ1 = ρ2 = 0.0015, allocation (16)–(17), "
            "eq. (9) as printed, eq. (39) disturbance at full scale, ΔJ(t) of eq. (35)). "
            "`consistent`: physical dipole field, disturbance × 0.1, 'xz' allocation, boundary layer "
            "δ = 1e-3 rad/s, AMNFTSMC with Ĥ(0) = ρ2/(1 + ρ1) (the same initial switching gain as MNFTSMC; "
            "the printed Ĥ(0) is ~2600× the wheel torque limit) and the spec's default μ = 0.1. The FTSMC row is the spec §4.7 stand-in, "
            "not the paper's reference [13].",
            "",
            "`consistent-eq9`: `consistent` with eq. (9) exactly as printed (field y, z flipped relative to "
            "the physical dipole in the paper's LVLH frame), the field of the spec's own prototype.",
            "",
            "What happened:",
            *_observations(by),
            "",
            "Qualitative claims (paper: adaptive beats non-adaptive on RMS and chattering; both keep tracking "
            "after the fault):",
            *[f"- {c}" for c in claims],
            "",
            "Chattering index: total variation of the normalized command (dipoles / 0.5 A·m², wheel / 2.3e-4 N·m) "
            "summed over the episode. Time to recover: seconds after 50 s until ‖q_e‖ ≤ 0.01 for good (NaN: "
            "never); it includes the ω_bo-surface tracking lag during the slew (spec §6 item 3).",
            "",
            "Plots: " + ", ".join(p.name for p in plots),
        ]
    )
