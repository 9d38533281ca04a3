"""The plants defined once (:mod:`attitude_envs.plants.ops`): every executor of a definition
computes the same numbers — compiled numba and plain Python bit for bit, a numpy batch equal
to its rows, CasADi's and JAX's evaluations to rounding (CasADi's virtual machine and XLA
order a few operations their own way) — and the limit rows say what the envs' limit checks
said."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attitude_envs.plants import magnetorquer_definition, slosh_definition
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


def _inversion_cases(n: int, seed: int):
    """Full states at speed and new inputs, about 1 in 20 beyond the thrust's transverse authority."""
    rng = np.random.default_rng(seed)
    ys = rng.normal(size=(n, 10)) * np.array([10, 10, 0.3, 0.3, 0.3, 3000, 5, 0.05, 0.1, 0.1])
    ys[:, 5] = np.abs(ys[:, 5])
    return ys, rng.normal(size=n), 0.01 * rng.normal(size=n)


def test_slosh_inversion_realizes_the_new_inputs_on_every_executor():
    """``invert_inputs``: compiled numba and plain Python bit for bit; the (δ, M_c) it returns
    make the definition's own derivative give a_z = u1 and Ω̇ = u2 wherever |sin δ| ≤ 1;
    JAX and CasADi evaluate it to rounding."""
    jax = pytest.importorskip("jax")
    casadi = pytest.importorskip("casadi")
    import jax.numpy as jnp

    from attitude_envs.jax.ops import JAX
    from attitude_envs.plants.ops import PYTHON
    from attitude_envs.symbolic.ops import CASADI

    pk = SloshParams().packed
    ys, u1s, u2s = _inversion_cases(300, seed=4)
    compiled, plain = slosh_definition.define(NUMBA), slosh_definition.define(PYTHON)
    want = []
    for y, u1, u2 in zip(ys, u1s, u2s, strict=True):
        got = compiled.invert_inputs(pk, y, u1, u2, 6)
        assert got == plain.invert_inputs(pk, y, u1, u2, 6)
        want.append(got)
        delta, moment, saturated = got
        if not saturated:
            dy = compiled.derivative(pk, y, math.sin(delta), math.cos(delta), moment)
            assert dy[6] - y[7] * y[5] == pytest.approx(u1, rel=1e-9, abs=1e-12)
            # Ω̇ is the small difference of large terms at v_x ≈ 3000 m/s: round-off ≈ 5e-10 of it
            assert dy[7] == pytest.approx(u2, rel=1e-8, abs=1e-12)
    want = np.array(want, dtype=float)
    assert 0 < want[:, 2].sum() < 60  # both branches taken

    traced = slosh_definition.define(JAX)
    with jax.enable_x64(True):  # a context, never the global config (other tests run in float32)
        f = jax.jit(jax.vmap(lambda y, a, b: jnp.stack(traced.invert_inputs(jnp.asarray(pk), y, a, b, 6))))
        got = np.asarray(f(jnp.asarray(ys), jnp.asarray(u1s), jnp.asarray(u2s)))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-10)

    y, a, b = casadi.SX.sym("y", 10), casadi.SX.sym("a"), casadi.SX.sym("b")
    fn = casadi.Function(
        "inv", [y, a, b], [casadi.vertcat(*slosh_definition.define(CASADI).invert_inputs(pk, y, a, b, 6))]
    )
    for yv, u1, u2, row in zip(ys[:40], u1s[:40], u2s[:40], want[:40], strict=True):
        np.testing.assert_allclose(np.asarray(fn(yv, u1, u2)).ravel(), row, rtol=1e-12, atol=1e-10)


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

    with jax.enable_x64(True):  # a context, never the global config (other tests run in float32)
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


