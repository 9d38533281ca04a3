"""Keplerian orbit, LVLH frame and the Earth field models of Magnetorquer-v0 (Sadigh et al.
2022, eq. 9 and Table 1)."""

import datetime as dt

import numpy as np
import pytest

from attitude_envs.plants import magnetic_field as mf
from attitude_envs.plants.orbit import EARTH_RADIUS_M, KeplerOrbit

MU_E = mf.DIPOLE_STRENGTH_T_M3


def paper_orbit(**kwargs):
    return KeplerOrbit.from_altitudes(1250.0, 311.0, 69.5, **kwargs)


def test_paper_orbit_reproduces_the_printed_orbital_rate():
    orbit = paper_orbit()
    assert orbit.a == pytest.approx(7151.5e3)
    assert orbit.e == pytest.approx((1250 - 311) / (2 * 6371 + 1250 + 311))
    assert orbit.mean_motion_rad_s == pytest.approx(10.439e-4, rel=1e-4)  # Table 1
    assert 2 * orbit.period_s == pytest.approx(12037.9, abs=0.5)  # two orbits: the paper's run


def test_keplerian_propagation_conserves_energy_and_momentum_and_hits_apsides():
    orbit = paper_orbit(arg_perigee_deg=30.0, raan_deg=40.0, mean_anomaly_deg=0.0)
    mu = orbit.mu
    s0 = orbit.state_at(0.0)
    assert s0.radius_m == pytest.approx((6371 + 311) * 1e3, rel=1e-12)  # perigee at M = 0
    assert orbit.state_at(orbit.period_s / 2).radius_m == pytest.approx((6371 + 1250) * 1e3, rel=1e-10)
    h0 = np.cross(s0.position_m, s0.velocity_m_s)
    e0 = s0.velocity_m_s @ s0.velocity_m_s / 2 - mu / s0.radius_m
    for t in np.linspace(0, orbit.period_s, 17):
        s = orbit.state_at(t)
        assert np.allclose(np.cross(s.position_m, s.velocity_m_s), h0, rtol=1e-10)
        assert s.velocity_m_s @ s.velocity_m_s / 2 - mu / s.radius_m == pytest.approx(e0, rel=1e-10)
        # LVLH: orthonormal, z nadir, y anti-normal; ν̇ = |h|/r²
        frame = s.eci_from_orbital
        assert np.allclose(frame.T @ frame, np.eye(3), atol=1e-12) and np.linalg.det(frame) == pytest.approx(1.0)
        assert np.allclose(frame[:, 2], -s.position_m / s.radius_m)
        assert np.allclose(frame[:, 1], -h0 / np.linalg.norm(h0))
        assert s.rate_rad_s == pytest.approx(np.linalg.norm(h0) / s.radius_m**2, rel=1e-12)
    # ν̈ is the derivative of ν̇ (central difference)
    dt_s = 1.0
    num = (orbit.state_at(1000 + dt_s).rate_rad_s - orbit.state_at(1000 - dt_s).rate_rad_s) / (2 * dt_s)
    assert orbit.state_at(1000).rate_dot_rad_s2 == pytest.approx(num, rel=1e-5)


def test_circular_model_is_the_papers_constant_rate_approximation():
    orbit = paper_orbit(model="circular")
    for t in (0.0, 1234.5, 6000.0):
        s = orbit.state_at(t)
        assert s.radius_m == orbit.a and s.rate_rad_s == orbit.mean_motion_rad_s and s.rate_dot_rad_s2 == 0.0
        assert s.argument_of_latitude_rad == pytest.approx(orbit.mean_motion_rad_s * t)


def test_dipole_field_at_equator_and_pole():
    r = EARTH_RADIUS_M
    b_eq = mf.dipole_eci_t(np.array([r, 0.0, 0.0]))
    assert np.allclose(b_eq, [0.0, 0.0, MU_E / r**3])  # points north, B0 = 3.07e-5 T
    assert MU_E / r**3 == pytest.approx(3.078e-5, rel=1e-3)
    b_pole = mf.dipole_eci_t(np.array([0.0, 0.0, 2 * r]))
    assert np.allclose(b_pole, [0.0, 0.0, -2 * MU_E / (2 * r) ** 3])  # twice as strong, pointing down
    b_south = mf.dipole_eci_t(np.array([0.0, 0.0, -r]))
    assert np.allclose(b_south, [0.0, 0.0, -2 * MU_E / r**3])  # pointing up out of the south pole


