"""Physics verification of the fuel-slosh plant (Navabi & Davoodi, eqs. 1–27, as we
reconstructed them): the equations are checked, not trusted."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from attitude_envs.integrators import rk4_step
from attitude_envs.plants import slosh
from attitude_envs.plants import slosh_model as sm

ROOT = Path(__file__).resolve().parents[1]


def _random_state(rng: np.random.Generator) -> np.ndarray:
    return rng.normal(size=10) * [10, 10, 1, 1, 1, 3000, 50, 0.5, 2, 2]


@pytest.fixture(scope="module")
def derive():
    pytest.importorskip("sympy")
    spec = importlib.util.spec_from_file_location("derive_slosh", ROOT / "tools" / "derive_slosh.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("preset", sorted(slosh.FILL_PRESETS))
def test_equations_satisfy_sympy_lagrange_derivation(derive, preset):
    """The closed-form body-frame equations (eqs. 11–14) zero the inertial Euler–Lagrange
    residual derived symbolically from T and R (eqs. 5 and 10), with thrust and moment."""
    p = slosh.SloshParams.from_fill_preset(preset)
    rng = np.random.default_rng(1)
    worst = max(
        derive.max_relative_residual(p, _random_state(rng), rng.uniform(-1, 1), 1000 * rng.normal()) for _ in range(20)
    )
    assert worst < 1e-10


def test_sympy_check_detects_a_wrong_term(derive, monkeypatch):
    """The residual check is sharp: a 1 % error in one centrifugal term is caught (the
    accelerations the compiled derivative would give with that pitch force error)."""
    p = slosh.SloshParams()
    y = _random_state(np.random.default_rng(2))
    good = slosh.derivative

    def wrong(params, state, delta, moment):
        dy = good(params, state, delta, moment)
        error = np.zeros(5)
        error[2] = 0.01 * params.S_z * state[slosh.IOM] ** 2
        dy[slosh.IVX :] += np.linalg.solve(slosh.mass_matrix(params, state[slosh.IPSI1 : slosh.IPSI2 + 1]), error)
        return dy

    monkeypatch.setattr(slosh, "derivative", wrong)
    assert derive.max_relative_residual(p, y, 0.3, 100.0) > 1e-6


def test_mass_matrix_symmetric_positive_definite():
    rng = np.random.default_rng(3)
    for preset in slosh.FILL_PRESETS:
        p = slosh.SloshParams.from_fill_preset(preset)
        for _ in range(200):
            M = slosh.mass_matrix(p, rng.uniform(-np.pi, np.pi, 2))
            assert np.array_equal(M, M.T)
            assert np.linalg.eigvalsh(M)[0] > 0


def test_mass_matrix_values_at_rest():
    """Derived constants of mapping (i) (reconstruction notes): m_t, S_z, I_θθ(0), J_i."""
    p = slosh.SloshParams()
    M = slosh.mass_matrix(p, np.zeros(2))
    assert M[0, 0] == pytest.approx(1125.0)
    assert p.S_z == pytest.approx(-412.5)
    assert M[2, 2] == pytest.approx(710.8)
    assert M[1, 2] == pytest.approx(-402.0)
    np.testing.assert_allclose(np.diag(M)[3:], [12.0, 1.05])
    np.testing.assert_allclose(M[2, 3:], [6.0, 0.6])
    assert p.axial_acceleration_m_s2 == pytest.approx(2.0)


@pytest.mark.parametrize("preset", ["i", "iii"])
def test_energy_and_momentum_conserved_without_thrust_or_damping(preset):
    p = slosh.SloshParams.from_fill_preset(preset, thrust_n=0.0, damping_kg_m2_s=(0.0, 0.0))
    y = np.array([3.0, -2.0, 0.1, 0.5, -0.4, 30.0, -5.0, 0.05, 0.3, -0.6])
    E0 = slosh.kinetic_energy(p, y)
    P0, H0 = slosh.momenta(p, y)
    h = 0.01
    for _ in range(2000):  # 20 s, ≈ 4 slosh periods
        y = rk4_step(lambda t, s: slosh.derivative(p, s, 0.0, 0.0), 0.0, y, h)
    P, H = slosh.momenta(p, y)
    assert abs(slosh.kinetic_energy(p, y) - E0) <= 1e-8 * E0
    assert np.linalg.norm(P - P0) <= 1e-8 * np.linalg.norm(P0)
    assert abs(H - H0) <= 1e-8 * abs(H0)
    assert abs(y[slosh.IPSI1] - 0.5) > 0.01  # the pendulums really moved


def test_damping_dissipates_energy():
    p = slosh.SloshParams(thrust_n=0.0)
    y = np.array([0, 0, 0, 0.5, -0.4, 30.0, -5.0, 0.05, 0.3, -0.6])
    E0 = slosh.kinetic_energy(p, y)
    for _ in range(500):
        y = rk4_step(lambda t, s: slosh.derivative(p, s, 0.0, 0.0), 0.0, y, 0.01)
    assert slosh.kinetic_energy(p, y) < E0


def test_free_slosh_frequency_matches_the_reconstruction():
    """Sanity check of the reconstruction notes: ψ1 from 5° with δ = M = 0 oscillates at ≈ 1.284 rad/s."""
    p = slosh.SloshParams()
    y = np.zeros(10)
    y[slosh.IVX] = 3000.0
    y[slosh.IPSI1] = math.radians(5.0)
    h, psi, times = 0.01, [], []
    for k in range(3000):
        y = rk4_step(lambda t, s: slosh.derivative(p, s, 0.0, 0.0), 0.0, y, h)
        psi.append(y[slosh.IPSI1])
        times.append((k + 1) * h)
    psi = np.array(psi)
    up = np.where((psi[:-1] < 0) & (psi[1:] >= 0))[0]
    period = np.mean(np.diff(np.array(times)[up]))
    assert 2 * np.pi / period == pytest.approx(1.284, abs=0.01)


def _fd_jacobian(fun, x0, eps):
    cols = []
    for k in range(len(x0)):
        dx = np.zeros(len(x0))
        dx[k] = eps[k]
        cols.append((fun(x0 + dx) - fun(x0 - dx)) / (2 * eps[k]))
    return np.array(cols).T


def test_full_linearization_matches_finite_differences():
    p = slosh.SloshParams()
    vx = 3000.0
    A, B = sm.full_linear(p, vx)

    def full(x, u=(0.0, 0.0)):
        y = np.zeros(10)
        y[slosh.IVX] = vx
        y[sm.REDUCED_INDEX] = x
        return sm.reduced_state(slosh.derivative(p, y, u[0], u[1]))

    A_fd = _fd_jacobian(full, np.zeros(7), [1e-4] * 7)
    B_fd = _fd_jacobian(lambda u: full(np.zeros(7), u), np.zeros(2), [1e-6, 1e-2])
    np.testing.assert_allclose(A, A_fd, rtol=1e-5, atol=1e-8 * np.max(np.abs(A)))
    np.testing.assert_allclose(B, B_fd, rtol=1e-5, atol=1e-9)


def test_reduced_linearization_matches_finite_differences():
    p = slosh.SloshParams()
    vx = 3000.0
    A, B = sm.reduced_linear(p, vx)

    def reduced(x, u=(0.0, 0.0)):
        return sm.reduced_derivative(p, np.concatenate([[vx], x]), np.asarray(u))[1:]

    np.testing.assert_allclose(A, _fd_jacobian(reduced, np.zeros(7), [1e-6] * 7), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(B, _fd_jacobian(lambda u: reduced(np.zeros(7), u), np.zeros(2), [1e-6] * 2), atol=1e-8)
    # the reconstruction notes' numbers of eqs. 25–27 (mapping (i), v_x = 3000 m/s)
    assert A[4, 3] == pytest.approx(-1.666667, abs=1e-6)
    assert A[6, 6] == pytest.approx(-0.476190, abs=1e-6)
    np.testing.assert_allclose(B[4], [-0.833333, -0.5], atol=1e-6)


def test_exact_inversion_realizes_new_inputs_and_matches_the_reconstructed_initial_inputs():
    """Reconstruction notes (inputs from eqs. 11–13): from the paper's initial condition under PD, δ(0) = −17.53°, M(0) = 859 N·m."""
    p = slosh.SloshParams()
    y = np.zeros(10)
    y[[slosh.IVX, slosh.IVZ, slosh.ITH, slosh.IPSI1, slosh.IPSI2]] = [3000, 100, math.radians(2), 0.5236, -0.5236]
    u1, u2 = -6e-3 * 100, -5e-5 * math.radians(2)
    delta, moment, saturated = sm.invert_inputs(p, y, u1, u2)
    assert not saturated
    assert math.degrees(delta) == pytest.approx(-17.53, abs=0.01)
    assert moment == pytest.approx(859.0, abs=1.0)
    _, a_z, dom = slosh.tank_accelerations(y, slosh.derivative(p, y, delta, moment))
    assert a_z == pytest.approx(u1, rel=1e-9)
    assert dom == pytest.approx(u2, rel=1e-7)


