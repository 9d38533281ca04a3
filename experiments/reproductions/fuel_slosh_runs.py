"""Closed-loop runs for the Navabi & Davoodi reproduction: the paper's setup (reduced models) and
the full FuelSlosh-v0 plant, with the metrics the reproduction reports.

Paper setup (as the paper runs it): PD and LQR on the reduced *linear* model with v_x(t) = 3000 + 2t
(δ, M recovered with the linear eqs. 15–17), fuzzy and Lyapunov on the reduced
*nonlinear* model (δ, M from exact inversion of eqs. 11–13). Continuous controllers are
integrated with scipy's LSODA (stiff-safe: the paper LQR has a −448 rad/s pole), max step
0.5 s, rtol 1e-8; the fuzzy controller (stateful gain schedule) is held over 0.1 s and
integrated with RK4 at 0.05 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from attitude_envs.info import policy_view
from attitude_envs.integrators import rk4_step
from attitude_envs.plants import slosh
from attitude_envs.plants.slosh_model import (
    REDUCED_INDEX,
    invert_inputs,
    invert_inputs_linear,
    reduced_derivative,
    reduced_linear,
)

# Settling thresholds (assumed: the paper defines none): last time |v_z| > 1 m/s, |θ| > 0.02°, |ψ| > 0.5°.
THRESHOLDS = {"v_z": 1.0, "theta": math.radians(0.02), "psi": math.radians(0.5)}


@dataclass
class Trajectory:
    """Sampled closed-loop run: time (s), reduced state x (7×N), v_x (N), new inputs
    u (2×N), physical inputs δ (rad) and M_c (N·m), and the step costs when from the env."""

    t: np.ndarray
    x: np.ndarray
    v_x: np.ndarray
    u: np.ndarray
    delta: np.ndarray
    moment: np.ndarray
    cost: float
    extra: dict = field(default_factory=dict)


def settling_time(t: np.ndarray, signal: np.ndarray, threshold: float) -> float:
    """Last time |signal| exceeds ``threshold`` (s); 0 if never, inf if still at the end."""
    above = np.nonzero(np.abs(signal) > threshold)[0]
    if above.size == 0:
        return 0.0
    return math.inf if above[-1] == len(t) - 1 else float(t[above[-1] + 1])


def metrics(tr: Trajectory) -> dict[str, float]:
    """The per-controller numbers of the reproduction table."""
    psi = np.abs(tr.x[[3, 5]])
    late = tr.t >= 20.0
    return {
        "settling v_z (s)": settling_time(tr.t, tr.x[0], THRESHOLDS["v_z"]),
        "settling theta (s)": settling_time(tr.t, tr.x[1], THRESHOLDS["theta"]),
        "settling psi1 (s)": settling_time(tr.t, tr.x[3], THRESHOLDS["psi"]),
        "settling psi2 (s)": settling_time(tr.t, tr.x[5], THRESHOLDS["psi"]),
        "peak abs psi1 after 20 s (deg)": math.degrees(float(psi[0, late].max())),
        "peak abs psi2 after 20 s (deg)": math.degrees(float(psi[1, late].max())),
        "min v_z (m/s)": float(tr.x[0].min()),
        "peak abs u1 (m/s^2)": float(np.abs(tr.u[0]).max()),
        "peak abs delta (deg)": math.degrees(float(np.abs(tr.delta).max())),
        "peak abs M (N m)": float(np.abs(tr.moment).max()),
        "J": tr.cost,
    }


def _quad_cost(t, x, u, Q, R) -> float:
    stage = np.einsum("in,ij,jn->n", x, Q, x) + np.einsum("in,ij,jn->n", u, R, u)
    return float(np.trapezoid(stage, t))


def simulate_reduced(policy, params: slosh.SloshParams, x0: np.ndarray, v_x0: float, t_final_s: float,
                     linear: bool, Q: np.ndarray, R: np.ndarray, sample_s: float = 0.5) -> Trajectory:  # fmt: skip
    """Run ``policy.new_inputs(x, v_x)`` on the reduced linear or nonlinear model."""
    ax = params.axial_acceleration_m_s2
    B = reduced_linear(params, v_x0)[1]

    def rhs(z, u):
        if linear:
            A = reduced_linear(params, z[0])[0]
            return np.concatenate([[ax], A @ z[1:] + B @ u])
        return reduced_derivative(params, np.concatenate([[z[0]], z[1:]]), u)

    z0 = np.concatenate([[v_x0], x0])
    t_eval = np.arange(0.0, t_final_s + 1e-9, sample_s)
    if getattr(policy, "stateful", False):  # the fuzzy schedule: sample and hold
        policy.reset()
        dt, h = 0.1, 0.05
        z, zs, us = z0.copy(), [], []
        every = round(sample_s / dt)
        for k in range(round(t_final_s / dt) + 1):
            u = policy.new_inputs(z[1:], z[0])
            if k % every == 0:
                zs.append(z.copy())
                us.append(u.copy())
            for _ in range(2):
                z = rk4_step(lambda t, s, u=u: rhs(s, u), 0.0, z, h)
        Z, U = np.array(zs).T, np.array(us).T
        t_eval = t_eval[: Z.shape[1]]
    else:
        sol = solve_ivp(
            lambda t, z: rhs(z, policy.new_inputs(z[1:], z[0])),
            (0.0, t_final_s),
            z0,
            method="LSODA",
            t_eval=t_eval,
            max_step=0.5,
            rtol=1e-8,
            atol=1e-10,
        )
        if not sol.success:
            raise RuntimeError(f"reduced-model run of {policy.name} failed: {sol.message}")
        Z = sol.y
        U = np.array([policy.new_inputs(Z[1:, k], Z[0, k]) for k in range(Z.shape[1])]).T
    x = Z[1:]
    delta, moment = recover_inputs(params, Z, U, linear)
    return Trajectory(t_eval, x, Z[0], U, delta, moment, _quad_cost(t_eval, x, U, Q, R))


def recover_inputs(params: slosh.SloshParams, Z: np.ndarray, U: np.ndarray, linear: bool):
    """δ (rad) and M_c (N·m) along a reduced run: linear eqs. 15–17 or exact inversion."""
    delta, moment = np.empty(Z.shape[1]), np.empty(Z.shape[1])
    for k in range(Z.shape[1]):
        if linear:
            delta[k], moment[k] = invert_inputs_linear(params, Z[1:, k], U[0, k], U[1, k])
        else:
            y = np.zeros(slosh.N_STATE)
            y[REDUCED_INDEX] = Z[1:, k]
            y[slosh.IVX] = Z[0, k]
            delta[k], moment[k], _ = invert_inputs(params, y, U[0, k], U[1, k])
    return delta, moment


def run_env(env, policy, sample_every: int = 5) -> Trajectory:
    """One episode of ``policy`` on FuelSlosh-v0 (same loop as the shared ``rollout``),
    sampled every ``sample_every`` control steps; J is the sum of ``info["cost"]``."""
    obs, info = env.reset(seed=0)
    policy.reset(0)
    ts, xs, vx, us, ds, ms = [], [], [], [], [], []
    total, k, saturated = 0.0, 0, 0
    terminated = truncated = False
    while not (terminated or truncated):
        action = policy.act(obs, policy_view(info))
        saturated += int(abs(float(action[0])) >= 1.0)
        obs, _, terminated, truncated, info = env.step(action)
        total += info["cost"]
        if k % sample_every == 0:
            ts.append(info["time_s"])
            xs.append(info["truth"]["x"])
            vx.append(info["truth"]["state"]["v_x_m_s"])
            us.append(info["truth"]["new_inputs"])
            ds.append(info["truth"]["applied"][0])
            ms.append(info["truth"]["applied"][1])
        k += 1
    return Trajectory(
        np.array(ts),
        np.array(xs).T,
        np.array(vx),
        np.array(us).T,
        np.array(ds),
        np.array(ms),
        total,
        {"terminated": bool(terminated), "gimbal_saturated_fraction": saturated / max(k, 1)},
    )
