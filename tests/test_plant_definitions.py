"""The plants defined once (:mod:`attitude_envs.plants.ops`): every executor of a definition
computes the same numbers — compiled numba and plain Python bit for bit, a numpy batch equal
to its rows, CasADi's and JAX's evaluations to rounding (CasADi's virtual machine and XLA
order a few operations their own way) — and the limit rows say what the envs' limit checks
said."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attitude_envs.plants import slosh_definition
from attitude_envs.plants.ops import NUMBA, NUMPY
from attitude_envs.plants.slosh import SloshParams


def _slosh_cases(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    pk = SloshParams().packed
    ys = rng.normal(size=(n, 10)) * np.array([1, 1, 0.5, 0.8, 0.8, 10, 1, 0.3, 1, 1])
    deltas = rng.uniform(-0.1, 0.1, n)
    moments = rng.uniform(-50, 50, n)
    Q = np.diag(rng.uniform(0.5, 2.0, 7)) + 0.01 * rng.normal(size=(7, 7))
    R = np.diag(rng.uniform(0.5, 2.0, 2))
    return pk, ys, deltas, moments, Q, R


def test_slosh_numba_equals_plain_python_bit_for_bit():
    pk, ys, deltas, moments, Q, R = _slosh_cases(200)
    compiled, plain = slosh_definition.define(NUMBA), slosh_definition.define(NUMPY)
    for y, d, m in zip(ys, deltas, moments, strict=True):
        args = (pk, y, math.sin(d), math.cos(d), m, Q, R)
        dy_c, stage_c, az_c, dom_c = compiled.augmented(*args)
        dy_p, stage_p, az_p, dom_p = plain.augmented(*args)
        assert np.array_equal(np.array(dy_c), np.array([float(v) for v in dy_p]))
        assert (stage_c, az_c, dom_c) == (float(stage_p), float(az_p), float(dom_p))


def test_slosh_numpy_batch_equals_its_rows():
    pk, ys, deltas, moments, _, _ = _slosh_cases(64, seed=1)
    plain = slosh_definition.define(NUMPY)
    batch = np.array(plain.derivative(pk, ys.T, np.sin(deltas), np.cos(deltas), moments))
    rows = np.array(
        [plain.derivative(pk, y, math.sin(d), math.cos(d), m) for y, d, m in zip(ys, deltas, moments, strict=True)]
    )
    assert np.array_equal(batch.T, rows)


def test_slosh_packed_constants_match_the_physical_parameters():
    p = SloshParams()
    m, a, l = np.array(p.slosh_mass_kg), np.array(p.hinge_m), np.array(p.length_m)
    pk = p.packed
    assert pk[slosh_definition.P_MT] == pytest.approx(p.mass_kg + p.fuel_mass_kg + m.sum(), rel=1e-15)
    s_z = p.mass_kg * p.b_m - p.fuel_mass_kg * p.fuel_offset_m - m @ a
    assert pk[slosh_definition.P_SZ] == pytest.approx(s_z, rel=1e-15)
    assert np.allclose(pk[[slosh_definition.P_J1, slosh_definition.P_J2]], np.array(p.slosh_inertia_kg_m2) + m * l**2)
    assert pk[slosh_definition.P_LEVER] == p.b_m + p.d_m


@pytest.mark.parametrize("value", [0.3, -0.3, 0.2999999999999999, 0.30000000000000004, -0.30000000000000004, np.nan])
def test_slosh_limit_rows_cross_exactly_where_the_absolute_value_exceeds_the_limit(value):
    plain = slosh_definition.define(NUMPY)
    limit = 0.3
    for index in (2, 3, 4, 7):
        y = np.zeros(10)
        y[index] = value
        crossed = max(plain.limit_rows(y, limit, limit, limit)) > 0.0
        assert crossed == bool(abs(value) > limit), (index, value)


def test_slosh_casadi_evaluates_the_definition_to_rounding():
    casadi = pytest.importorskip("casadi")
    from attitude_envs.symbolic.ops import CASADI

    pk, ys, deltas, moments, Q, R = _slosh_cases(50, seed=2)
    y = casadi.SX.sym("y", 10)
    s, c, mom = casadi.SX.sym("s"), casadi.SX.sym("c"), casadi.SX.sym("m")
    dy, stage, _, _ = slosh_definition.define(CASADI).augmented(pk, y, s, c, mom, casadi.DM(Q), casadi.DM(R))
    fn = casadi.Function("f", [y, s, c, mom], [casadi.vertcat(*dy, stage)])
    compiled = slosh_definition.define(NUMBA)
    for yv, d, m in zip(ys, deltas, moments, strict=True):
        want_dy, want_stage, _, _ = compiled.augmented(pk, yv, math.sin(d), math.cos(d), m, Q, R)
        got = np.asarray(fn(yv, math.sin(d), math.cos(d), m)).ravel()
        np.testing.assert_allclose(got, np.array([*want_dy, want_stage]), rtol=1e-13, atol=1e-13)


def test_slosh_jax_traces_the_definition_to_rounding():
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from attitude_envs.jax.ops import JAX

    pk, ys, deltas, moments, Q, R = _slosh_cases(50, seed=3)
    traced = slosh_definition.define(JAX)

    @jax.jit
    @jax.vmap
    def f(y, d, m):
        dy, stage, _, _ = traced.augmented(
            jnp.asarray(pk), y, jnp.sin(d), jnp.cos(d), m, jnp.asarray(Q), jnp.asarray(R)
        )
        return jnp.stack([*dy, stage])

    got = np.asarray(f(jnp.asarray(ys), jnp.asarray(deltas), jnp.asarray(moments)))
    compiled = slosh_definition.define(NUMBA)
    want = np.array(
        [
            np.array([*r[0], r[1]])
            for r in (
                compiled.augmented(pk, y, math.sin(d), math.cos(d), m, Q, R)
                for y, d, m in zip(ys, deltas, moments, strict=True)
            )
        ]
    )
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-12)
