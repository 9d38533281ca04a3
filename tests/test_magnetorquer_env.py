"""Magnetorquer-v0 (spec 002): physics, actuators, the fault at 50 s, reference, bad input."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs import quaternion
from attitude_envs.envs.magnetorquer import PAPER_FAULTS
from attitude_envs.plants import magnetorquer as mt
from attitude_envs.trajectories import SLEW_FACTOR, SmoothBangBang

MT = "attitude_envs/Magnetorquer-v0"
SHORT = {"episode_duration_s": 20.0}


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"task": "regulation", "observe_field": True, "gravity_gradient": True, "field_model": "dipole-printed"},
        {
            "orbit": {"model": "circular", "mean_anomaly_deg": 0.0},
            "inertia_uncertainty": {"kind": "random", "moment_scale": 0.1, "axis_angle_deg": 10},
            "disturbance": {"kind": "random_walk", "std_nm_per_sqrt_s": 1e-6},
            "faults": PAPER_FAULTS,
            "time_varying_inertia": None,
        },
    ],
)
def test_check_env_is_clean_with_warnings_as_errors(kwargs):
    env = gym.make(MT, **SHORT, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)


def test_check_env_with_igrf():
    pytest.importorskip("ppigrf")
    env = gym.make(MT, field_model="igrf", observe_field=True, **SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)


def test_magnetic_torque_is_m_cross_b_and_perpendicular_to_b():
    env = gym.make(MT, **SHORT).unwrapped
    _, info = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(20):
        b = info["magnetic_field_body_t"]
        action = rng.uniform(-1, 1, 4).astype(np.float32)
        _, _, _, _, info = env.step(action)
        tau = info["magnetic_torque_nm"]
        m = info["applied"][:3]
        assert np.allclose(m, action[:3].astype(float) * 0.5)
        assert np.allclose(tau, np.cross(m, b), rtol=1e-12, atol=0)  # one sub-step: field at the step start
        assert abs(tau @ b) <= 1e-12 * np.linalg.norm(tau) * np.linalg.norm(b)
        assert np.linalg.norm(tau) > 1e-7
        assert np.allclose(info["control_torque_nm"], tau + [0, info["applied"][3], 0])


def test_torque_free_motion_conserves_inertial_momentum_with_the_wheel_working():
    """No field torque, no disturbance, constant (asymmetric) inertia: the wheel only
    exchanges momentum, so the total angular momentum in ECI stays put (Keplerian orbit)."""
    env = gym.make(
        MT,
        disturbance=None,
        time_varying_inertia=None,
        inertia_uncertainty={"kind": "random", "moment_scale": 0.2, "axis_angle_deg": 30},
        control_dt_s=0.1,
        integrator_dt_s=0.05,
        **SHORT,
    ).unwrapped
    _, info = env.reset(seed=3, options={"rate_rad_s": [0.03, -0.05, 0.02], "wheel_speed_rad_s": [50.0]})
    inertia = info["true_inertia_kg_m2"]
    assert not np.allclose(inertia, np.diag(np.diag(inertia)))  # principal axes rotated

    def momentum(info):
        orbit_state = env.orbit.state_at(info["time_s"])
        st = info["state"]
        return mt.angular_momentum_inertial(
            st["attitude"],
            st["inertial_rate_rad_s"],
            st["wheel_speed_rad_s"][0],
            inertia,
            env.model.params.wheel_inertia_kg_m2,
            orbit_state.eci_from_orbital,
        )

    h0 = momentum(info)
    w0 = info["state"]["wheel_speed_rad_s"][0]
    for k in range(200):
        _, _, _, _, info = env.step(np.array([0, 0, 0, 1.0 if k < 100 else -0.5], dtype=np.float32))
    assert info["state"]["wheel_speed_rad_s"][0] != pytest.approx(w0, abs=10.0)  # the wheel did work
    assert np.allclose(momentum(info), h0, rtol=0, atol=1e-10 * np.linalg.norm(h0))


def test_torque_free_rigid_body_conserves_kinetic_energy():
    env = gym.make(MT, disturbance=None, time_varying_inertia=None, **SHORT).unwrapped
    _, info = env.reset(seed=0, options={"rate_rad_s": [0.02, 0.01, -0.03], "wheel_speed_rad_s": [20.0]})
    p = env.model.params

    def energy(info):
        w = info["state"]["inertial_rate_rad_s"]
        om = info["state"]["wheel_speed_rad_s"][0]
        eff = p.inertia_kg_m2 - p.wheel_inertia_kg_m2 * np.outer(mt.E_Y, mt.E_Y)
        return 0.5 * w @ eff @ w + 0.5 * p.wheel_inertia_kg_m2 * (om + w[1]) ** 2

    e0 = energy(info)
    for _ in range(100):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    assert energy(info) == pytest.approx(e0, rel=1e-9)


def test_paper_fault_at_50_s_reaches_only_the_magnetorquers():
    env = gym.make(MT, faults=PAPER_FAULTS, control_dt_s=1.0, episode_duration_s=60.0).unwrapped
    env.reset(seed=0)
    action = np.array([0.8, -0.6, 0.4, 0.5], dtype=np.float32)
    commanded = action.astype(float) * [0.5, 0.5, 0.5, 2.3e-4]
    for _ in range(60):
        t = env._t
        _, _, _, _, info = env.step(action)
        assert np.allclose(info["commanded"], commanded)
        expected = commanded * ([1.0, 1.0, 1.0, 1.0] if t < 50.0 else [0.9, 0.7, 0.6, 1.0])
        assert np.allclose(info["applied"], expected, rtol=1e-12)
        assert [f["active"] for f in info["faults"]] == [info["time_s"] >= 50.0] * 3
    assert [f["index"] for f in info["faults"]] == [0, 1, 2]


def test_wheel_momentum_limit_blocks_further_spin_up():
    env = gym.make(MT, max_wheel_momentum_nms=1e-3, disturbance=None, control_dt_s=1.0, **SHORT).unwrapped
    env.reset(seed=0, options={"wheel_speed_rad_s": [-19.9]})  # h_w = J_w Ω ≈ −9.95e-4 N·m·s
    # T_w > 0 on the body spins the wheel further negative
    applied = [env.step(np.array([0, 0, 0, 1.0], dtype=np.float32))[4]["applied"][3] for _ in range(5)]
    assert applied[0] == pytest.approx(2.3e-4) and applied[-1] == 0.0
    assert env.step(np.array([0, 0, 0, -1.0], dtype=np.float32))[4]["applied"][3] == pytest.approx(-2.3e-4)


def test_tracking_starts_on_the_reference_and_reference_is_the_papers_profile():
    env = gym.make(MT, **SHORT).unwrapped
    obs, info = env.reset(seed=0)
    assert np.allclose(obs, 0.0) and np.allclose(info["state"]["attitude"], [0, 0, 0, 1])
    ref = SmoothBangBang([10.0, 20.0, 10.0], 1200.0)
    assert SLEW_FACTOR == pytest.approx(0.13125)
    assert np.allclose(np.degrees(ref.euler(1200.0)[0]), [10, 20, 10])
    assert np.allclose(np.degrees(ref.euler(600.0)[0]), [5, 10, 5])  # symmetric profile
    assert np.allclose(ref.euler(1200.0)[1], 0.0, atol=1e-15)  # rest at t_f
    assert ref.profile(300.0)[2] == pytest.approx(1.0) and ref.profile(900.0)[2] == pytest.approx(-1.0)
    # peak rate (T_max/J)·0.28125·t_f at t_f/2 (spec §5.1)
    assert ref.euler(600.0)[1][1] == pytest.approx(ref.gain[1] * 0.28125 * 1200.0)
    # q̇_d is the derivative of q_d and ω_d its body rate
    h = 1e-3
    for t in (100.0, 450.0, 1000.0):
        q_d, w_d, q_dot = ref.attitude(t)
        num = (ref.attitude(t + h)[0] - ref.attitude(t - h)[0]) / (2 * h)
        assert np.allclose(q_dot, num, atol=1e-12)
        assert np.allclose(2 * quaternion.multiply(quaternion.conjugate(q_d), num)[:3], w_d, atol=1e-11)
    # eq. (38) is the 3-2-1 sequence
    q_d = ref.attitude(1200.0)[0]
    assert np.allclose(quaternion.to_euler_321_deg(q_d), [10, 20, 10])


def test_regulation_draws_start_within_angle_and_seeded_anomaly():
    env = gym.make(MT, task="regulation", initial_angle_deg=15.0, **SHORT).unwrapped
    angles, lats = [], []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        angles.append(info["error_angle_deg"])
        lats.append(info["orbit"]["argument_of_latitude_rad"])
    assert max(angles) <= 15.0 + 1e-9 and min(angles) < 7.5 < max(angles)
    assert len(set(np.round(lats, 6))) == 20
    _, info = env.reset(seed=0, options={"mean_anomaly_deg": 0.0})
    assert info["orbit"]["radius_m"] == pytest.approx((6371 + 311) * 1e3)  # perigee


def test_reward_is_the_integrated_cost_and_independent_of_the_control_period():
    costs = []
    for dt in (0.5, 0.25):
        env = gym.make(MT, control_dt_s=dt, integrator_dt_s=0.25, episode_duration_s=10.0).unwrapped
        env.reset(seed=0, options={"rate_rad_s": [1e-3, -2e-3, 5e-4], "mean_anomaly_deg": 10.0})
        total, done = 0.0, False
        while not done:
            _, reward, term, trunc, info = env.step(np.array([0.2, -0.1, 0.3, 0.5], dtype=np.float32))
            assert reward == -info["cost"] and info["cost"] > 0
            total += info["cost"]
            done = term or trunc
        costs.append(total)
    assert costs[0] == pytest.approx(costs[1], rel=1e-9)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"max_dipole_am2": -0.5}, r"max_dipole_am2 must be in \(0, inf\)"),
        ({"max_wheel_torque_nm": 0.0}, r"max_wheel_torque_nm must be in \(0, inf\)"),
        ({"orbit": {"inclination_deg": 190.0}}, r"inclination_deg must be in \[0, 180\]"),
        ({"orbit": {"apogee_altitude_km": 300.0, "perigee_altitude_km": 400.0}}, "apogee >= perigee"),
        ({"orbit": {"eccentricity": 1.2}}, "orbit has unknown keys"),
        ({"orbit": {"mean_anomaly_deg": "sometimes"}}, "orbit.mean_anomaly_deg must be one of"),
        ({"field_model": "tilted"}, "field_model must be one of"),
        ({"task": "slew"}, "task must be one of"),
        ({"disturbance": "huge"}, "disturbance must be one of"),
        ({"disturbance_scale": -1.0}, r"disturbance_scale must be in \[0, inf\)"),
        ({"time_varying_inertia": {"amplitude_kg_m2": [1.0, 0, 0]}}, "must stay below the smallest principal"),
        ({"reference": {"t_final_s": -5.0}}, "reference.t_final_s must be in"),
        ({"inertia_kg_m2": np.diag([1.0, 1.0, 3.0])}, "triangle inequality"),
        ({"initial_angle_deg": 200.0}, r"initial_angle_deg must be in \[0, 180\]"),
        ({"faults": [{"kind": "bias", "index": 4, "value": 0.1}]}, r"index must be an integer in \[0, 3\]"),
    ],
)
def test_bad_input_raises_value_error_naming_the_parameter(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(MT, **kwargs)


def test_eccentricity_at_or_above_one_raises():
    from attitude_envs.plants.orbit import KeplerOrbit

    for e in (1.0, 1.5):
        with pytest.raises(ValueError, match=r"eccentricity must be in \[0, 1\)"):
            KeplerOrbit(7.2e6, e, 69.5)


def test_gravity_gradient_torque_option():
    """3μ/r³ ô × (Iô), ô the nadir in body axes: zero at the principal-axes-aligned attitude,
    (3μ/r³)(I_zz − I_yy) sinθ cosθ about x after a roll θ (circular orbit, r = a)."""
    inertia = np.diag([0.9, 1.0, 1.2])
    env = gym.make(
        MT,
        inertia_kg_m2=inertia,
        disturbance=None,
        time_varying_inertia=None,
        gravity_gradient=True,
        orbit={"model": "circular", "mean_anomaly_deg": 0.0},
        **SHORT,
    ).unwrapped
    _, info = env.reset(seed=0, options={"attitude": [0, 0, 0, 1.0]})
    assert np.allclose(info["disturbance_torque_nm"], 0.0, atol=1e-20)
    theta = np.radians(20.0)
    _, info = env.reset(seed=0, options={"attitude": quaternion.from_axis_angle([1, 0, 0], theta)})
    k = 3 * 3.986004418e14 / env.orbit.a**3
    expected = k * (1.2 - 1.0) * np.sin(theta) * np.cos(theta)
    assert np.allclose(info["disturbance_torque_nm"], [expected, 0, 0], rtol=1e-12, atol=1e-20)
    assert abs(expected) > 1e-7
