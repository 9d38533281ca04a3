"""Magnetorquer-v0 (Sadigh, Kashaninia & Dehghan 2022): physics, actuators, the fault at 50 s,
reference, presets, the info contract, bad input."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs import presets, quaternion
from attitude_envs.info import policy_view
from attitude_envs.plants import magnetorquer as mt
from attitude_envs.trajectories import SLEW_FACTOR, SmoothBangBang

MT = "attitude_envs/Magnetorquer-v0"
SHORT = {"episode_duration_s": 20.0}
PAPER_FAULTS = presets.get(MT, "sadigh-2022-faults").params()["faults"]  # eq. (40)


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
        b = info["truth"]["magnetic_field_body_t"]
        assert np.array_equal(info["measured"]["magnetic_field_body_t"], b)  # no sensors: the truth
        action = rng.uniform(-1, 1, 4).astype(np.float32)
        _, _, _, _, info = env.step(action)
        tau = info["truth"]["magnetic_torque_nm"]
        m = info["truth"]["applied"][:3]
        assert np.allclose(m, action[:3].astype(float) * 0.5)
        assert np.allclose(tau, np.cross(m, b), rtol=1e-12, atol=0)  # one sub-step: field at the step start
        assert abs(tau @ b) <= 1e-12 * np.linalg.norm(tau) * np.linalg.norm(b)
        assert np.linalg.norm(tau) > 1e-7
        assert np.allclose(info["truth"]["control_torque_nm"], tau + [0, info["truth"]["applied"][3], 0])


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
    inertia = info["truth"]["true_inertia_kg_m2"]
    assert not np.allclose(inertia, np.diag(np.diag(inertia)))  # principal axes rotated

    def momentum(info):
        orbit_state = env.orbit.state_at(info["time_s"])
        st = info["truth"]["state"]
        return mt.angular_momentum_inertial(
            st["attitude"],
            st["inertial_rate_rad_s"],
            st["wheel_speed_rad_s"][0],
            inertia,
            env.model.params.wheel_inertia_kg_m2,
            orbit_state.eci_from_orbital,
        )

    h0 = momentum(info)
    w0 = info["truth"]["state"]["wheel_speed_rad_s"][0]
    for k in range(200):
        _, _, _, _, info = env.step(np.array([0, 0, 0, 1.0 if k < 100 else -0.5], dtype=np.float32))
    assert info["truth"]["state"]["wheel_speed_rad_s"][0] != pytest.approx(w0, abs=10.0)  # the wheel did work
    assert np.allclose(momentum(info), h0, rtol=0, atol=1e-10 * np.linalg.norm(h0))


def test_torque_free_rigid_body_conserves_kinetic_energy():
    env = gym.make(MT, disturbance=None, time_varying_inertia=None, **SHORT).unwrapped
    _, info = env.reset(seed=0, options={"rate_rad_s": [0.02, 0.01, -0.03], "wheel_speed_rad_s": [20.0]})
    p = env.model.params

    def energy(info):
        w = info["truth"]["state"]["inertial_rate_rad_s"]
        om = info["truth"]["state"]["wheel_speed_rad_s"][0]
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
    t = 0.0
    for _ in range(60):
        _, _, _, _, info = env.step(action)
        assert np.allclose(info["commanded"], commanded)
        expected = commanded * ([1.0, 1.0, 1.0, 1.0] if t < 50.0 else [0.9, 0.7, 0.6, 1.0])
        assert np.allclose(info["truth"]["applied"], expected, rtol=1e-12)
        assert [f["active"] for f in info["truth"]["faults"]] == [info["time_s"] >= 50.0] * 3
        t = info["time_s"]
    assert [f["index"] for f in info["truth"]["faults"]] == [0, 1, 2]


def test_wheel_momentum_limit_blocks_further_spin_up():
    env = gym.make(MT, max_wheel_momentum_nms=1e-3, disturbance=None, control_dt_s=1.0, **SHORT).unwrapped
    env.reset(seed=0, options={"wheel_speed_rad_s": [-19.9]})  # h_w = J_w Ω ≈ −9.95e-4 N·m·s
    # T_w > 0 on the body spins the wheel further negative
    applied = [env.step(np.array([0, 0, 0, 1.0], dtype=np.float32))[4]["truth"]["applied"][3] for _ in range(5)]
    assert applied[0] == pytest.approx(2.3e-4) and applied[-1] == 0.0
    info = env.step(np.array([0, 0, 0, -1.0], dtype=np.float32))[4]
    assert info["truth"]["applied"][3] == pytest.approx(-2.3e-4)


def test_tracking_starts_on_the_reference_and_reference_is_the_papers_profile():
    env = gym.make(MT, **SHORT).unwrapped
    obs, info = env.reset(seed=0)
    assert np.allclose(obs, 0.0) and np.allclose(info["truth"]["state"]["attitude"], [0, 0, 0, 1])
    ref = SmoothBangBang([10.0, 20.0, 10.0], 1200.0)
    assert SLEW_FACTOR == pytest.approx(0.13125)
    assert np.allclose(np.degrees(ref.euler(1200.0)[0]), [10, 20, 10])
    assert np.allclose(np.degrees(ref.euler(600.0)[0]), [5, 10, 5])  # symmetric profile
    assert np.allclose(ref.euler(1200.0)[1], 0.0, atol=1e-15)  # rest at t_f
    assert ref.profile(300.0)[2] == pytest.approx(1.0) and ref.profile(900.0)[2] == pytest.approx(-1.0)
    # peak rate (T_max/J)·0.28125·t_f at t_f/2 (the profile of the paper's eqs. 36–37)
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
        angles.append(info["truth"]["error_angle_deg"])
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
    assert np.allclose(info["truth"]["disturbance_torque_nm"], 0.0, atol=1e-20)
    theta = np.radians(20.0)
    _, info = env.reset(seed=0, options={"attitude": quaternion.from_axis_angle([1, 0, 0], theta)})
    k = 3 * 3.986004418e14 / env.orbit.a**3
    expected = k * (1.2 - 1.0) * np.sin(theta) * np.cos(theta)
    assert np.allclose(info["truth"]["disturbance_torque_nm"], [expected, 0, 0], rtol=1e-12, atol=1e-20)
    assert abs(expected) > 1e-7


def test_presets_hold_the_papers_values_with_sources():
    names = [p.name for p in presets.for_env(MT)]
    assert names == ["sadigh-2022", "sadigh-2022-faults"]
    paper = presets.get(MT)  # the default
    assert paper.name == "sadigh-2022"
    values = paper.params()
    assert np.array_equal(values["inertia_kg_m2"], np.diag([0.951, 0.97 + 50e-6, 0.946]))
    assert (values["max_dipole_am2"], values["max_wheel_torque_nm"], values["wheel_inertia_kg_m2"]) == (
        0.5,
        2.3e-4,
        50e-6,
    )
    assert values["orbit"]["inclination_deg"] == 69.5 and values["orbit"]["apogee_altitude_km"] == 1250.0
    for key in paper.values:
        source = paper.source(key)
        assert source.startswith("Sadigh et al. 2022") or source.startswith("assumed:"), (key, source)
    faults = presets.get(MT, "sadigh-2022-faults")
    assert {k: v for k, v in faults.params().items() if k != "faults"}.keys() == values.keys()
    assert faults.source("faults").startswith("Sadigh et al. 2022, eq. 40")
    # the faults preset is the paper's scenario: same episode as passing its faults
    a = gym.make(MT, preset="sadigh-2022-faults", **SHORT).unwrapped
    b = gym.make(MT, faults=PAPER_FAULTS, **SHORT).unwrapped
    a.reset(seed=2)
    b.reset(seed=2)
    for _ in range(3):
        oa, ra, *_ = a.step(np.full(4, 0.3))
        ob, rb, *_ = b.step(np.full(4, 0.3))
        assert np.array_equal(oa, ob) and ra == rb


def test_partial_dict_keywords_complete_from_the_preset():
    env = gym.make(MT, orbit={"model": "circular", "mean_anomaly_deg": 0.0}, **SHORT).unwrapped
    assert env.orbit.model == "circular" and np.degrees(env.orbit.inclination_rad) == pytest.approx(69.5)
    env = gym.make(MT, reference={"t_final_s": 600.0}, **SHORT).unwrapped
    assert env.model.reference.t_final_s == 600.0
    off = gym.make(MT, time_varying_inertia=None, disturbance=None, **SHORT).unwrapped
    assert off.time_varying_inertia is None and off.disturbance is None and not off.paper_disturbance
    part = gym.make(MT, time_varying_inertia={"frequency_rad_s": [0.1, 0.1, 0.1]}, **SHORT).unwrapped
    assert np.array_equal(part.time_varying_inertia.amplitude_kg_m2, [0.095, 0.19, 0.095])  # eq. (35)'s
    with pytest.raises(ValueError, match="preset must be one of"):
        gym.make(MT, preset="sadig-2022")
    with pytest.raises(ValueError, match="time_varying_inertia must be one of"):
        gym.make(MT, time_varying_inertia="printed")


def test_info_separates_truth_from_what_a_flight_computer_has():
    env = gym.make(MT, **SHORT).unwrapped
    _, info = env.reset(seed=0)
    _, _, _, _, info = env.step(np.full(4, 0.5, dtype=np.float32))
    truth, measured = info["truth"], info["measured"]
    state_keys = {"attitude", "rate_rad_s", "inertial_rate_rad_s", "wheel_speed_rad_s", "wheel_momentum_nms"}
    assert set(truth["state"]) == state_keys
    assert set(measured) == state_keys | {"magnetic_field_body_t"}
    assert {
        "applied",
        "faults",
        "error_angle_deg",
        "disturbance_torque_nm",
        "true_inertia_kg_m2",
        "magnetic_torque_nm",
        "control_torque_nm",
        "magnetic_field_body_t",
    } <= set(truth)
    for key in state_keys:
        assert np.array_equal(measured[key], truth["state"][key])  # sensors off: the truth
    view = policy_view(info)
    assert set(view) == {"measured", "cost", "time_s", "commanded", "reference", "orbit", "magnetic_field_orbital_t"}
    assert set(view["reference"]) == {"attitude", "rate_rad_s", "attitude_rate"}
    assert "sensors" not in info


def test_measured_state_comes_from_the_sensors():
    bias = {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 0, "value": 1e-3, "onset_s": 0.0}
    env = gym.make(MT, sensors={"magnetometer": {"noise_std": 1e-8}}, faults=[bias], **SHORT).unwrapped
    _, info = env.reset(seed=1)
    for _ in range(3):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    truth, measured, raw = info["truth"], info["measured"], info["sensors"]
    assert set(raw) == {"gyro", "star_tracker", "tachometer", "magnetometer"}
    assert np.array_equal(measured["magnetic_field_body_t"], raw["magnetometer"])
    assert not np.array_equal(measured["magnetic_field_body_t"], truth["magnetic_field_body_t"])
    assert np.allclose(measured["magnetic_field_body_t"], truth["magnetic_field_body_t"], atol=1e-7)
    assert np.allclose(measured["inertial_rate_rad_s"] - truth["state"]["inertial_rate_rad_s"], [1e-3, 0, 0])
    assert np.allclose(measured["rate_rad_s"] - truth["state"]["rate_rad_s"], [1e-3, 0, 0], atol=1e-12)
    assert np.allclose(measured["attitude"], truth["state"]["attitude"])  # noise-free star tracker
    # the bias is on x: the y rate and the wheel, so the momentum, are exact
    assert measured["wheel_momentum_nms"] == pytest.approx(truth["state"]["wheel_momentum_nms"], rel=1e-12)
    assert set(truth["sensor_bias"]) == {"magnetometer"}


def test_public_interface_of_the_single_env():
    env = gym.make(MT, observe_field=True, disturbance={"kind": "random_walk", "std_nm_per_sqrt_s": 1e-6}, **SHORT)
    env = env.unwrapped
    env.reset(seed=0)
    assert env.observation_size == 10 and env.kernel_constants.ndim == 1
    assert np.array_equal(env.state_row, [0, 0, 0, 1, 0, 0, 0, 0])
    for view in (env.state_row, env.snapshot, env.episode_constants):
        assert not view.flags.writeable
    before = env.disturbance.walk_nm.copy()
    env.advance_disturbance()
    assert not np.array_equal(env.disturbance.walk_nm, before)
    from attitude_envs.plants import magnetorquer_kernels as kernels

    assert np.array_equal(env.episode_constants[kernels.EN_DIST : kernels.EN_DIST + 3], env.disturbance.walk_nm)
