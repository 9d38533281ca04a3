"""The stand-alone LQR of the feedback-linearization paper (Modares Mech. Eng.; authors not in
our copy): the quaternion-feedback law ``T = 2K q_E,vec q_E4 − K_d ω``.

Law (the paper's eq. 60) with ``q_E = q_S* ⊗ q_T`` (eq. 61). This package's error
quaternion is its conjugate, ``q_e = q_T* ⊗ q`` (``q_e,vec = −q_E,vec``, same scalar part ≥ 0),
so the law reads ``T = −2 K_q q_e,vec q_e4 − K_ω ω`` here.

Gains: LQR on the rigid-body model linearized about zero attitude and rate with the wheels
at rest (eqs. 69–74, ``h_w = 0``), weights ``Q = blockdiag(170·I₃ on q_vec, 13131·I₃ on ω)``,
``R = 2500·I₃`` on the body torque (eqs. 75–76), solved with scipy's CARE. With the paper's
``I = diag(4, 4, 3)`` this gives ``K = 0.2608``, ``K_d = 2.5091/2.5091/2.4566`` (eqs. 77–78).
The policy designs on the env's *nominal* body inertia as the wheels see it,
``I_eff = I − J_s A Aᵀ`` (the exact gyrostat's response to motor torque, see
:mod:`attitude_envs.plants.gyrostat`): for the paper's pyramid that moves ``K_d`` in the fifth digit
(2.5090/2.4565).

``stiffness="paper"`` (default) uses eq. 60 as written, i.e. twice the stiffness the LQR
design implies for small angles (``2 q_e4 q_e,vec ≈ θ`` while the design's state is
``q_vec ≈ θ/2``; assumed: the paper's eq. 60 is reproduced as printed); ``"consistent"`` halves it (``K/2``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.linearization import LinearModel
from baselines.allocation import WheelAllocator
from baselines.measured import MeasuredState

PAPER_Q = np.diag([170.0] * 3 + [13131.0] * 3)  # the paper's eq. 75, order [q_vec, ω]
PAPER_R = 2500.0 * np.eye(3)  # the paper's eq. 76


def quaternion_lqr_gains(inertia_kg_m2, Q=PAPER_Q, R=PAPER_R) -> tuple[np.ndarray, np.ndarray]:
    """``(K_q, K_ω)`` (3×3 each) of the LQR on the linearized rigid body (the paper's eqs. 69–74).

    State ``[q_vec, ω]`` (``q̇_vec = ½ω``, ``I ω̇ = T``), input body torque ``T`` (N·m);
    ``Q`` (6×6, on ``[q_vec, ω]``) and ``R`` (3×3) as in eqs. 75–76 by default. The LQR law is
    ``T = −K_q q_vec − K_ω ω``; for diagonal ``I`` both gains are diagonal.
    """
    inertia = validation.inertia("inertia_kg_m2", inertia_kg_m2)
    q_mat = validation.psd_matrix("Q", Q, 6)
    r_mat = validation.psd_matrix("R", R, 3, definite=True)
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(inertia)])
    K = LinearModel(A, B, q_mat, r_mat).lqr_gain()
    return K[:, :3], K[:, 3:]


class QuaternionLQRPolicy:
    """The feedback-linearization paper's eq. 60 on ReactionWheel-v0, built from the env's nominal model.

    State feedback on the measured state ``info["measured"]`` (attitude, rate, target). The
    body torque is allocated to the wheels by :class:`baselines.allocation.WheelAllocator`.
    """

    def __init__(
        self,
        env,
        Q=PAPER_Q,
        R=PAPER_R,
        stiffness: str = "paper",
        saturation: str = "scale",
        name: str = "quaternion-lqr",
    ) -> None:
        model = env.unwrapped.model
        validation.choice("stiffness", stiffness, {"paper", "consistent"})
        inertia_eff = np.linalg.inv(model.params.inertia_eff_inv)
        self.attitude_gain, self.rate_gain = quaternion_lqr_gains(0.5 * (inertia_eff + inertia_eff.T), Q, R)
        self._stiffness = 2.0 if stiffness == "paper" else 1.0
        self.allocator = WheelAllocator.for_env(env, saturation)
        self.name = name

    def reset(self, seed: int | None = None) -> None:
        pass

    def body_torque_nm(self, state: MeasuredState) -> np.ndarray:
        """Eq. 60: ``T = −s K_q q_e,vec q_e4 − K_ω ω`` (``s = 2`` as in the paper), N·m."""
        qe = quaternion.error(state.attitude, state.target_attitude)
        return -self._stiffness * qe[3] * (self.attitude_gain @ qe[:3]) - self.rate_gain @ state.rate_rad_s

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.allocator.action(self.body_torque_nm(MeasuredState.from_info(info)))