def _magnetorquer_cases(n: int, seed: int = 0):
    """Random augmented states, commands and time contexts (compact layout)."""
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, 9)) * np.array([1, 1, 1, 1, 1e-2, 1e-2, 1e-2, 100, 0])
    m = rng.uniform(-0.2, 0.2, (n, 3))
    t_w = rng.uniform(-1e-3, 1e-3, n)
    ctx = np.empty((n, magnetorquer_definition.COMPACT_SIZE))
    ctx[:, 0] = rng.uniform(1e-3, 1.2e-3, n)  # ν̇
    ctx[:, 1] = rng.normal(0, 1e-8, n)  # ν̈
    ctx[:, 2] = rng.uniform(6.7e6, 7.2e6, n)  # r
    ctx[:, 3:6] = rng.normal(0, 3e-5, (n, 3))  # b_orb
    q_d = rng.normal(size=(n, 4))
    ctx[:, 6:10] = q_d / np.linalg.norm(q_d, axis=1, keepdims=True)
    ctx[:, 10:13] = rng.normal(0, 1e-3, (n, 3))
    inertia = np.diag([0.03, 0.04, 0.05]) + 1e-3 * rng.normal(size=(3, 3))
    inertia = 0.5 * (inertia + inertia.T)
    ctx[:, 13:22] = inertia.ravel()
    ctx[:, 22:31] = np.linalg.inv(inertia - 1e-5 * np.outer([0, 1, 0], [0, 1, 0])).ravel()
    ctx[:, 31:34] = rng.normal(0, 1e-6, (n, 3))
    Q = np.diag([1.0, 2.0, 3.0, 1e3, 2e3, 3e3]) + 0.1 * np.ones((6, 6))
    R = np.diag([10.0, 20.0, 30.0])
    return z, m, t_w, ctx, Q, R


def _magnetorquer_args(z, m, t_w, ctx, Q, R, *, gravity=True, diagonal=False, flip=True):
    layout = magnetorquer_definition.COMPACT_LAYOUT
    return (z, 0, m, t_w, ctx, 0, layout, 1e-5, gravity, Q, R, diagonal, flip)


@pytest.mark.parametrize("gravity", [True, False])
def test_magnetorquer_numba_equals_plain_python_bit_for_bit(gravity):
    compiled, plain = magnetorquer_definition.define(NUMBA), magnetorquer_definition.define(NUMPY)
    for row in zip(*_magnetorquer_cases(100)[:4], strict=True):
        z, m, t_w, ctx = row
        _, _, _, _, Q, R = _magnetorquer_cases(1)
        want = compiled.augmented(*_magnetorquer_args(z, m, t_w, ctx, Q, R, gravity=gravity))
        got = plain.augmented(*_magnetorquer_args(z, m, t_w, ctx, Q, R, gravity=gravity))
        assert np.array_equal(np.array(want), np.array([float(v) for v in got]))


def test_magnetorquer_diagonal_path_sums_as_the_full_forms():
    """The stage cost's diagonal path skips only zero products: for diagonal weights it equals
    the full quadratic forms bit for bit (the JAX twin always takes the full forms)."""
    compiled = magnetorquer_definition.define(NUMBA)
    rng = np.random.default_rng(4)
    Q, R = np.diag(rng.uniform(1, 5, 6)), np.diag(rng.uniform(1, 5, 3))
    for _ in range(200):
        x, u = tuple(rng.normal(size=6)), tuple(rng.normal(size=3))
        assert compiled.stage_cost(Q, R, x, u, True) == compiled.stage_cost(Q, R, x, u, False)


def test_magnetorquer_error_state_sign_and_wheel_momentum_limit():
    plain = magnetorquer_definition.define(NUMPY)
    ref = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    flipped = plain.error_state(0.1, 0.2, 0.3, -0.9, 0.0, 0.0, 0.0, ref, 0, True)
    kept = plain.error_state(0.1, 0.2, 0.3, -0.9, 0.0, 0.0, 0.0, ref, 0, False)
    assert flipped[6] > 0 and kept[6] < 0
    assert np.allclose(flipped[:3], [-0.1, -0.2, -0.3]) and np.allclose(kept[:3], [0.1, 0.2, 0.3])
    # h_w = J_w (Ω + ω_bo,y − ν̇) at q = identity: J_w = 1, Ω = 2, ω_bo,y = 0, ν̇ = 0 -> h_w = 2
    # T_w acts on the body, −T_w on the wheel: a negative T_w grows a positive h_w
    assert plain.wheel_torque(-0.5, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 2.0) == 0.0  # at the limit: blocked
    assert plain.wheel_torque(0.5, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 2.0) == 0.5  # unloads it
    assert plain.wheel_torque(-0.5, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 2.0) == -0.5  # below the limit


