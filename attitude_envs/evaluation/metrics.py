"""Episode metrics: the shared cost J and the papers' criteria, from an :class:`EpisodeTrace`.

Time integrals are dt-independent (they converge as the control period shrinks): state
quantities by the trapezoid rule over the step boundaries, torques exactly (held over each
step). The paper's per-sample sums (the feedback-linearization paper's Table 2 sums over solver output points) are
carried too, over the control samples, with ``sum ≈ integral / dt``.

Criteria of the feedback-linearization paper (Modares Mech. Eng.): EULERINT = ∫ α dt with α the eigen-axis error angle in degrees
(eqs. 13–14; *not* time-weighted), wheel power ``P_i = Ω_i u_i`` (the paper's motor model: the motor constants
cancel, ``K_V ≈ K_T`` in SI, so ``P = V i`` is the mechanical power), effort ``|u_i|`` and
energy ``u_i²`` summed over wheels.
"""

from __future__ import annotations

import numpy as np

from attitude_envs import quaternion
from attitude_envs.evaluation.trace import EpisodeTrace

RPM_PER_RAD_S = 60.0 / (2.0 * np.pi)


def _trapezoid(values: np.ndarray, time_s: np.ndarray) -> float:
    return float(np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(time_s)))


def settling_time_s(time_s: np.ndarray, error: np.ndarray, band: float) -> float:
    """First time after which ``error`` stays ≤ ``band`` (same units); ``nan`` if it never does."""
    outside = np.nonzero(error > band)[0]
    if len(outside) == 0:
        return float(time_s[0])
    last = outside[-1]
    return float("nan") if last == len(error) - 1 else float(time_s[last + 1])


def overshoot_deg(attitude: np.ndarray, target: np.ndarray) -> float:
    """Largest rotation past the target along the initial error axis, deg (0 if none).

    The error rotation vector ``θ(t) = 2 atan2(|q_e,vec|, q_e4) ê`` (``q_e = q_T* ⊗ q``) is
    projected on its initial direction; overshoot is the most negative projection.
    """
    vecs = np.array([_rotation_vector(q, qt) for q, qt in zip(attitude, target, strict=True)])
    r0 = vecs[0]
    norm0 = float(np.linalg.norm(r0))
    if norm0 == 0.0:
        return 0.0
    proj = vecs @ (r0 / norm0)
    return float(np.degrees(max(0.0, -np.min(proj))))


def _rotation_vector(q: np.ndarray, q_target: np.ndarray) -> np.ndarray:
    qe = quaternion.error(q, q_target)
    s = float(np.linalg.norm(qe[:3]))
    if s == 0.0:
        return np.zeros(3)
    return 2.0 * np.arctan2(s, qe[3]) * qe[:3] / s


def episode_metrics(
    trace: EpisodeTrace,
    settling_band: float = 0.02,
    settling_band_deg: float = 1.0,
    steady_state_fraction: float = 0.1,
    wheel_speed_limit_rad_s: float | None = None,
) -> dict[str, float | int | bool]:
    """All metrics of one episode as a flat dict (one row of the tidy table).

    ``settling_band``: relative band (fraction of the initial error angle α0) for
    ``settling_time_s``; ``settling_band_deg``: absolute band (deg) for
    ``settling_time_abs_s``; ``steady_state_fraction``: final fraction of the episode averaged
    for ``steady_state_error_deg``; ``wheel_speed_limit_rad_s``: design limit whose violation
    is flagged (``None``: not checked).
    """
    if not 0.0 < settling_band < 1.0:
        raise ValueError(f"settling_band must be in (0, 1), got {settling_band!r}")
    if not settling_band_deg > 0.0:
        raise ValueError(f"settling_band_deg must be in (0, inf), got {settling_band_deg!r}")
    if not 0.0 < steady_state_fraction <= 1.0:
        raise ValueError(f"steady_state_fraction must be in (0, 1], got {steady_state_fraction!r}")
    t = trace.time_s
    dt = trace.dt_s
    alpha = trace.error_angle_deg
    u = trace.applied_nm
    wheel = trace.wheel_speed_rad_s
    # Power of each wheel at both ends of each step with that step's (held) torque.
    p_start = np.abs(wheel[:-1] * u).sum(axis=1)
    p_end = np.abs(wheel[1:] * u).sum(axis=1)
    effort = np.abs(u).sum(axis=1)
    energy = (u * u).sum(axis=1)
    tail = t >= t[-1] - steady_state_fraction * (t[-1] - t[0])
    limit = trace.max_wheel_torque_nm
    # a step is saturated when the env clipped the action, a wheel ran at its torque limit, or
    # the speed limit cut a wheel's torque (applied ≠ commanded)
    saturated = (
        np.any(np.abs(trace.action) > 1.0, axis=1)
        | np.any(np.abs(u) >= limit * (1.0 - 1e-6), axis=1)
        | np.any(np.abs(trace.applied_nm - trace.commanded_nm) > 1e-9 * limit, axis=1)
    )
    peak_wheel = float(np.max(np.abs(wheel)))
    row: dict[str, float | int | bool] = {
        "J": float(np.sum(trace.cost)),
        "steps": trace.steps,
        "duration_s": float(t[-1] - t[0]),
        "terminated": trace.terminated,
        "initial_error_deg": float(alpha[0]),
        "final_error_deg": float(alpha[-1]),
        "eulerint_deg_s": _trapezoid(alpha, t),
        "settling_time_s": settling_time_s(t, alpha, settling_band * alpha[0]),
        "settling_time_abs_s": settling_time_s(t, alpha, settling_band_deg),
        "overshoot_deg": overshoot_deg(trace.attitude, trace.target_attitude),
        "steady_state_error_deg": float(np.mean(alpha[tail])),
        "power_integral_j": float(np.sum(0.5 * (p_start + p_end) * dt)),
        "effort_integral_nm_s": float(np.sum(effort * dt)),
        "energy_integral_nm2_s": float(np.sum(energy * dt)),
        "power_sum_w": float(np.sum(p_start)),
        "effort_sum_nm": float(np.sum(effort)),
        "energy_sum_nm2": float(np.sum(energy)),
        "peak_motor_torque_nm": float(np.max(np.abs(u))) if u.size else 0.0,
        "peak_wheel_speed_rpm": peak_wheel * RPM_PER_RAD_S,
        "saturation_fraction": float(np.mean(saturated)) if len(saturated) else 0.0,  # of the steps
    }
    row["overshoot_pct"] = float(100.0 * row["overshoot_deg"] / alpha[0]) if alpha[0] > 0 else 0.0
    if wheel_speed_limit_rad_s is not None:
        row["wheel_speed_limit_rpm"] = float(wheel_speed_limit_rad_s) * RPM_PER_RAD_S
        row["wheel_speed_violation"] = bool(peak_wheel > wheel_speed_limit_rad_s)
    return row
