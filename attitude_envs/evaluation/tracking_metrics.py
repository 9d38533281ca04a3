"""Tracking metrics of Sadigh, Kashaninia & Dehghan 2022 (eqs. 42–44), chattering and recovery after a fault.

Signals are sampled once per control step of length ``dt_s`` and held over it (zero-order
hold, as the env applies them), so an integral ``∫|x| dt`` is the exact sum ``Σ|x_k| dt``.

* :func:`rms_eq42` — ``RMS = sqrt(∫_0^{T_f} ‖q_e‖² dt)`` (no 1/T_f, as printed), with the
  paper's additive error ``q_e = q − q_d`` (vector parts);
* :func:`ast_eq43` — ``AST = Σ_i ∫|T_i| dt``, i over the three magnetic torque components
  and the wheel torque, N·m·s;
* :func:`asm_eq44` — ``ASM = Σ_i ∫|m_i| dt``, A·m²·s;
* :func:`chattering_index` — total variation ``Σ_k Σ_i |u_{k+1,i} − u_{k,i}|`` of a command
  history, in the command's units (per channel normalized if ``scale`` is given);
* :func:`time_to_recover` — seconds from a fault until a tracking error re-enters and then
  stays within a threshold until the end (NaN if it never does).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from attitude_envs.info import TRUTH, policy_view


def additive_error(q: np.ndarray, q_d: np.ndarray) -> np.ndarray:
    """Sadigh, Kashaninia & Dehghan 2022's additive error ``q_e = q − q_d`` of the vector parts, both signed with w ≥ 0 (…×3)."""
    q = np.where(q[..., 3:4] < 0, -q, q)
    q_d = np.where(q_d[..., 3:4] < 0, -q_d, q_d)
    return q[..., :3] - q_d[..., :3]


def rms_eq42(q_e: np.ndarray, dt_s: float) -> float:
    """Eq. (42): ``sqrt(∫ ‖q_e‖² dt)`` of an (n×3) error history, √s."""
    return float(np.sqrt(np.sum(np.asarray(q_e) ** 2) * dt_s))


def ast_eq43(magnetic_torque_nm: np.ndarray, wheel_torque_nm: np.ndarray, dt_s: float) -> float:
    """Eq. (43): ``Σ_i ∫|T_i| dt`` over T_mx, T_my, T_mz (n×3) and T_w (n), N·m·s."""
    return float((np.sum(np.abs(magnetic_torque_nm)) + np.sum(np.abs(wheel_torque_nm))) * dt_s)


def asm_eq44(dipole_am2: np.ndarray, dt_s: float) -> float:
    """Eq. (44): ``Σ_i ∫|m_i| dt`` of an (n×3) dipole history, A·m²·s."""
    return float(np.sum(np.abs(dipole_am2)) * dt_s)


def chattering_index(commands: np.ndarray, scale=None) -> float:
    """Total variation of a command history (n×k): ``Σ_k Σ_i |u_{k+1,i} − u_{k,i}| / scale_i``."""
    u = np.asarray(commands, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    if scale is not None:
        u = u / np.asarray(scale, dtype=float)
    return float(np.sum(np.abs(np.diff(u, axis=0))))


def time_to_recover(time_s: np.ndarray, error: np.ndarray, fault_time_s: float, threshold: float) -> float:
    """Seconds after ``fault_time_s`` until ``error`` is ≤ ``threshold`` for good (NaN: never).

    0 when the error never leaves the threshold after the fault.
    """
    t = np.asarray(time_s, dtype=float)
    e = np.asarray(error, dtype=float)
    after = t >= fault_time_s
    if not np.any(after):
        raise ValueError(f"fault_time_s {fault_time_s} is after the last sample {t[-1]}")
    ta, ea = t[after], e[after]
    outside = np.nonzero(~(ea <= threshold))[0]
    if outside.size == 0:
        return 0.0
    last = outside[-1]
    if last == ea.size - 1:
        return float("nan")
    return float(ta[last + 1] - fault_time_s)


@dataclass
class EpisodeTrace:
    """Per-step history of one Magnetorquer-v0 episode (arrays after :meth:`finish`)."""

    dt_s: float
    time_s: list = field(default_factory=list)
    q_e: list = field(default_factory=list)
    error_angle_deg: list = field(default_factory=list)
    dipole_am2: list = field(default_factory=list)
    dipole_cmd_am2: list = field(default_factory=list)
    wheel_torque_nm: list = field(default_factory=list)
    wheel_cmd_nm: list = field(default_factory=list)
    magnetic_torque_nm: list = field(default_factory=list)
    cost: float = 0.0
    terminated: bool = False

    def add(self, info: dict[str, Any]) -> None:
        """Append one step from the env's full ``info`` (its ground truth ``info["truth"]``)."""
        truth = info[TRUTH]
        self.time_s.append(info["time_s"])
        self.q_e.append(additive_error(truth["state"]["attitude"], info["reference"]["attitude"]))
        self.error_angle_deg.append(truth["error_angle_deg"])
        self.dipole_am2.append(truth["applied"][:3])
        self.dipole_cmd_am2.append(info["commanded"][:3])
        self.wheel_torque_nm.append(truth["applied"][3])
        self.wheel_cmd_nm.append(info["commanded"][3])
        self.magnetic_torque_nm.append(truth["magnetic_torque_nm"])
        self.cost += info["cost"]

    def finish(self) -> EpisodeTrace:
        for name in (
            "time_s",
            "q_e",
            "error_angle_deg",
            "dipole_am2",
            "dipole_cmd_am2",
            "wheel_torque_nm",
            "wheel_cmd_nm",
            "magnetic_torque_nm",
        ):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        return self


def run_traced(env, policy, seed: int | None = None, options: dict | None = None) -> EpisodeTrace:
    """Run one episode; ``q_e`` is sampled at the end of each step (t = dt … T_f), the
    actuator signals are the ones held over each step. The policy acts on
    :func:`attitude_envs.info.policy_view` of each info; the trace records the truth."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    trace = EpisodeTrace(env.unwrapped.control_dt_s)
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        trace.add(info)
        done = terminated or truncated
        trace.terminated = bool(terminated)
    return trace.finish()


def tracking_metrics(
    trace: EpisodeTrace,
    max_dipole_am2: float,
    max_wheel_torque_nm: float,
    fault_time_s: float | None = 50.0,
    recover_threshold: float = 0.02,
) -> dict[str, float]:
    """Eqs. (42)–(44) (AST and ASM on the applied signals, ASM also on the commanded
    dipoles), the chattering index of the normalized command (dimensionless total
    variation) and the time to recover ‖q_e‖ ≤ ``recover_threshold`` after the fault."""
    dt = trace.dt_s
    scale = [max_dipole_am2] * 3 + [max_wheel_torque_nm]
    commands = np.column_stack([trace.dipole_cmd_am2, trace.wheel_cmd_nm])
    out = {
        "RMS": rms_eq42(trace.q_e, dt),
        "AST": ast_eq43(trace.magnetic_torque_nm, trace.wheel_torque_nm, dt),
        "ASM": asm_eq44(trace.dipole_am2, dt),
        "ASM_commanded": asm_eq44(trace.dipole_cmd_am2, dt),
        "chattering": chattering_index(commands, scale),
        "J": trace.cost,
        "final_error_deg": float(trace.error_angle_deg[-1]),
        "max_error_deg": float(np.max(trace.error_angle_deg)),
    }
    if fault_time_s is not None:
        err = np.linalg.norm(trace.q_e, axis=1)
        out["time_to_recover_s"] = time_to_recover(trace.time_s, err, fault_time_s, recover_threshold)
    return out
