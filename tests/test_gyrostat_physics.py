"""Physics verification of ReactionWheel-v0: conservation laws, RK4 order, analytic cases."""

import gymnasium as gym
import numpy as np
import pytest
from conftest import asymmetric_inertia
from scipy.integrate import solve_ivp

from attitude_envs import quaternion
from attitude_envs.plants import gyrostat


def make(**kwargs):
    base = dict(
        inertia_kg_m2=asymmetric_inertia(),
        max_wheel_speed_rad_s=np.inf,
        episode_duration_s=1e6,
        max_rate_rad_s=100.0,
    )
    base.update(kwargs)
    return gym.make("attitude_envs/ReactionWheel-v0", **base).unwrapped


def inertial_momentum(env, info):
    s = info["truth"]["state"]
    h_body = gyrostat.body_momentum(env.model.params, s["rate_rad_s"], s["wheel_speed_rad_s"])
    return quaternion.to_matrix(s["attitude"]) @ h_body


def test_torque_free_conserves_momentum_and_energy_over_1000_s():
    env = make(control_dt_s=0.1, integrator_dt_s=0.02)
    _, info = env.reset(
        seed=0,
        options={"rate_rad_s": [0.05, -0.03, 0.08], "wheel_speed_rad_s": [30.0, -20.0, 10.0, 5.0]},
    )
    p = env.model.params
    h0 = inertial_momentum(env, info)
    e0 = gyrostat.kinetic_energy(p, info["truth"]["state"]["rate_rad_s"], info["truth"]["state"]["wheel_speed_rad_s"])
    zero = np.zeros(4)
    for _ in range(10000):
        _, _, term, trunc, info = env.step(zero)
        assert not (term or trunc)
    assert info["time_s"] == pytest.approx(1000.0)
    h1 = inertial_momentum(env, info)
    e1 = gyrostat.kinetic_energy(p, info["truth"]["state"]["rate_rad_s"], info["truth"]["state"]["wheel_speed_rad_s"])
    assert np.linalg.norm(h1 - h0) / np.linalg.norm(h0) <= 1e-9
    assert abs(e1 - e0) / e0 <= 1e-9
    # the motion is not trivial: the body really tumbled
    assert np.linalg.norm(info["truth"]["state"]["rate_rad_s"] - [0.05, -0.03, 0.08]) > 1e-3
    assert abs(np.linalg.norm(info["truth"]["state"]["attitude"]) - 1.0) <= 1e-12


def test_internal_wheel_torques_conserve_total_momentum(rng):
    env = make(control_dt_s=0.1, integrator_dt_s=0.02)
    _, info = env.reset(seed=1, options={"rate_rad_s": [0.02, 0.01, -0.03]})
    h0 = inertial_momentum(env, info)
    for _ in range(500):
        _, _, _, _, info = env.step(rng.uniform(-1, 1, 4))
    h1 = inertial_momentum(env, info)
    assert np.linalg.norm(h1 - h0) / np.linalg.norm(h0) <= 1e-9
    assert np.max(np.abs(info["truth"]["state"]["wheel_speed_rad_s"])) > 1.0  # the wheels did work


def reference_solution(env, y0, u, t_end):
    p = env.model.params
    sol = solve_ivp(
        lambda t, y: gyrostat.derivative(p, y, u, np.zeros(3)),
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
    )
    return sol.y[:, -1]


def test_rk4_global_error_is_fourth_order():
    u_cmd = np.array([0.3, -0.2, 0.1, 0.4])
    options = {"rate_rad_s": [0.4, -0.3, 0.5], "wheel_speed_rad_s": [50.0, -40.0, 20.0, 0.0]}
    errors = []
    for h in (0.2, 0.1, 0.05):
        env = make(control_dt_s=0.2, integrator_dt_s=h)
        env.reset(seed=0, options=options)
        y0 = env._y.copy()
        for _ in range(50):
            env.step(u_cmd)
        ref = reference_solution(env, y0, u_cmd * env.model.params.max_wheel_torque_nm, 10.0)
        errors.append(np.linalg.norm(env._y[:7] - ref[:7]))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert errors[-1] < 1e-6
    for r in ratios:
        assert 12.0 < r < 20.0, (errors, ratios)