def test_magnetorquer_casadi_and_jax_evaluate_the_definition_to_rounding():
    casadi = pytest.importorskip("casadi")
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from attitude_envs.jax.ops import JAX
    from attitude_envs.symbolic.ops import CASADI

    zs, ms, tws, ctxs, Q, R = _magnetorquer_cases(40, seed=5)
    compiled = magnetorquer_definition.define(NUMBA)
    want = np.array(
        [compiled.augmented(*_magnetorquer_args(*row, Q, R)) for row in zip(zs, ms, tws, ctxs, strict=True)]
    )
    z, m = casadi.SX.sym("z", 9), casadi.SX.sym("m", 3)
    t_w, ctx = casadi.SX.sym("t"), casadi.SX.sym("c", magnetorquer_definition.COMPACT_SIZE)
    expr = magnetorquer_definition.define(CASADI).augmented(
        *_magnetorquer_args(z, m, t_w, ctx, casadi.DM(Q), casadi.DM(R))
    )
    fn = casadi.Function("f", [z, m, t_w, ctx], [casadi.vertcat(*expr)])
    got = np.array([np.asarray(fn(*row)).ravel() for row in zip(zs, ms, tws, ctxs, strict=True)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-18)
    traced = magnetorquer_definition.define(JAX)
    f = jax.jit(
        jax.vmap(lambda *row: jnp.stack(traced.augmented(*_magnetorquer_args(*row, jnp.asarray(Q), jnp.asarray(R)))))
    )
    with jax.enable_x64(True):  # a context, never the global config (other tests run in float32)
        got = np.asarray(f(*(jnp.asarray(a) for a in (zs, ms, tws, ctxs))))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-18)


def _gyrostat_rows(rng, n: int):
    """A scratch row list (one lane) of the gyrostat definition: state (7+n), u, u/J_s, ext (3),
    matrices (18), target (4), then room for the error state (6+n) and the derivative (7+n);
    and the constants C (wheel axes, Q (6+n)², R (n²), the scalars: ``pack_constants``)."""
    from attitude_envs.plants import gyrostat_kernels as kernels

    q = rng.normal(size=4)
    y = np.r_[q / np.linalg.norm(q), rng.normal(0, 0.1, 3), rng.normal(0, 100, n)]
    u = rng.normal(0, 0.05, n)
    axes = rng.normal(size=(3, n))
    axes /= np.linalg.norm(axes, axis=0)
    inertia = np.diag([4.0, 4.5, 3.0]) + 0.1 * np.ones((3, 3))
    j_s = 0.01
    eff_inv = np.linalg.inv(inertia - j_s * axes @ axes.T)
    Q = np.diag(rng.uniform(1, 5, 6 + n)) + 0.01 * rng.normal(size=(6 + n, 6 + n))
    R = np.diag(rng.uniform(1, 5, n))
    C = kernels.pack_constants(axes, Q, R, j_s, 0.2, 600.0, 0.01, rng.normal(0, 0.1, 3))
    t = rng.normal(size=4)
    W = np.r_[y, u, u / j_s, rng.normal(0, 1e-3, 3), kernels.pack_matrices(inertia, eff_inv), t / np.linalg.norm(t)]
    W = np.r_[W, np.zeros((6 + n) + (7 + n))]
    return W, C


@pytest.mark.parametrize("n", [3, 4, 6])
def test_gyrostat_rows_numba_equal_plain_python_bit_for_bit(n):
    from attitude_envs.plants import gyrostat_definition as gd

    compiled, plain = gd.define(NUMBA), gd.define(NUMPY)
    rng = np.random.default_rng(n)
    Y, U, UJ = 0, 7 + n, 7 + 2 * n
    EXT = UJ + n
    MAT = EXT + 3
    TGT = MAT + gd.MAT_ROWS
    X = TGT + 4
    OUT = X + 6 + n
    for _ in range(20):
        W, C = _gyrostat_rows(rng, n)
        sc = C.shape[0] - gd.N_SCALARS
        cq = 3 * n
        lists = [W.copy(), list(W)]
        costs = []
        for ex, w in zip((compiled, plain), lists, strict=True):
            ex.derivative_lane(w, C, 0, 1, n, True, Y, U, UJ, EXT, MAT, OUT, 0, sc)
            costs.append(ex.state_cost_lane(w, C, 0, 1, n, True, False, Y, TGT, X, cq, sc, True))
        assert np.array_equal(np.asarray(lists[0]), np.array(lists[1], dtype=float))
        assert costs[0] == costs[1]


