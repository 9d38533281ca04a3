"""Fault-tolerant sliding-mode attitude tracking of Sadigh, Kashaninia & Dehghan 2022 (Journal of
Control 15(4); magnetorquers + one y wheel).

* :class:`AMNFTSMCPolicy` — adaptive modified nonsingular fast terminal SMC, eqs. (18)–(24):
  ``u_c = u_eq − (ρ1 + 1) Ĥ φ sign(S)``, ``dĤ/dt = μ φ ‖S‖`` (Ĥ never decreases);
* :class:`MNFTSMCPolicy` — the non-adaptive version, eq. (41): ``u_c = u_eq − ρ2 sign(S)``;
* :class:`FTSMCStandInPolicy` — **a stand-in, not the paper's FTSMC [13]** (whose reference
  list is missing): the same law with the unmodified terminal term ``sig^r(q_e)`` (assumed);
* :func:`allocate_paper` — eqs. (16)–(17): ``m = b × u_c/|b|²`` (the component of the demand
  perpendicular to b), saturated, then ``T_w = [u_c − m × b]_y`` clipped; variants "xz" and
  "exact" (the wheel first takes the along-b part, so the whole demand is realized).

Sliding variable, eq. (18): ``S = ω_bo + γ1 q_e + γ2 s_c(q_e)`` with the additive error
``q_e = q − q_d`` (vector parts, scalar-first sign w ≥ 0). Every parameter the paper omits
is a documented default of :class:`SlidingModeGains` that the user can override.
All controllers use the nominal model (``env.unwrapped.model``) and the measured q, ω_bo, Ω
and body-frame field ``b`` (``info["measured"]``: the sensor layer's view, never the truth),
tracking the commanded reference ``info["reference"]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from attitude_envs import quaternion, validation
from attitude_envs.info import MEASURED
from attitude_envs.plants.magnetorquer import E_Y, orbital_to_body
from attitude_envs.quaternion import cross

ALLOCATIONS = ("paper", "xz", "exact")


@dataclass(frozen=True)
class SlidingModeGains:
    """Controller parameters: from the paper, or "assumed" where the paper omits them.

    * ``gamma1``, ``gamma2`` (1/s) (assumed 0.01, 0.001); ``r`` (assumed 0.6); ``epsilon``
      (assumed 0.01); ``kappa1``, ``kappa2`` — None: the C¹ construction
      κ1 = (2−r)ϵ^(r−1), κ2 = (r−1)ϵ^(r−2) (κ2 < 0, unlike the text's "κ2 > 0");
    * ``rho1`` = ``rho2`` = 0.0015 N·m (paper), ``h0`` = Ĥ(0) = 0.605 (paper), ``mu``
      (adaptation rate, assumed 0.1), ``p`` = ``q`` = 2 in φ (eq. 21, assumed), φ fed by ω_bi
      (assumed);
    * ``boundary_layer`` δ (rad/s): None = ``sign(S)`` as printed; a number uses ``sat(S/δ)``
      (off by default);
    * ``allocation``: ``"paper"`` (eq. 16 on the whole demand), ``"xz"`` (only the x/z
      demand goes to the magnetorquers) or ``"exact"`` (eq. 16 on the demand
      less the wheel torque that makes it perpendicular to b: realizes any demand within the
      limits, see :func:`allocate_paper`); ``dipole_saturation``: ``"scale"``
      (direction-preserving, default) or ``"clip"`` (per axis).
    """

    gamma1: float = 0.01
    gamma2: float = 0.001
    r: float = 0.6
    epsilon: float = 0.01
    kappa1: float | None = None
    kappa2: float | None = None
    rho1: float = 0.0015
    rho2: float = 0.0015
    h0: float = 0.605
    mu: float = 0.1
    p: float = 2.0
    q: float = 2.0
    boundary_layer: float | None = None
    allocation: str = "paper"
    dipole_saturation: str = "scale"

    def __post_init__(self) -> None:
        for name in ("gamma1", "gamma2", "epsilon", "rho1", "rho2", "mu", "p", "q"):
            validation.positive(name, getattr(self, name))
        validation.nonnegative("h0", self.h0)
        if not 0.0 < float(self.r) < 1.0:
            raise ValueError(f"r must be in (0, 1), got {self.r!r}")
        if self.boundary_layer is not None:
            validation.positive("boundary_layer", self.boundary_layer)
        validation.choice("allocation", self.allocation, ALLOCATIONS)
        validation.choice("dipole_saturation", self.dipole_saturation, {"scale", "clip"})
        if self.kappa1 is None:
            object.__setattr__(self, "kappa1", (2.0 - self.r) * self.epsilon ** (self.r - 1.0))
        if self.kappa2 is None:
            object.__setattr__(self, "kappa2", (self.r - 1.0) * self.epsilon ** (self.r - 2.0))


def terminal_term(q_e: np.ndarray, gains: SlidingModeGains, modified: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``s_c`` of eq. (19) and its derivative ``ds_c/dq_e`` of eq. (24), element-wise.

    ``modified=False`` is the plain ``sig^r`` term of the FTSMC stand-in, its derivative
    evaluated at ``max(|q_e|, 1e-6)`` (assumed).
    """
    a = np.abs(q_e)
    sgn = np.sign(q_e)
    if not modified:
        return sgn * a**gains.r, gains.r * np.maximum(a, 1e-6) ** (gains.r - 1.0)
    near = a < gains.epsilon
    s_c = np.where(near, gains.kappa1 * q_e + gains.kappa2 * sgn * q_e**2, sgn * a**gains.r)
    ds = np.where(
        near, gains.kappa1 + 2.0 * gains.kappa2 * a, gains.r * np.maximum(a, gains.epsilon) ** (gains.r - 1.0)
    )
    return s_c, ds


def allocate_paper(
    u_c: np.ndarray,
    b_body_t: np.ndarray,
    max_dipole_am2: float,
    max_wheel_torque_nm: float,
    saturation: str = "scale",
    variant: str = "paper",
) -> tuple[np.ndarray, float]:
    """Eqs. (16)–(17) of Sadigh, Kashaninia & Dehghan 2022: dipole (A·m²) and wheel body torque (N·m) for a demand ``u_c``.

    ``m = b × u/|b|²`` makes ``m × b`` the component of ``u`` perpendicular to ``b``. The
    dipole is saturated (direction-preserving ``"scale"`` or per-axis ``"clip"``) and the
    wheel takes the y component of what is left, ``T_w = [u_c − m × b]_y`` (eq. 17), clipped
    to ±max_wheel_torque_nm. ``u`` depends on ``variant``:

    * ``"paper"``: ``u = u_c`` (eq. 16). The x/z part of ``u_c``'s component along b is lost.
    * ``"xz"``: ``u = [u_cx, 0, u_cz]``; the wheel alone takes the y demand.
      About the x/z axis ``ê ∥ [b_x, 0, b_z]`` only the fraction ``b_y²/|b|²`` is realized.
    * ``"exact"``: ``u = u_c − k T* e_y`` with ``T* = (u_c·b)/b_y``, the wheel torque that
      leaves a demand perpendicular to b. With ``k = 1``, ``m × b + T_w e_y = u_c`` exactly
      (the one solution with ``m ⊥ b``; a dipole along b makes no torque) and eq. (17)
      returns ``T_w = T*``. ``k ∈ [0, 1]`` is the largest value that keeps the dipole and
      ``k T*`` within their limits (``b_y → 0`` needs an unbounded T*): the perpendicular
      part ``u_⊥`` is realized first (``k = 0`` is eq. 16) and then as much of the along-b
      part as the limits allow; the realized x/z torque is ``u_⊥ + k u_∥`` and y is exact.
      When ``u_⊥`` alone exceeds the dipole limits, ``k = 0`` and ``m`` is saturated as above.
    """
    validation.choice("variant", variant, ALLOCATIONS)
    b2 = float(b_body_t @ b_body_t)
    if b2 <= 0.0:
        raise ValueError("b_body_t must be non-zero to allocate magnetic torque")
    if variant == "xz":
        u = np.array([u_c[0], 0.0, u_c[2]])
    elif variant == "exact":
        u = u_c - _along_b_wheel_share(u_c, b_body_t, b2, max_dipole_am2, max_wheel_torque_nm) * E_Y
    else:
        u = u_c
    m = cross(b_body_t, u) / b2
    peak = float(np.max(np.abs(m)))
    if saturation == "scale":
        if peak > max_dipole_am2:
            m = m * (max_dipole_am2 / peak)
    else:
        m = np.clip(m, -max_dipole_am2, max_dipole_am2)
    t_w = float(np.clip((u_c - cross(m, b_body_t))[1], -max_wheel_torque_nm, max_wheel_torque_nm))
    return m, t_w


def _along_b_wheel_share(u_c: np.ndarray, b: np.ndarray, b2: float, max_dipole: float, max_wheel: float) -> float:
    """``k T*`` of the "exact" allocation (N·m): ``T* = (u_c·b)/b_y``, ``k`` the largest value in
    [0, 1] with ``|m_i(k T*)| ≤ max_dipole`` and ``|k T*| ≤ max_wheel``, where
    ``m(T) = b × (u_c − T e_y)/|b|²`` (0 when ``m(0)`` is already outside the limits)."""
    along = float(u_c @ b)
    if along == 0.0:
        return 0.0
    m0 = cross(b, u_c) / b2
    if np.max(np.abs(m0)) > max_dipole:
        return 0.0
    if b[1] == 0.0:
        return 0.0  # no wheel torque makes torque along b
    t_star = along / b[1]
    dm = -t_star * cross(b, E_Y) / b2  # m(k T*) = m0 + k dm
    k = min(1.0, max_wheel / abs(t_star))
    for a, c in zip(m0.tolist(), dm.tolist(), strict=True):
        if c > 0.0:
            k = min(k, (max_dipole - a) / c)
        elif c < 0.0:
            k = min(k, (-max_dipole - a) / c)
    return k * t_star


@dataclass
class _History:
    time_s: list = field(default_factory=list)
    gain: list = field(default_factory=list)
    sliding: list = field(default_factory=list)
    demand_nm: list = field(default_factory=list)


class SlidingModeController:
    """Shared machinery of the three laws; ``law`` in {"amnftsmc", "mnftsmc", "ftsmc"}."""

    law = "mnftsmc"
    name = "MNFTSMC"

    def __init__(self, env, gains: SlidingModeGains | None = None, record: bool = False, **overrides) -> None:
        model = env.unwrapped.model
        base = gains or SlidingModeGains()
        if overrides and ({"r", "epsilon"} & set(overrides)):
            # κ1, κ2 follow r and ϵ unless given explicitly
            overrides = {"kappa1": None, "kappa2": None, **overrides}
        self.gains = replace(base, **overrides) if overrides else base
        self.inertia = model.params.inertia_kg_m2
        self.wheel_inertia = model.params.wheel_inertia_kg_m2
        self.max_dipole = model.params.max_dipole_am2
        self.max_wheel_torque = model.params.max_wheel_torque_nm
        self.orbital_rate = model.orbital_rate_rad_s
        self.dt = model.control_dt_s
        self.record = record
        self.gain = self.gains.h0
        self.history = _History()

    def reset(self, seed: int | None = None) -> None:
        self.gain = self.gains.h0
        self.history = _History()

    def demand(self, info: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, float]:
        """The commanded body torque ``u_c`` (N·m), the sliding variable S and φ."""
        g = self.gains
        st = info[MEASURED]
        q = np.asarray(st["attitude"], dtype=float)
        if q[3] < 0:
            q = -q
        q0, qv = q[3], q[:3]
        w_bo = np.asarray(st["rate_rad_s"], dtype=float)
        om = float(st["wheel_speed_rad_s"][0])
        ref = info["reference"]
        q_d = np.asarray(ref["attitude"], dtype=float)
        q_d_dot = np.asarray(ref["attitude_rate"], dtype=float)
        if q_d[3] < 0:
            q_d, q_d_dot = -q_d, -q_d_dot
        r_w_oi = -self.orbital_rate * orbital_to_body(q)[:, 1]
        w_bi = w_bo + r_w_oi
        q_e = qv - q_d[:3]
        q_e_dot = 0.5 * (quaternion.skew(qv) @ w_bo + q0 * w_bo) - q_d_dot[:3]
        s_c, ds = terminal_term(q_e, g, modified=self.law != "ftsmc")
        s = w_bo + g.gamma1 * q_e + g.gamma2 * s_c  # eq. (18)
        h = self.inertia @ w_bi + self.wheel_inertia * om * E_Y
        u_eq = (
            cross(w_bi, h)
            - self.inertia @ (g.gamma1 * q_e_dot)
            - self.inertia @ cross(w_bo, r_w_oi)
            - self.inertia @ (g.gamma2 * ds * q_e_dot)
        )  # eq. (23)
        n = float(np.linalg.norm(w_bi))
        phi = 1.0 + n + n**2 + n**g.p + n**g.q + n ** (g.p * g.q)  # eq. (21)
        switch = np.sign(s) if g.boundary_layer is None else np.clip(s / g.boundary_layer, -1.0, 1.0)
        if self.law == "amnftsmc":
            u_c = u_eq - (g.rho1 + 1.0) * self.gain * phi * switch  # eq. (20)
        else:
            u_c = u_eq - g.rho2 * switch  # eq. (41)
        return u_c, s, phi

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        u_c, s, phi = self.demand(info)
        b = np.asarray(info[MEASURED]["magnetic_field_body_t"], dtype=float)
        m, t_w = allocate_paper(
            u_c, b, self.max_dipole, self.max_wheel_torque, self.gains.dipole_saturation, self.gains.allocation
        )
        if self.record:
            self.history.time_s.append(float(info["time_s"]))
            self.history.gain.append(self.gain)
            self.history.sliding.append(s)
            self.history.demand_nm.append(u_c)
        if self.law == "amnftsmc":
            self.gain += self.gains.mu * phi * float(np.linalg.norm(s)) * self.dt  # eq. (22), explicit Euler
        return np.concatenate([m / self.max_dipole, [t_w / self.max_wheel_torque]]).astype(np.float32)


class AMNFTSMCPolicy(SlidingModeController):
    """Adaptive modified nonsingular fast terminal SMC (the paper's proposed law)."""

    law = "amnftsmc"
    name = "AMNFTSMC"


class MNFTSMCPolicy(SlidingModeController):
    """Non-adaptive MNFTSMC, eq. (41)."""

    law = "mnftsmc"
    name = "MNFTSMC"


class FTSMCStandInPolicy(SlidingModeController):
    """FTSMC **stand-in** (assumed: the paper's ref. [13] is missing): plain sig^r terminal term, ``−ρ2 sign(S)``; not ref. [13]."""

    law = "ftsmc"
    name = "FTSMC (stand-in)"
