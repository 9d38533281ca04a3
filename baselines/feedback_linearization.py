"""Input–output feedback linearization on the quaternion vector part + LQR outer loop, from the
feedback-linearization paper (Modares Mech. Eng.; authors not in our copy).

Outputs ``y = q_vec`` (the paper's eqs. 15–16), relative degree {2, 2, 2}:

    ÿ = D(x) + E(x) T                                                      (eq. 19)
    D = ½ Ω₁:₃(ω) q̇ + ½ Q''(q) ω̇_drift,   E = ½ Q''(q) I⁻¹                 (eqs. 25–26)
    T = E⁻¹ (v − D)                                                        (eq. 28)
    v = −K [y − y_d; ẏ]   (K = [K1·I₃, K2·I₃], LQR on 3 double integrators) (eqs. 30–33)

with ``Q''(q) = [[q4, −q3, q2], [q3, q4, −q1], [−q2, q1, q4]]`` (eq. 67) and ``q̇ = ½ q ⊗ [ω, 0]``.
The outer gains come from scipy's CARE with ``Q = 0.1·I₆``, ``R = 100·I₃`` (eqs. 79–82):
``K1 = √(q/r) = 0.031623``, ``K2 = √(q/r + 2K1) = 0.253467``.

Built from the env's *nominal* gyrostat (the paper's model is its small-wheel case): the drift
is ``ω̇_drift = I_eff⁻¹(−ω × (Iω + J_s A Ω))`` with ``I_eff = I − J_s A Aᵀ`` and ``Ω`` the
tachometer wheel speeds, and ``E`` uses ``I_eff``, so the closed loop is exactly linear in ``y``
for the nominal plant (up to the zero-order hold of the torque over a control period).

``output="absolute"`` (default, the paper's choice) uses the absolute attitude ``q`` and
``y_d = q_T,vec`` (signs chosen so that ``q4 ≥ 0`` and ``q_T4 ≥ 0``; assumed: the paper does not fix the sign);
``"error"`` uses the error quaternion ``q_e = q_T* ⊗ q`` (same kinematics, target fixed) with
``y_d = 0``, which works from any start attitude (singular only 180° from the target).

**Singularity** (eq. 29: ``det E = q4 / (8 Ixx Iyy Izz)``): when ``|q4| < q4_min`` the
linearizing law is not applied. ``on_singular="fallback"`` (default) commands the paper's
quaternion-feedback law (eq. 60, :class:`baselines.quaternion_lqr.QuaternionLQRPolicy`) for
that step and counts it in ``singular_steps``; ``"raise"`` raises :class:`SingularControlError`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.linearization import LinearModel
from attitude_envs.quaternion import cross
from baselines.allocation import WheelAllocator
from baselines.measured import MeasuredState
from baselines.quaternion_lqr import QuaternionLQRPolicy

PAPER_OUTER_Q = 0.1 * np.eye(6)  # the paper's eq. 79
PAPER_OUTER_R = 100.0 * np.eye(3)  # the paper's eq. 80


class SingularControlError(RuntimeError):
    """The feedback-linearizing law was asked for a torque where ``E(x)`` is singular (q4 → 0)."""


def outer_loop_gain(Q=PAPER_OUTER_Q, R=PAPER_OUTER_R) -> np.ndarray:
    """LQR gain ``K`` (3×6, ``v = −K ξ``) of three double integrators ``ξ = [y, ẏ]`` (eqs. 31–33)."""
    q_mat = validation.psd_matrix("Q", Q, 6)
    r_mat = validation.psd_matrix("R", R, 3, definite=True)
    A = np.zeros((6, 6))
    A[:3, 3:] = np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.eye(3)])
    return LinearModel(A, B, q_mat, r_mat).lqr_gain()


def q_double_prime(q: np.ndarray) -> np.ndarray:
    """``Q''(q)`` of the paper's eq. 67: ``q̇_vec = ½ Q''(q) ω`` (scalar-last ``q``)."""
    q1, q2, q3, q4 = q
    return np.array([[q4, -q3, q2], [q3, q4, -q1], [-q2, q1, q4]])


class FeedbackLinearizationPolicy:
    """The paper's feedback-linearizing controller on ReactionWheel-v0 (state feedback on the measured state ``info["measured"]``)."""

    def __init__(
        self,
        env,
        Q=PAPER_OUTER_Q,
        R=PAPER_OUTER_R,
        output: str = "absolute",
        q4_min: float = 0.05,
        on_singular: str = "fallback",
        saturation: str = "scale",
        name: str = "feedback-linearization",
    ) -> None:
        model = env.unwrapped.model
        self.output = validation.choice("output", output, {"absolute", "error"})
        self.on_singular = validation.choice("on_singular", on_singular, {"fallback", "raise"})
        self.q4_min = float(q4_min)
        if not 0.0 < self.q4_min < 1.0:
            raise ValueError(f"q4_min must be in (0, 1), got {q4_min!r}")
        self.gain = outer_loop_gain(Q, R)
        p = model.params
        self._inertia = p.inertia_kg_m2
        self._inertia_eff_inv = p.inertia_eff_inv
        self._wheel_momentum = p.wheel_inertia_kg_m2 * p.wheel_axes  # h_w = J_s A Ω
        self.allocator = WheelAllocator.for_env(env, saturation)
        self._fallback = QuaternionLQRPolicy(env, saturation=saturation)
        self.name = name
        self.singular_steps = 0

    @property
    def k1(self) -> float:
        """Position gain of each channel (paper: 0.0316)."""
        return float(self.gain[0, 0])

    @property
    def k2(self) -> float:
        """Rate gain of each channel (paper: 0.2535)."""
        return float(self.gain[0, 3])

    def reset(self, seed: int | None = None) -> None:
        self.singular_steps = 0

    def outputs(self, state: MeasuredState) -> tuple[np.ndarray, np.ndarray]:
        """``(q, y_d)``: the quaternion whose vector part is the output, and the output target."""
        if self.output == "error":
            return quaternion.error(state.attitude, state.target_attitude), np.zeros(3)
        q = state.attitude if state.attitude[3] >= 0 else -state.attitude
        target = state.target_attitude if state.target_attitude[3] >= 0 else -state.target_attitude
        return q, target[:3]

    def body_torque_nm(self, state: MeasuredState) -> np.ndarray:
        """Eq. 28 body torque (N·m), or the fallback law when ``|q4| < q4_min``."""
        q, y_d = self.outputs(state)
        if abs(q[3]) < self.q4_min:
            if self.on_singular == "raise":
                raise SingularControlError(
                    f"feedback linearization is singular: |q4| = {abs(q[3]):.3g} < q4_min = {self.q4_min}"
                )
            self.singular_steps += 1
            return self._fallback.body_torque_nm(state)
        w = state.rate_rad_s
        qpp = q_double_prime(q)
        qv_dot = 0.5 * qpp @ w
        q4_dot = -0.5 * float(q[:3] @ w)
        h = self._inertia @ w + self._wheel_momentum @ state.wheel_speed_rad_s
        w_dot_drift = self._inertia_eff_inv @ -cross(w, h)
        D = 0.5 * (q4_dot * w + cross(qv_dot, w)) + 0.5 * qpp @ w_dot_drift  # eq. 25
        E = 0.5 * qpp @ self._inertia_eff_inv  # eq. 26
        v = -self.gain @ np.concatenate([q[:3] - y_d, qv_dot])  # eq. 33
        return np.linalg.solve(E, v - D)  # eq. 28

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.allocator.action(self.body_torque_nm(MeasuredState.from_info(info)))