def test_dipole_in_lvlh_is_the_wertz_form_and_differs_from_print_by_a_half_turn():
    orbit = paper_orbit(model="circular", raan_deg=25.0)
    field = mf.FieldModel("dipole")
    printed = mf.FieldModel("dipole-printed")
    i = orbit.inclination_rad
    for t in np.linspace(0, orbit.period_s, 9):
        s = orbit.state_at(t)
        a = s.argument_of_latitude_rad
        expected = MU_E / s.radius_m**3 * np.array([np.cos(a) * np.sin(i), -np.cos(i), 2 * np.sin(a) * np.sin(i)])
        assert np.allclose(field.orbital_t(t, s, i), expected, rtol=1e-12, atol=1e-20)
        assert np.allclose(printed.orbital_t(t, s, i), np.diag([1, -1, -1]) @ expected, rtol=1e-12, atol=1e-20)


def test_igrf_matches_the_package_for_one_date_and_position():
    ppigrf = pytest.importorskip("ppigrf")
    epoch = dt.datetime(2020, 1, 1)
    r_km, colat, lon = 7000.0, 60.0, 30.0
    th, ph = np.radians(colat), np.radians(lon)
    pos = r_km * 1e3 * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    b = mf.igrf_ecef_t(pos, epoch)
    br, bth, bph = (float(np.ravel(v)[0]) * 1e-9 for v in ppigrf.igrf_gc(r_km, colat, lon, epoch))
    r_hat = pos / np.linalg.norm(pos)
    th_hat = np.array([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)])
    ph_hat = np.array([-np.sin(ph), np.cos(ph), 0.0])
    assert b @ r_hat == pytest.approx(br) and b @ th_hat == pytest.approx(bth) and b @ ph_hat == pytest.approx(bph)
    # the northern-hemisphere field points down and is of dipole magnitude at this radius
    assert br < 0
    dipole = np.linalg.norm(mf.dipole_eci_t(pos))
    assert 0.7 < np.linalg.norm(b) / dipole < 1.3


def test_igrf_table_interpolates_the_package_along_the_orbit():
    pytest.importorskip("ppigrf")
    orbit = paper_orbit(model="circular")
    field = mf.FieldModel("igrf", epoch="2020-06-01T00:00:00", igrf_step_s=10.0)
    field.prepare(orbit, 100.0)

    def direct(t):
        theta = mf.greenwich_sidereal_angle_rad(field.epoch) + mf.EARTH_RATE_RAD_S * t
        c, sn = np.cos(theta), np.sin(theta)
        rot = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1.0]])  # ECEF → ECI
        return rot @ mf.igrf_ecef_t(rot.T @ orbit.state_at(t).position_m, field.epoch)

    assert np.allclose(field.eci_t(30.0, orbit.state_at(30.0)), direct(30.0), rtol=1e-12)  # a node: exact
    exact = direct(35.0)
    between = field.eci_t(35.0, orbit.state_at(35.0))  # linear interpolation over 74 km of track
    assert 0 < np.linalg.norm(between - exact) < 1e-3 * np.linalg.norm(exact)


def test_gmst_at_j2000():
    # GMST at 2000-01-01 12:00 UT1 is 280.46061837°
    assert np.degrees(mf.greenwich_sidereal_angle_rad(dt.datetime(2000, 1, 1, 12))) == pytest.approx(280.46061837)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"eccentricity": 1.0}, r"eccentricity must be in \[0, 1\)"),
        ({"eccentricity": -0.1}, r"eccentricity must be in \[0, 1\)"),
        ({"inclination_deg": 180.5}, r"inclination_deg must be in \[0, 180\]"),
        ({"inclination_deg": -1.0}, r"inclination_deg must be in \[0, 180\]"),
        ({"semi_major_axis_m": -7e6}, "semi_major_axis_m must be in"),
        ({"model": "j2"}, "orbit.model must be one of"),
    ],
)
def test_bad_orbit_elements_raise(kwargs, match):
    args = {"semi_major_axis_m": 7.15e6, "eccentricity": 0.05, "inclination_deg": 69.5}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        KeplerOrbit(**args)


def test_bad_field_settings_raise():
    with pytest.raises(ValueError, match="field_model must be one of"):
        mf.FieldModel("quadrupole")
    with pytest.raises(ValueError, match="field_epoch must be in"):
        mf.FieldModel("igrf", epoch="2050-01-01")
    with pytest.raises(ValueError, match="apogee_altitude_km and perigee_altitude_km"):
        KeplerOrbit.from_altitudes(300.0, 1250.0, 69.5)