def _pd(x):
    return np.array([-6e-3 * x[0], -5e-5 * x[1] - 6e-3 * x[2]])


def test_reduced_model_tracks_full_model_within_the_reconstructed_tolerance():
    """Reconstruction notes: under PD with exact input inversion the full 5-DOF plant follows the
    reduced nonlinear model within ≈ 0.3 % (v_z and θ, relative to their peaks)."""
    p = slosh.SloshParams()
    y = np.zeros(10)
    y[[slosh.IVX, slosh.IVZ, slosh.ITH, slosh.IPSI1, slosh.IPSI2]] = [3000, 100, math.radians(2), 0.5236, -0.5236]
    z = np.array([3000, 100, math.radians(2), 0, 0.5236, 0, -0.5236, 0])

    def full(t, s):
        d, m, _ = sm.invert_inputs(p, s, *_pd(sm.reduced_state(s)))
        return slosh.derivative(p, s, d, m)

    def reduced(t, s):
        return sm.reduced_derivative(p, s, _pd(s[1:]))

    h = 0.1
    vz_f, vz_r, th_f, th_r = [], [], [], []
    for _ in range(2500):  # 250 s: through the v_z undershoot (reconstruction notes: −31.1 m/s at 250 s)
        y = rk4_step(full, 0.0, y, h)
        z = rk4_step(reduced, 0.0, z, h)
        vz_f.append(y[slosh.IVZ])
        vz_r.append(z[1])
        th_f.append(y[slosh.ITH])
        th_r.append(z[2])
    vz_f, vz_r, th_f, th_r = map(np.array, (vz_f, vz_r, th_f, th_r))
    assert np.max(np.abs(vz_f - vz_r)) <= 3e-3 * np.max(np.abs(vz_r))
    assert np.max(np.abs(th_f - th_r)) <= 3e-3 * np.max(np.abs(th_r))
    assert vz_r[-1] == pytest.approx(-31.1, abs=0.3)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"mass_kg": -1.0}, "mass_kg"),
        ({"slosh_mass_kg": (50.0, -5.0)}, "slosh_mass_kg"),
        ({"length_m": (0.2, 0.0)}, "length_m"),
        ({"length_m": (0.2, float("nan"))}, "length_m"),
        ({"damping_kg_m2_s": (-1.0, 0.5)}, "damping_kg_m2_s"),
        ({"thrust_n": -1.0}, "thrust_n"),
        ({"fuel_mass_kg": -1.0}, "fuel_mass_kg"),
    ],
)
def test_bad_parameters_raise(kwargs, name):
    with pytest.raises(ValueError, match=name):
        slosh.SloshParams(**kwargs)


