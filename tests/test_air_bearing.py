"""AirBearing-v0 (Ahangarani Farahani et al. air-bearing simulator): offset torque, pendulum
energy, tilt stops, Euler angles in info."""

import math

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs import presets, quaternion
from attitude_envs.euler import euler_321_rad, euler_321_rates
from attitude_envs.plants import gyrostat

ENV_ID = "attitude_envs/AirBearing-v0"


def make(**kwargs):
    return gym.make(ENV_ID, **kwargs).unwrapped


def test_offset_torque_is_eq_10_and_restoring():
    params = make().model.params
    rng = np.random.default_rng(3)
    p = presets.get("AirBearing-v0").values["offset_torque_nm"].value
    np.testing.assert_array_equal(params.offset_torque_nm, p)
    for _ in range(20):
        phi, theta, psi = rng.uniform([-40, -40, -180], [40, 40, 180])
        t = gyrostat.gravity_torque_nm(params, quaternion.from_euler_321_deg(phi, theta, psi))
        f, th = math.radians(phi), math.radians(theta)
        eq10 = [
            p[1] * math.cos(f) * math.cos(th) - p[2] * math.sin(f) * math.cos(th),
            -p[0] * math.cos(f) * math.cos(th) - p[2] * math.sin(th),
            p[0] * math.sin(f) * math.cos(th) + p[1] * math.sin(th),
        ]
        np.testing.assert_allclose(t, eq10, atol=1e-15)
    # restoring: a positive roll (pitch) gives a negative roll (pitch) torque, stiffness p_z
    for axis in (0, 1):
        angles = [0.0, 0.0, 30.0]
        angles[axis] = 5.0
        t = gyrostat.gravity_torque_nm(params, quaternion.from_euler_321_deg(*angles))
        gravity_free = gyrostat.gravity_torque_nm(params, quaternion.from_euler_321_deg(0.0, 0.0, 30.0))
        assert t[axis] - gravity_free[axis] == pytest.approx(-p[2] * math.sin(math.radians(5.0)), rel=1e-3)


