"""Nominal model of the reaction-wheel spacecraft as controllers see it.

Error state (the cost's and the observation's ``x``):

    x = [q_e,vec (3), ω (3, rad/s), h_w (N, N·m·s, only when wheel momentum is weighted)]

with ``q_e = q_T* ⊗ q`` (sign w ≥ 0, see :func:`attitude_envs.quaternion.error`) and
``h_w,i = J_s Ω_i``. The cost input is either the body torque ``T = −A u`` (3, N·m,
``cost_input="body"``, as both papers weight it) or the wheel motor torques ``u`` (N, N·m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude_envs.cost import QuadraticCost
from attitude_envs.linearization import LinearModel, complex_step_jacobian
from attitude_envs.plants import gyrostat_kernels as kernels
from attitude_envs.plants.gyrostat import GyrostatParams
from attitude_envs.plants.gyrostat_definition import MAT_ROWS, N_SCALARS, define
from attitude_envs.plants.ops import NUMPY

_PLANT = define(NUMPY)


@dataclass(frozen=True)
class ReactionWheelModel:
    """Nominal gyrostat + error state + cost: what model-based controllers may use."""

    params: GyrostatParams
    cost: QuadraticCost
    cost_input: str  # "body" or "wheel"
    include_wheel_momentum: bool
    control_dt_s: float

    @property
    def n_state(self) -> int:
        return 6 + (self.params.n_wheels if self.include_wheel_momentum else 0)

    @property
    def allocation(self) -> np.ndarray:
        """Minimum-norm map from a body torque demand ``T`` (N·m) to wheel motor torques
        ``u = −A⁺ T`` (N×3), so that the body receives ``−A u = T``."""
        return -np.linalg.pinv(self.params.wheel_axes)

    def error_state(self, q: np.ndarray, w: np.ndarray, wheel_speed_rad_s: np.ndarray, q_target: np.ndarray):
        """``x`` of the current physical state relative to the target attitude (at rest)."""
        y = np.concatenate([q, w, wheel_speed_rad_s]).astype(float).reshape(-1, 1)
        x = np.empty((self.n_state, 1))
        kernels.error_state_columns(
            y,
            np.asarray(q_target, dtype=float).reshape(4, 1),
            self.params.wheel_inertia_kg_m2,
            self.include_wheel_momentum,
            x,
            np.empty(1),
        )
        return x[:, 0]

    def error_derivative(
        self, x: np.ndarray, motor_torque_nm: np.ndarray, wheel_speed_rad_s: np.ndarray | None = None
    ) -> np.ndarray:
        """``ẋ`` of the nonlinear plant in error coordinates (the target is inertially fixed, so
        ``q̇_e = ½ q_e ⊗ [ω, 0]``: the plant definition's derivative at ``q = q_e``).

        When wheel momentum is not part of ``x`` the wheels sit at ``wheel_speed_rad_s`` (rad/s,
        zero by default). ``x`` and ``motor_torque_nm`` (N·m) may hold one state per column, real
        or complex (:meth:`linearize` differentiates this by the complex step).
        """
        p = self.params
        n, j_s = p.n_wheels, p.wheel_inertia_kg_m2
        x, u = np.asarray(x), np.asarray(motor_torque_nm)
        v, w = x[:3], x[3:6]
        if self.include_wheel_momentum:
            wheel = x[6:] / j_s
        else:
            wheel = np.zeros(n) if wheel_speed_rad_s is None else np.asarray(wheel_speed_rad_s, dtype=float)
            wheel = np.broadcast_to(wheel.reshape((n,) + (1,) * (x.ndim - 1)), (n,) + x.shape[1:])
        s = 1.0 - (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        y = [*v, np.sqrt(np.where(np.real(s) < 0.0, 0.0, s)), *w, *wheel]
        constants = kernels.pack_constants(p.wheel_axes, np.zeros(0), np.zeros(0), j_s, 0.0, np.inf, 0.0, np.zeros(3))
        sc = constants.shape[0] - N_SCALARS
        mats = kernels.pack_matrices(p.inertia_kg_m2, p.inertia_eff_inv)
        rows = [*y, *u, *(u / j_s), 0.0, 0.0, 0.0, *mats] + [0.0] * (7 + n)
        out = 7 + 3 * n + 3 + MAT_ROWS
        _PLANT.derivative_lane(rows, constants, 0, 1, n, False, 0, 7 + n, 7 + 2 * n, 7 + 3 * n, 10 + 3 * n, out, 0, sc)
        dy = rows[out : out + 7 + n]
        parts = [*dy[0:3], *dy[4:7]]
        if self.include_wheel_momentum:
            parts += [j_s * d for d in dy[7:]]
        return np.array(parts)

    def linearize(self, wheel_speed_rad_s: np.ndarray | None = None, input: str | None = None) -> LinearModel:
        """Continuous linearization about the target at rest (``x = 0``), wheels at
        ``wheel_speed_rad_s`` (default zero): the Jacobians of the plant definition's
        :meth:`error_derivative`, exact to rounding (complex step). ``input`` is ``"body"`` or
        ``"wheel"`` (default: the cost's input); ``Q`` and ``R`` are the cost's when ``input``
        is the cost's input, else ``R`` is mapped (``R_wheel = AᵀR_body A`` is singular for
        N > 3: use it only with ``input="wheel"`` costs)."""
        p = self.params
        input = self.cost_input if input is None else input
        if input not in ("body", "wheel"):
            raise ValueError(f"input must be one of ['body', 'wheel'], got {input!r}")
        wheel = np.zeros(p.n_wheels) if wheel_speed_rad_s is None else np.asarray(wheel_speed_rad_s, dtype=float)
        n = self.n_state
        z0 = np.zeros(n + p.n_wheels)
        if self.include_wheel_momentum:
            z0[6:n] = p.wheel_inertia_kg_m2 * wheel
        jacobian = complex_step_jacobian(lambda z: self.error_derivative(z[:n], z[n:], wheel), z0)
        A, b_wheel = jacobian[:, :n], jacobian[:, n:]
        if input == "wheel":
            B = b_wheel
            R = self.cost.R if self.cost_input == "wheel" else p.wheel_axes.T @ self.cost.R @ p.wheel_axes
        else:  # the body torque T enters through the minimum-norm allocation u = A⁺(−T)
            B = b_wheel @ self.allocation
            R = self.cost.R if self.cost_input == "body" else self.allocation.T @ self.cost.R @ self.allocation
        return LinearModel(A, B, self.cost.Q, R)

    def discrete(self, dt_s: float | None = None, **kwargs) -> LinearModel:
        """Exact ZOH discretization (plant and cost) over ``dt_s`` (default: the control period)."""
        return self.linearize(**kwargs).discretize(self.control_dt_s if dt_s is None else dt_s)
