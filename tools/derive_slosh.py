"""Derive the fuel-slosh equations of motion with sympy (development tool): the
Lagrangian model of Navabi & Davoodi, eqs. 1–10.

Generalized coordinates q = [X, Z, θ, ψ1, ψ2] in an *inertial* frame (no body-frame
quasi-velocities, so the derivation is plain Euler–Lagrange):

    d/dt ∂T/∂q̇ − ∂T/∂q + ∂R/∂q̇ = Q(δ, M_c),   R = ½ Σ ε_i ψ̇_i²  (the paper's eq. 10)

Body axes: i = (cos θ, −sin θ), k = (sin θ, cos θ) in (X, Z), so a body point (x, z) sits
at R_O + x i + z k. The thrust F(cos δ i + sin δ k) acts at x = −(b + d); the couple M_c
acts on θ. The generalized forces follow from virtual work.

``residual_function()`` returns a numeric function of (q, q̇, q̈, params, δ, M_c) that is
zero for motions satisfying the equations; the tests feed it the accelerations of the
closed-form body-frame plant in :mod:`attitude_envs.plants.slosh` (the paper's eqs. 11–14). Running
this file prints the largest residual over random states.
"""

from __future__ import annotations

import functools

import sympy as sp

PARAM_NAMES = ("m", "I", "m0", "I0", "m1", "m2", "I1", "I2", "a0", "a1", "a2", "l1", "l2", "b", "d", "F", "e1", "e2")


@functools.lru_cache(maxsize=1)
def residual_function():
    """Lambdified residual ``r(q, qd, qdd, params, delta, moment) -> 5 values``."""
    t = sp.symbols("t")
    X, Z, th, p1, p2 = (sp.Function(n)(t) for n in ("X", "Z", "th", "p1", "p2"))
    q = [X, Z, th, p1, p2]
    par = sp.symbols(PARAM_NAMES)
    m, I, m0, I0, m1, m2, I1, I2, a0, a1, a2, l1, l2, b, d, F, e1, e2 = par
    delta, Mc = sp.symbols("delta M_c")
    ihat = sp.Matrix([sp.cos(th), -sp.sin(th)])
    khat = sp.Matrix([sp.sin(th), sp.cos(th)])
    origin = sp.Matrix([X, Z])

    def point(x, z):
        return origin + x * ihat + z * khat

    def ke(mass, r):
        v = r.diff(t)
        return sp.Rational(1, 2) * mass * (v.T * v)[0]

    T = ke(m, point(-b, 0)) + ke(m0, point(a0, 0)) + sp.Rational(1, 2) * (I + I0) * th.diff(t) ** 2
    for mi, Ii, ai, li, psi in ((m1, I1, a1, l1, p1), (m2, I2, a2, l2, p2)):
        T += ke(mi, point(ai - li * sp.cos(psi), li * sp.sin(psi)))
        T += sp.Rational(1, 2) * Ii * (th.diff(t) + psi.diff(t)) ** 2
    R = sp.Rational(1, 2) * (e1 * p1.diff(t) ** 2 + e2 * p2.diff(t) ** 2)

    # virtual work of the thrust at the gimbal and of the couple on θ
    force = F * (sp.cos(delta) * ihat + sp.sin(delta) * khat)
    r_gimbal = point(-(b + d), 0)
    Qgen = [(force.T * r_gimbal.diff(qj))[0] for qj in q]
    Qgen[2] += Mc

    eqs = []
    for j, qj in enumerate(q):
        qdj = qj.diff(t)
        eqs.append(T.diff(qdj).diff(t) - T.diff(qj) + R.diff(qdj) - Qgen[j])

    qs = sp.symbols("X Z th p1 p2")
    qds = sp.symbols("Xd Zd thd p1d p2d")
    qdds = sp.symbols("Xdd Zdd thdd p1dd p2dd")
    subs = {}
    for f, sd, sdd in zip(q, qds, qdds, strict=True):
        subs[f.diff(t, 2)] = sdd
        subs[f.diff(t)] = sd
    plain = []
    for e in eqs:
        e = e.subs(subs)
        e = e.subs(dict(zip(q, qs, strict=True)))
        plain.append(sp.expand(e))
    fn = sp.lambdify((qs, qds, qdds, par, delta, Mc), plain, modules="math")
    return fn


def params_tuple(p) -> tuple[float, ...]:
    """The sympy parameter tuple of a :class:`attitude_envs.plants.slosh.SloshParams`."""
    return (
        p.mass_kg,
        p.inertia_kg_m2,
        p.fuel_mass_kg,
        p.fuel_inertia_kg_m2,
        p.slosh_mass_kg[0],
        p.slosh_mass_kg[1],
        p.slosh_inertia_kg_m2[0],
        p.slosh_inertia_kg_m2[1],
        p.fuel_offset_m,
        p.hinge_m[0],
        p.hinge_m[1],
        p.length_m[0],
        p.length_m[1],
        p.b_m,
        p.d_m,
        p.thrust_n,
        p.damping_kg_m2_s[0],
        p.damping_kg_m2_s[1],
    )


def inertial_accelerations(y, dy):
    """(q, q̇, q̈) in inertial coordinates from the body-frame state ``y`` and its ``ẏ``."""
    import math

    X, Z, th, p1, p2, vx, vz, om, dp1, dp2 = y
    dvx, dvz, dom, ddp1, ddp2 = dy[5:]
    c, s = math.cos(th), math.sin(th)
    Xd, Zd = vx * c + vz * s, -vx * s + vz * c
    Xdd = dvx * c - vx * s * om + dvz * s + vz * c * om
    Zdd = -dvx * s - vx * c * om + dvz * c - vz * s * om
    return (X, Z, th, p1, p2), (Xd, Zd, om, dp1, dp2), (Xdd, Zdd, dom, ddp1, ddp2)


def max_relative_residual(params, y, delta: float, moment: float) -> float:
    """Largest residual of the inertial Lagrange equations under the plant's ẏ, relative
    to the size of the terms (the thrust F or the largest generalized force)."""
    from attitude_envs.plants import slosh

    dy = slosh.derivative(params, y, delta, moment)
    q, qd, qdd = inertial_accelerations(y, dy)
    res = residual_function()(q, qd, qdd, params_tuple(params), delta, moment)
    scale = max(1.0, params.thrust_n, abs(moment), params.total_mass_kg * max(abs(v) for v in qdd[:2]))
    return max(abs(r) for r in res) / scale


if __name__ == "__main__":
    import numpy as np

    from attitude_envs.plants import slosh

    rng = np.random.default_rng(0)
    worst = 0.0
    for preset in slosh.FILL_PRESETS:
        p = slosh.SloshParams.from_fill_preset(preset)
        for _ in range(50):
            y = rng.normal(size=10) * [10, 10, 1, 1, 1, 3000, 50, 0.5, 2, 2]
            worst = max(worst, max_relative_residual(p, y, rng.uniform(-1, 1), rng.normal() * 500))
    print(f"largest relative residual of the Lagrange equations: {worst:.3e}")