def test_unknown_fill_preset_raises():
    with pytest.raises(ValueError, match="fill_preset"):
        slosh.SloshParams.from_fill_preset("v")


@pytest.mark.parametrize(
    ("preset", "J", "omega", "zeta"),
    [
        ("i", (12.0, 1.05), (1.291, 0.976), (0.119, 0.244)),
        ("ii", (50.5, 1.05), (1.335, 0.976), (0.027, 0.244)),
        ("iii", (28.0, 5.05), (1.464, 1.335), (0.045, 0.037)),
        ("iv", (28.0, 1.2), (1.464, 1.291), (0.045, 0.161)),
    ],
)
def test_fill_presets_match_the_reconstructed_slosh_modes(preset, J, omega, zeta):
    """The four readings of Table 3's lengths: J_i, ω_i = √(m_i l_i a_x / J_i), ζ_i = ε_i / (2 J_i ω_i) per mapping;
    ω_i also equals the reduced linear model's undamped slosh frequency."""
    p = slosh.SloshParams.from_fill_preset(preset)
    np.testing.assert_allclose(p.J, J, atol=1e-9)
    A, _ = sm.reduced_linear(p, 3000.0)
    w = np.sqrt(-np.array([A[4, 3], A[6, 5]]))
    np.testing.assert_allclose(w, omega, atol=1e-3)
    np.testing.assert_allclose(np.asarray(p.damping_kg_m2_s) / (2 * p.J * w), zeta, atol=1e-3)


def test_params_copy_recomputes_derived_constants():
    p = slosh.SloshParams().with_(mass_kg=1090.0)
    assert p.total_mass_kg == pytest.approx(1625.0)
    assert p.S_z == pytest.approx(1090.0 * -0.6 - 480 * 0.05 - 50 * 0.6 - 5 * 0.9)
    assert p == slosh.SloshParams(mass_kg=1090.0)