def test_fault_effect_is_the_table_on_every_executor():
    """attitude_envs.faults.define_effect: each kind's output, on the Python, JAX and CasADi
    executors alike (saturation and unknown codes leave the command as it is)."""
    from attitude_envs.faults import KIND_CODES, define_effect
    from attitude_envs.plants.ops import PYTHON

    x, value, t, onset, eff, latched = 0.8, 0.3, 7.0, 2.0, 0.25, -0.4
    want = {
        "loss_of_effectiveness": x * (1.0 - value),
        "effectiveness": x * eff,
        "bias": x + value,
        "drift": x + value * (t - onset),
        "stuck": latched,
        "outage": 0.0,
        "saturation": x,
        "intermittent": 0.0,  # off
    }
    executors = [define_effect(PYTHON)]
    jax = pytest.importorskip("jax")
    from attitude_envs.jax.ops import JAX

    executors.append(jax.jit(define_effect(JAX)))
    casadi = pytest.importorskip("casadi")
    from attitude_envs.symbolic.ops import CASADI

    sym = casadi.SX.sym("x")
    for kind, expected in want.items():
        for effect in executors:
            with jax.enable_x64(True):  # float64 like the others (a context: other tests run in float32)
                got = float(effect(KIND_CODES[kind], x, value, t, onset, eff, latched, False))
            assert got == expected, kind
        expr = define_effect(CASADI)(KIND_CODES[kind], sym, value, t, onset, eff, latched, False)
        assert float(casadi.Function("f", [sym], [expr])(x)) == expected, kind
    assert define_effect(PYTHON)(KIND_CODES["intermittent"], x, value, t, onset, eff, latched, True) == x
    assert define_effect(PYTHON)(0, x, value, t, onset, eff, latched, True) == x  # no fault (the JAX padding)


def test_chain_stages_agree_on_every_executor():
    """attitude_envs.actuator_dynamics.define_chain: each stage on plain Python and compiled
    numba scalars equals the numpy stage elementwise, bit for bit (ties of the resolution
    rounded half to even, sign(0) = 0), and the CasADi stages evaluate to the same numbers."""
    from attitude_envs.actuator_dynamics import define_chain
    from attitude_envs.plants.ops import PYTHON

    rng = np.random.default_rng(3)
    c = np.concatenate([rng.uniform(-2.0, 2.0, 40), [0.005, 0.015, -0.025, 0.0]])
    q = np.full(c.shape, 0.01)
    last, y0, w = rng.uniform(-1, 1, c.shape), rng.uniform(-1, 1, c.shape), rng.uniform(0, 1, c.shape)
    speed = np.concatenate([rng.normal(0.0, 50.0, 40), [0.0, 0.0, -1.0, 2.0]])
    vec = define_chain(NUMPY)

    def stages(s, i, sign):
        return (
            s.quantized(c[i], q[i], 1.5),
            s.rate_limited(c[i], last[i], 0.2),
            s.toward(c[i], y0[i], w[i]),
            s.with_friction(c[i], 0.01, sign(speed[i]), 1e-4, speed[i]),
        )

    want = np.stack(
        [
            vec.quantized(c, q, 1.5),
            vec.rate_limited(c, last, 0.2),
            vec.toward(c, y0, w),
            vec.with_friction(c, 0.01, np.sign(speed), 1e-4, speed),
        ],
        axis=1,
    )
    plain = define_chain(PYTHON)
    compiled = define_chain(NUMBA)
    quantized, rate, toward, friction = (
        compiled.quantized,
        compiled.rate_limited,
        compiled.toward,
        compiled.with_friction,
    )
    numba_sign = NUMBA.sign
    sign = NUMBA.compile(lambda v: numba_sign(v))
    for i in range(len(c)):
        assert np.array_equal(np.array(stages(plain, i, PYTHON.sign)), want[i]), i
        got = (
            quantized(c[i], q[i], 1.5),
            rate(c[i], last[i], 0.2),
            toward(c[i], y0[i], w[i]),
            friction(c[i], 0.01, sign(speed[i]), 1e-4, speed[i]),
        )
        assert np.array_equal(np.array(got), want[i]), i
    casadi = pytest.importorskip("casadi")
    from attitude_envs.symbolic.ops import CASADI

    sym = define_chain(CASADI)
    v = casadi.SX.sym("v", 4)
    f = casadi.Function(
        "f",
        [v],
        [
            casadi.vertcat(
                sym.rate_limited(v[0], v[1], 0.2),
                sym.toward(v[0], v[2], v[3]),
                sym.with_friction(v[0], 0.01, casadi.sign(v[1]), 1e-4, v[1]),
            )
        ],
    )
    for i in range(len(c)):
        got = np.asarray(f([c[i], last[i], y0[i], w[i]])).ravel()
        expect = [want[i, 1], want[i, 2], vec.with_friction(c[i], 0.01, np.sign(last[i]), 1e-4, last[i])]
        np.testing.assert_allclose(got, expect, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="round"):
        sym.quantized(v[0], 0.01, 1.5)