def test_kernel_applies_offset_torque():
    env = make()
    params = env.model.params
    q = quaternion.from_euler_321_deg(12.0, -7.0, 40.0)
    y = np.concatenate([q, np.zeros(3), np.zeros(3)])
    dy = gyrostat.derivative(params, y, np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(dy[4:7], params.inertia_eff_inv @ gyrostat.gravity_torque_nm(params, q), rtol=1e-12)
    # and it is absent on a free body (ReactionWheel-v0 unchanged)
    free = gym.make("attitude_envs/ReactionWheel-v0").unwrapped.model.params
    np.testing.assert_array_equal(free.offset_torque_nm, np.zeros(3))


def test_pendulum_energy_is_conserved_with_idle_wheels():
    """Zero wheel torque: kinetic (body + wheels) + gravity potential energy is constant,
    while the platform swings through the bottom (roll changes sign)."""
    env = make(episode_duration_s=30.0)
    params = env.model.params
    _, info = env.reset(
        seed=0,
        options={
            "euler_321_deg": [15.0, -10.0, 20.0],
            "rate_rad_s": [0.02, 0.01, 0.05],
            "wheel_speed_rad_s": [30.0, -20.0, 10.0],
        },
    )

    def energy(info):
        s = info["truth"]["state"]
        return gyrostat.kinetic_energy(params, s["rate_rad_s"], s["wheel_speed_rad_s"]) + gyrostat.gravity_potential_j(
            params, s["attitude"]
        )

    e0 = energy(info)
    rolls = []
    done = False
    while not done:
        _, _, term, trunc, info = env.step(np.zeros(3))
        done = term or trunc
        rolls.append(info["truth"]["euler_321_deg"][0])
        assert energy(info) == pytest.approx(e0, rel=1e-10)
    assert not term
    assert min(rolls) < -5.0 < 5.0 < max(rolls)  # it really swung (period ≈ 28 s)
    assert abs(e0) > 0.01


def test_tilt_stop_terminates_yaw_is_unlimited():
    env = make(episode_duration_s=20.0)
    env.reset(seed=0, options={"euler_321_deg": [35.0, 0.0, 0.0], "rate_rad_s": [0.5, 0.0, 0.0]})
    for _ in range(200):
        _, _, term, trunc, info = env.step(np.zeros(3))
        if term:
            break
    assert term and not trunc and info["truth"]["tilt_limit_hit"]
    assert abs(info["truth"]["euler_321_deg"][0]) > 40.0
    env.reset(seed=0, options={"euler_321_deg": [0.0, 0.0, 170.0], "rate_rad_s": [0.0, 0.0, 0.5]})
    yaws = []
    for _ in range(100):
        _, _, term, _, info = env.step(np.zeros(3))
        yaws.append(info["truth"]["euler_321_deg"][2])
        assert not term
    assert min(yaws) < -150.0  # wrapped through ±180° without terminating


def test_info_euler_and_random_start():
    env = make()
    for seed in range(5):
        _, info = env.reset(seed=seed)
        e = info["truth"]["euler_321_deg"]
        np.testing.assert_allclose(e, quaternion.to_euler_321_deg(info["truth"]["state"]["attitude"]), atol=1e-9)
        assert np.all(np.abs(e) <= [20.0 + 1e-9, 20.0 + 1e-9, 45.0 + 1e-9])
        assert np.all(np.abs(info["truth"]["state"]["rate_rad_s"]) <= math.radians(2.0))
    _, a = env.reset(seed=7)
    _, b = env.reset(seed=7)
    np.testing.assert_array_equal(a["truth"]["state"]["attitude"], b["truth"]["state"]["attitude"])


def test_euler_rates_match_finite_differences():
    rng = np.random.default_rng(0)
    q = quaternion.from_euler_321_deg(20.0, -30.0, 100.0)
    w = rng.normal(size=3) * 0.3
    h = 1e-6
    q2 = quaternion.multiply(q, quaternion.from_axis_angle(w, np.linalg.norm(w) * h))
    e1, e2 = np.array(euler_321_rad(q)), np.array(euler_321_rad(q2))
    roll, pitch, _ = e1
    np.testing.assert_allclose(euler_321_rates(roll, pitch, w), (e2 - e1) / h, rtol=1e-4, atol=1e-8)


def test_standard_env_api():
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make(ENV_ID).unwrapped, skip_render_check=True)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"tilt_limit_deg": 95.0},
        {"offset_torque_nm": [0.0, 1.0]},
        {"initial_euler_max_deg": [45.0, 0.0, 0.0]},
        {"preset": "pyramid-4wheel"},
        {"max_wheel_torque_nm": -1.0},
    ],
)
def test_bad_construction(kwargs):
    with pytest.raises(ValueError):
        gym.make(ENV_ID, **kwargs)


def test_bad_reset_options():
    env = make()
    with pytest.raises(ValueError, match="euler_321_deg"):
        env.reset(options={"euler_321_deg": [1.0, 2.0]})
    with pytest.raises(ValueError, match="either"):
        env.reset(options={"euler_321_deg": [1.0, 2.0, 3.0], "attitude": [0, 0, 0, 1]})


def test_air_bearing_is_a_configuration_of_the_reaction_wheel_env():
    """ReactionWheel-v0 with the air-bearing preset's values is the same plant, bit for bit."""
    values = presets.get("AirBearing-v0").params()
    values.pop("initial_euler_max_deg")  # AirBearing-v0's own keyword (random Euler start)
    rw = gym.make("attitude_envs/ReactionWheel-v0", **values).unwrapped
    ab = make()
    np.testing.assert_array_equal(rw.kernel_constants, ab.kernel_constants)
    options = {"attitude": quaternion.from_euler_321_deg(30.0, -5.0, 30.0), "rate_rad_s": [0.3, 0.02, -0.01]}
    rw.reset(seed=3, options=options)
    ab.reset(seed=3, options=options)
    rng = np.random.default_rng(0)
    for _ in range(100):
        a = rng.uniform(-0.2, 0.2, 3)
        o1, r1, t1, _, i1 = rw.step(a)
        o2, r2, t2, _, i2 = ab.step(a)
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2
        assert i1["truth"]["tilt_limit_hit"] == i2["truth"]["tilt_limit_hit"]
        if t1:
            break
    assert t1 and i1["truth"]["tilt_limit_hit"]  # the stop is a ReactionWheel-v0 keyword too
