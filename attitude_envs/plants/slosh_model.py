"""Reduced slosh models, linearizations and input inversion of Navabi & Davoodi
(double-pendulum fuel slosh; year not in our copy, ≥ 2012), eqs. 15–27.

The paper's controllers act on "new inputs" ``u = [u1, u2] = [a_z, Ω̇]`` (transverse
acceleration of the tank centre, m/s², and pitch acceleration, rad/s²; our reading of the
paper's eqs. 22–24, whose symbols are lost in our copy) and recover the physical gimbal
angle δ (rad) and pitch moment M_c (N·m) from the full equations (linear eqs. 15–17 or
nonlinear eqs. 11–13). Reduced state ``x = [v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` (m/s, rad, rad/s);
the axial speed v_x (m/s) is a parameter of the reduced linear model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from attitude_envs import validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.linearization import LinearModel
from attitude_envs.plants import slosh, slosh_kernels
from attitude_envs.plants.slosh import SloshParams

REDUCED_STATE = (
    "v_z_m_s",
    "theta_rad",
    "pitch_rate_rad_s",
    "psi1_rad",
    "psi1_rate_rad_s",
    "psi2_rad",
    "psi2_rate_rad_s",
)
# full-state indices of the reduced state x
REDUCED_INDEX = np.array([slosh.IVZ, slosh.ITH, slosh.IOM, slosh.IPSI1, slosh.IDPSI1, slosh.IPSI2, slosh.IDPSI2])


def reduced_state(y: np.ndarray) -> np.ndarray:
    """The reduced (error) state ``x`` (7) of a full state ``y`` (10)."""
    return np.asarray(y)[REDUCED_INDEX]


def reduced_derivative(p: SloshParams, z: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Reduced nonlinear model (the paper's eqs. 20, 22–24), ``z = [v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]``,
    ``u = [a_z (m/s²), Ω̇ (rad/s²)]``; a_x is the constant F/m_t (eq. 20)."""
    vx, vz, _, om, p1, dp1, p2, dp2 = z
    u1, u2 = float(u[0]), float(u[1])
    ax = p.axial_acceleration_m_s2
    out = np.empty(8)
    out[0] = ax - om * vz
    out[1] = u1 + vx * om
    out[2] = om
    out[3] = u2
    for k, (psi, dpsi) in enumerate(((p1, dp1), (p2, dp2))):
        a_i, J, ml, eps = p.hinge_m[k], p.J[k], p.ml[k], p.damping_kg_m2_s[k]
        ddpsi = -u2 - (ml / J) * ((ax - a_i * om**2) * math.sin(psi) + (u1 - a_i * u2) * math.cos(psi)) - eps / J * dpsi
        out[4 + 2 * k] = dpsi
        out[5 + 2 * k] = ddpsi
    return out


