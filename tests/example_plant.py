"""A plant written the way a user adds one: a single-axis spacecraft with one reaction wheel.

The body (inertia ``J``, kg·m²) turns about one axis; the wheel (spin inertia ``J_w``,
kg·m²) is driven by a motor torque ``u`` (N·m): ``J θ̈ = −u``, ``J_w Ω̇ = u`` (wheel speed
relative to inertial space; the total momentum ``J ω + J_w Ω`` is conserved). The stage
cost ``xᵀQx + uᵀRu`` of the error ``x = [θ − θ_T, ω]`` is integrated next to the state by
the same RK4 step, so the reward does not depend on the control period.

The equations are written once, in :func:`define`, against the suite's operation set
(:mod:`attitude_envs.plants.ops`): the env steps them with plain numpy here, and the same
source compiles under numba, traces under JAX and builds CasADi expressions (the Jacobian
of the linearization test comes from there).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from attitude_envs.cost import QuadraticCost
from attitude_envs.integrators import rk4_step
from attitude_envs.plants.ops import NUMPY, Ops, define_quad_form


@dataclass(frozen=True)
class SingleAxisModel:
    """Nominal model: inertias, torque limit, cost weights and control period."""

    inertia_kg_m2: float
    wheel_inertia_kg_m2: float
    max_torque_nm: float
    cost: QuadraticCost
    control_dt_s: float

    def linearize(self) -> tuple[np.ndarray, np.ndarray]:
        """Continuous ``ẋ = A x + B u`` of the error state (exact: the plant is linear)."""
        a = np.array([[0.0, 1.0], [0.0, 0.0]])
        b = np.array([[0.0], [-1.0 / self.inertia_kg_m2]])
        return a, b


@functools.cache
def define(ops: Ops) -> SimpleNamespace:
    """The plant's equations for the executor ``ops``."""
    quad_form = define_quad_form(ops)

    @ops.compile
    def derivative(y, u, inertia_kg_m2, wheel_inertia_kg_m2, target_rad, Q, R):
        """``d/dt [θ, ω, Ω, J]`` (rad/s, rad/s², rad/s², cost rate) under the motor torque
        ``u`` (N·m), with the cost rate ``xᵀQx + uᵀRu`` as the last entry."""
        x = (y[0] - target_rad, y[1])
        return (
            y[1],
            -u / inertia_kg_m2,
            u / wheel_inertia_kg_m2,
            quad_form(R, (u,), 1, quad_form(Q, x, 2)),
        )

    return SimpleNamespace(derivative=derivative)


def derivative(y: np.ndarray, u: float, model: SingleAxisModel, target_rad: float) -> np.ndarray:
    """``d/dt [θ, ω, Ω, J]`` with the cost rate as the last entry (the definition, in numpy)."""
    dy = define(NUMPY).derivative(
        y, u, model.inertia_kg_m2, model.wheel_inertia_kg_m2, target_rad, model.cost.Q, model.cost.R
    )
    return np.array(dy, dtype=float)


def step(y: np.ndarray, u: float, model: SingleAxisModel, target_rad: float, n_sub: int) -> tuple[np.ndarray, float]:
    """Advance ``[θ, ω, Ω]`` over one control period with ``u`` held; returns the new state
    and the integrated cost of the period."""
    h = model.control_dt_s / n_sub
    z = np.append(y, 0.0)
    for _ in range(n_sub):
        z = rk4_step(lambda _t, s: derivative(s, u, model, target_rad), 0.0, z, h)
    return z[:3], float(z[3])