def test_axisymmetric_torque_free_precession_matches_analytic():
    # Three orthogonal wheels, free (zero motor torque) and absolutely at rest: the body
    # then moves as a torque-free axisymmetric rigid body of inertia I_eff = I − J_s·1.
    it, ia, js = 5.0, 3.0, 0.01
    env = make(
        inertia_kg_m2=np.diag([it, it, ia]),
        wheel_axes=np.eye(3),
        wheel_inertia_kg_m2=js,
        control_dt_s=0.05,
        integrator_dt_s=0.01,
    )
    w0 = np.array([0.1, 0.0, 0.5])
    _, info = env.reset(seed=0, options={"rate_rad_s": w0, "wheel_speed_rad_s": -w0})
    it_e, ia_e = it - js, ia - js
    lam = (ia_e - it_e) / it_e * w0[2]
    h_inertial = np.array([it_e * w0[0], 0.0, ia_e * w0[2]])  # attitude starts at identity
    precession = np.linalg.norm(h_inertial) / it_e
    h_hat = h_inertial / np.linalg.norm(h_inertial)
    z0 = np.array([0.0, 0.0, 1.0])
    for k in range(1, 401):
        _, _, _, _, info = env.step(np.zeros(3))
        t = 0.05 * k
        w = info["truth"]["state"]["rate_rad_s"]
        expected_w = [w0[0] * np.cos(lam * t), w0[0] * np.sin(lam * t), w0[2]]
        assert np.allclose(w, expected_w, atol=1e-10)
    # the body z axis cones about H at the rate |H|/I_t
    c, s = np.cos(precession * t), np.sin(precession * t)
    kx = quaternion.skew(h_hat)
    rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
    z_now = quaternion.to_matrix(info["truth"]["state"]["attitude"])[:, 2]
    assert np.allclose(z_now, rot @ z0, atol=1e-9)


def test_quaternion_norm_stays_unit(rng):
    env = make(control_dt_s=0.1)
    env.reset(seed=3, options={"rate_rad_s": [0.3, -0.2, 0.25]})
    for _ in range(3000):
        env.step(rng.uniform(-1, 1, 4))
        assert abs(np.linalg.norm(env._y[:4]) - 1.0) <= 1e-12


def test_wheel_torque_and_speed_limits_are_respected():
    env = gym.make("attitude_envs/ReactionWheel-v0", max_wheel_speed_rad_s=100.0, episode_duration_s=1e4).unwrapped
    p = env.model.params
    env.reset(seed=0)
    action = np.array([1.0, -1.0, 3.0, 0.2])  # 3.0 is beyond the actuator range
    _, _, _, _, info = env.step(action)
    assert np.allclose(info["truth"]["applied"], [0.5, -0.5, 0.5, 0.1])  # clipped to ±max torque
    speeds = []
    for _ in range(400):
        _, _, _, _, info = env.step(action)
        speeds.append(info["truth"]["state"]["wheel_speed_rad_s"])
    speeds = np.array(speeds)
    # 0.5 N·m on 5e-4 kg·m² would reach 100 rad/s in 0.1 s; the limit holds from then on
    assert np.max(np.abs(speeds)) <= p.max_wheel_speed_rad_s * (1 + 1e-3)
    assert np.max(np.abs(speeds[:, :3])) >= p.max_wheel_speed_rad_s * (1 - 1e-3)
    assert np.all(np.abs(info["truth"]["applied"][:3]) < 0.05 * p.max_wheel_torque_nm)


def test_constant_disturbance_spins_up_the_body():
    torque = np.array([1e-3, -2e-3, 0.5e-3])
    env = make(control_dt_s=0.1, disturbance={"kind": "constant", "torque_nm": torque})
    _, info = env.reset(seed=0)
    for _ in range(10):
        _, _, _, _, info = env.step(np.zeros(4))
    # over 1 s from rest the gyroscopic term is negligible: I_eff ω ≈ T t
    w_expected = env.model.params.inertia_eff_inv @ torque * 1.0
    assert np.allclose(info["truth"]["state"]["rate_rad_s"], w_expected, rtol=1e-4, atol=1e-12)
    assert np.allclose(info["truth"]["disturbance_torque_nm"], torque)