def reduced_linear(p: SloshParams, v_x_m_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the reduced linear model (the paper's eqs. 25–27) at axial speed v_x."""
    ax = p.axial_acceleration_m_s2
    A = np.zeros((7, 7))
    B = np.zeros((7, 2))
    A[0, 2] = v_x_m_s
    A[1, 2] = 1.0
    B[0, 0] = 1.0
    B[2, 1] = 1.0
    for k in range(2):
        r = 3 + 2 * k
        J, ml, a_i = p.J[k], p.ml[k], p.hinge_m[k]
        A[r, r + 1] = 1.0
        A[r + 1, r] = -ml * ax / J
        A[r + 1, r + 1] = -p.damping_kg_m2_s[k] / J
        B[r + 1] = [-ml / J, -(1.0 - ml * a_i / J)]
    return A, B


def _linear_mass(p: SloshParams) -> np.ndarray:
    """Mass matrix of ``[v̇_z, Ω̇, ψ̈1, ψ̈2]`` at ψ = 0 (rows z, pitch, ψ1, ψ2 of eqs. 16–18)."""
    M = slosh.mass_matrix(p, np.zeros(2))
    return M[1:, 1:]


def full_linear(p: SloshParams, v_x_m_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the full plant linearized about the relative equilibrium (the
    paper's eqs. 15–18) for ``x`` (7) and the physical inputs ``[δ (rad), M_c (N·m)]``;
    v̇_x = F/m_t."""
    ax = p.axial_acceleration_m_s2
    ml, eps = p.ml, np.asarray(p.damping_kg_m2_s)
    Mlin = _linear_mass(p)
    s_lin = p.S_z + ml.sum()
    # right-hand sides of rows (z, pitch, ψ1, ψ2) as K x + G [δ, M]
    K = np.zeros((4, 7))
    G = np.zeros((4, 2))
    K[0, 2] = p.total_mass_kg * v_x_m_s
    G[0, 0] = p.thrust_n
    K[1, 2] = s_lin * v_x_m_s
    K[1, 3], K[1, 5] = -ax * ml[0], -ax * ml[1]
    G[1] = [p.lever_arm_m * p.thrust_n, 1.0]
    for k in range(2):
        K[2 + k, 2] = ml[k] * v_x_m_s
        K[2 + k, 3 + 2 * k] = -ml[k] * ax
        K[2 + k, 4 + 2 * k] = -eps[k]
    acc_x = np.linalg.solve(Mlin, K)
    acc_u = np.linalg.solve(Mlin, G)
    A = np.zeros((7, 7))
    B = np.zeros((7, 2))
    A[1, 2] = A[3, 4] = A[5, 6] = 1.0
    for row, acc in ((0, 0), (2, 1), (4, 2), (6, 3)):
        A[row] = acc_x[acc]
        B[row] = acc_u[acc]
    return A, B


#: fixed-point passes of the exact input inversion (from δ = 0; the gimbal sine settles to round-off)
INVERSION_ITERATIONS = 6


def invert_inputs(p: SloshParams, y: np.ndarray, u1: float, u2: float, iterations: int = INVERSION_ITERATIONS):
    """Exact inversion on the full plant (the nonlinear eqs. 11–13 solved for the inputs; the
    plant definition's ``invert_inputs``): the ``(δ, M_c)`` (rad, N·m) that make a_z = u1
    (m/s²) and Ω̇ = u2 (rad/s²) at the full state ``y``; also returns whether |sin δ| had to be
    clipped to 1 (thrust authority exceeded)."""
    delta, moment, saturated = slosh_kernels.invert_inputs(
        p.packed, slosh.checked_state(y), float(u1), float(u2), validation.integer("iterations", iterations, 1)
    )
    return float(delta), float(moment), bool(saturated)


def invert_inputs_linear(p: SloshParams, x: np.ndarray, u1: float, u2: float) -> tuple[float, float]:
    """Linear recovery of ``(δ, M_c)`` (rad, N·m) from eqs. 15–17 (used by the
    paper for PD and LQR); ψ̈ from the reduced linear model (eq. 26)."""
    ax = p.axial_acceleration_m_s2
    ml = p.ml
    psi = x[[3, 5]]
    dpsi = x[[4, 6]]
    a_i = np.asarray(p.hinge_m)
    ddpsi = -(ml * ax / p.J) * psi - np.asarray(p.damping_kg_m2_s) / p.J * dpsi - (ml / p.J) * u1
    ddpsi -= (1.0 - ml * a_i / p.J) * u2
    s_lin = p.S_z + ml.sum()
    f_delta = p.total_mass_kg * u1 + s_lin * u2 + float(ml @ ddpsi)
    delta = f_delta / p.thrust_n
    moment = (
        p.pitch_inertia(np.zeros(2)) * u2
        + float((p.J - ml * a_i) @ ddpsi)
        + s_lin * u1
        + ax * float(ml @ psi)
        - p.lever_arm_m * p.thrust_n * delta
    )
    return float(delta), float(moment)


@dataclass(frozen=True)
class FuelSloshModel:
    """The nominal model of FuelSlosh-v0 (``env.unwrapped.model``).

    ``params`` (:class:`SloshParams`), ``cost`` (Q on x, R on the realized new inputs
    ``[a_z, Ω̇]``), actuator limits ``max_gimbal_rad`` and ``max_moment_nm``, the design
    axial speed ``design_v_x_m_s`` of the linear model and ``control_dt_s``.
    """

    params: SloshParams
    cost: QuadraticCost
    max_gimbal_rad: float
    max_moment_nm: float
    design_v_x_m_s: float
    control_dt_s: float

    def linearize(self, v_x_m_s: float | None = None) -> LinearModel:
        """Continuous reduced linear model (new inputs) with the env's cost weights."""
        vx = self.design_v_x_m_s if v_x_m_s is None else v_x_m_s
        A, B = reduced_linear(self.params, vx)
        return LinearModel(A, B, self.cost.Q, self.cost.R)

    def discrete(self, dt_s: float | None = None) -> LinearModel:
        """Exact ZOH discretization of the reduced linear model and cost."""
        return self.linearize().discretize(self.control_dt_s if dt_s is None else dt_s)

    def full_linear(self, v_x_m_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Full-plant linearization in the physical inputs (δ rad, M_c N·m), eqs. 15–18."""
        return full_linear(self.params, self.design_v_x_m_s if v_x_m_s is None else v_x_m_s)

    def inputs_for(self, y: np.ndarray, u: np.ndarray, linear: bool = False) -> tuple[float, float]:
        """Physical ``(δ, M_c)`` realizing new inputs ``u`` at full state ``y`` (exact
        inversion, or the paper's linear recovery with ``linear=True``)."""
        if linear:
            return invert_inputs_linear(self.params, reduced_state(y), float(u[0]), float(u[1]))
        delta, moment, _ = invert_inputs(self.params, y, float(u[0]), float(u[1]))
        return delta, moment

    def normalize(self, delta_rad: float, moment_nm: float) -> np.ndarray:
        """The env action (clipped to [-1, 1]) commanding ``δ`` and ``M_c``."""
        a = np.array([delta_rad / self.max_gimbal_rad, moment_nm / self.max_moment_nm])
        return np.clip(a, -1.0, 1.0).astype(np.float32)
