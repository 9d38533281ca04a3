"""Reference attitude trajectories: the smooth bang-bang Euler profile of Sadigh et al. 2022.

Per 3-2-1 Euler angle j (roll φ, pitch θ, yaw ψ), eq. (36):
``θ_j(t) = θ_j0 + K_j ∫∫ f``, with ``K_j = T_max/J_jj`` and the smooth sign function
``f`` of eq. (37) (Δt = t_f/4, so f rises 0→1 on [0, t_f/4], falls 1→−1 on
[t_f/4, 3t_f/4], returns −1→0 on [3t_f/4, t_f], and is 0 afterwards — assumed: the paper
does not say what follows t_f). The third branch uses ``t − t1``: the printed ``t − t2``
would give f(t2) = −5, so it is read as a misprint. The slew is
parameterized by its increment: ``K_j = Δθ_j / (0.13125 t_f²)`` (∫∫f over [0, t_f] =
21/160 t_f²). Quaternion by eq. (38) (3-2-1, :func:`attitude_envs.quaternion.from_euler_321_deg`).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Polynomial as P

from attitude_envs import validation
from attitude_envs.plants import magnetorquer_kernels as kernels

SLEW_FACTOR = 21.0 / 160.0  # ∫0^tf ∫0^τ f = 0.13125 t_f² (eq. 37)


def _segments(t_final_s: float) -> list[tuple[float, float, P]]:
    """Pieces (start, end, f as a polynomial in absolute time) of eq. (37)."""
    dt = 0.25 * t_final_s
    t1, t3 = 0.5 * t_final_s - dt, t_final_s - dt
    s = P([0.0, 1.0])
    rise = (s / dt) ** 2 * (3.0 - 2.0 * s / dt)
    fall_arg = (s - t1) / (2.0 * dt)
    fall = 1.0 - 2.0 * fall_arg**2 * (3.0 - 2.0 * fall_arg)
    ret_arg = (s - t3) / dt
    back = -1.0 + ret_arg**2 * (3.0 - 2.0 * ret_arg)
    return [(0.0, t1, rise), (t1, t3, fall), (t3, t_final_s, back)]


class SmoothBangBang:
    """Euler-angle reference of Sadigh et al. 2022, eqs. (36)–(38); angles deg, time s.

    ``delta_deg``: slew increment [Δφ, Δθ, Δψ]; ``start_deg``: θ0; ``t_final_s``: t_f;
    the rates at t0 = 0 are zero and the angles are held after t_f (assumed: the paper
    gives none of θ0, θ̇0, t0, t_f or T_max; the default slew is ours).
    """

    def __init__(self, delta_deg=(10.0, 20.0, 10.0), t_final_s: float = 1200.0, start_deg=(0.0, 0.0, 0.0)) -> None:
        self.delta_rad = np.radians(validation.finite_array("reference.delta_deg", delta_deg, (3,)))
        self.start_rad = np.radians(validation.finite_array("reference.start_deg", start_deg, (3,)))
        self.t_final_s = validation.positive("reference.t_final_s", t_final_s)
        self.gain = self.delta_rad / (SLEW_FACTOR * self.t_final_s**2)  # K_j = T_max/J_jj, rad/s²
        self._pieces = []
        v0, p0 = 0.0, 0.0
        for a, b, f in _segments(self.t_final_s):
            v = f.integ(lbnd=a) + v0  # ∫f from a, plus the running value
            p = v.integ(lbnd=a) + p0
            self._pieces.append((a, b, f.coef[::-1].tolist(), v.coef[::-1].tolist(), p.coef[::-1].tolist()))
            v0, p0 = float(v(b)), float(p(b))
        self._constant = bool(np.all(self.delta_rad == 0.0))
        self._final = (v0, p0)
        #: the profile in the layout of the compiled evaluator (one implementation)
        self.packed = kernels.pack_reference(
            self._constant, self.t_final_s, self.start_rad, self.gain, self._final, self._pieces
        )

    def profile(self, t_s: float) -> tuple[float, float, float]:
        """(∫∫f, ∫f, f) at ``t_s`` (s², s, 1)."""
        return kernels.profile(self.packed, 0, float(t_s))

    def euler(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Angles (rad) and angle rates (rad/s) [φ, θ, ψ]."""
        p, v, _ = self.profile(t_s)
        return self.start_rad + self.gain * p, self.gain * v

    def attitude(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired quaternion (scalar last, w ≥ 0), its body rate ω_d (rad/s, desired axes,
        relative to the orbital frame) and its time derivative q̇_d (1/s); held before 0 and
        after t_f. Quaternion by eq. (38) (3-2-1, as :func:`attitude_envs.quaternion.from_euler_321_deg`)."""
        out = np.empty(11)
        kernels.reference_into(self.packed, 0, float(t_s), out, 0)
        return out[:4], out[4:7], out[7:]
