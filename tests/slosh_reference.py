"""Frozen NumPy reference of the fuel-slosh plant and FuelSlosh-v0's step as they were
before the compiled kernels (commit e8f3727): mass matrix, forces and ``np.linalg.solve``,
the env's augmented RK4. Regression oracle for :mod:`attitude_envs.plants.slosh_kernels`;
not used by the package."""

from __future__ import annotations

import math

import numpy as np

from attitude_envs.cost import QuadraticCost
from attitude_envs.integrators import rk4_step
from attitude_envs.plants.slosh import SloshParams

REDUCED_INDEX = [6, 2, 7, 3, 8, 4, 9]


def mass_matrix(p: SloshParams, psi: np.ndarray) -> np.ndarray:
    sp, cp = np.sin(psi), np.cos(psi)
    mls, mlc = p.ml * sp, p.ml * cp
    a_i = np.asarray(p.hinge_m)
    M = np.zeros((5, 5))
    M[0, 0] = M[1, 1] = p.total_mass_kg
    M[0, 2] = M[2, 0] = mls.sum()
    M[1, 2] = M[2, 1] = p.S_z + mlc.sum()
    M[2, 2] = p.I_rigid - 2.0 * float(np.sum(p.ml * a_i * np.cos(psi)))
    for i in range(2):
        M[0, 3 + i] = M[3 + i, 0] = mls[i]
        M[1, 3 + i] = M[3 + i, 1] = mlc[i]
        M[2, 3 + i] = M[3 + i, 2] = p.J[i] - mlc[i] * a_i[i]
        M[3 + i, 3 + i] = p.J[i]
    return M


def forces(p: SloshParams, y: np.ndarray, delta_rad: float, moment_nm: float) -> np.ndarray:
    psi, dpsi = y[3:5], y[8:10]
    vx, vz, om = y[5], y[6], y[7]
    sp, cp = np.sin(psi), np.cos(psi)
    a_i = np.asarray(p.hinge_m)
    w2 = (om + dpsi) ** 2
    fs, fc = p.thrust_n * math.sin(delta_rad), p.thrust_n * math.cos(delta_rad)
    mls, mlc = p.ml * sp, p.ml * cp
    out = np.empty(5)
    out[0] = fc - p.total_mass_kg * om * vz - p.S_z * om**2 - float(mlc @ w2)
    out[1] = fs + p.total_mass_kg * om * vx + float(mls @ w2)
    out[2] = (
        moment_nm
        + p.lever_arm_m * fs
        + om * vx * (p.S_z + mlc.sum())
        - om * vz * mls.sum()
        - float(np.sum(mls * a_i * (2.0 * om * dpsi + dpsi**2)))
    )
    out[3:] = mls * a_i * om**2 + p.ml * om * (vx * cp - vz * sp) - np.asarray(p.damping_kg_m2_s) * dpsi
    return out


def derivative(p: SloshParams, y: np.ndarray, delta_rad: float, moment_nm: float) -> np.ndarray:
    dy = np.empty(10)
    th, vx, vz = y[2], y[5], y[6]
    c, s = math.cos(th), math.sin(th)
    dy[0] = vx * c + vz * s
    dy[1] = -vx * s + vz * c
    dy[2] = y[7]
    dy[3:5] = y[8:10]
    dy[5:] = np.linalg.solve(mass_matrix(p, y[3:5]), forces(p, y, delta_rad, moment_nm))
    return dy


def env_step(p: SloshParams, cost: QuadraticCost, y, delta, moment, h, n_sub):
    """The old FuelSlosh-v0 plant step: ``(y_next, step cost, [∫a_z, ∫Ω̇])``."""

    def augmented(_t, aug):
        yy = aug[:10]
        dy = derivative(p, yy, delta, moment)
        u_c = np.array([dy[6] - yy[7] * yy[5], dy[7]])
        return np.concatenate([dy, [cost.stage(yy[REDUCED_INDEX], u_c)], u_c])

    aug = np.concatenate([y, np.zeros(3)])
    for _ in range(n_sub):
        aug = rk4_step(augmented, 0.0, aug, h)
    return aug[:10], float(aug[10]), aug[11:]
