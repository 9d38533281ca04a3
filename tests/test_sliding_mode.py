"""Sadigh et al. 2022 baselines (AMNFTSMC, MNFTSMC, FTSMC stand-in, allocation, B-dot) and metrics."""

import gymnasium as gym
import numpy as np
import pytest

from attitude_envs import presets
from attitude_envs.evaluation import rollout
from attitude_envs.evaluation.tracking_metrics import (
    additive_error,
    asm_eq44,
    ast_eq43,
    chattering_index,
    rms_eq42,
    run_traced,
    time_to_recover,
    tracking_metrics,
)
from baselines.bdot import BDotPolicy
from baselines.sliding_mode import (
    AMNFTSMCPolicy,
    FTSMCStandInPolicy,
    MNFTSMCPolicy,
    SlidingModeGains,
    allocate_paper,
    terminal_term,
)

MT = "attitude_envs/Magnetorquer-v0"
PAPER_FAULTS = presets.get(MT, "sadigh-2022-faults").params()["faults"]  # eq. (40)


def test_allocation_reproduces_a_demand_perpendicular_to_b(rng):
    for _ in range(50):
        b = rng.normal(size=3) * 3e-5
        u = np.cross(b, rng.normal(size=3)) * 1e-1  # ⊥ b, |u| ~ 1e-6 N·m
        m, t_w = allocate_paper(u, b, max_dipole_am2=1e3, max_wheel_torque_nm=1.0)
        assert np.allclose(np.cross(m, b) + [0, t_w, 0], u, rtol=0, atol=1e-12 * np.linalg.norm(u))
        assert abs(t_w) <= 1e-12 * np.linalg.norm(u)


def test_allocation_parallel_part_goes_to_the_wheel_y_only(rng):
    b = np.array([1.0, 2.0, -0.5]) * 1e-5
    u = 3e-6 * b / np.linalg.norm(b)  # entirely parallel to b: no magnetic torque can make it
    m, t_w = allocate_paper(u, b, 0.5, 1.0)
    assert np.allclose(m, 0.0, atol=1e-18) and t_w == pytest.approx(u[1])
    # saturation keeps the dipole's direction ("scale") or clips each axis ("clip")
    u_big = np.cross(b, [1.0, 0.0, 0.0]) * 1e3
    m_scale, _ = allocate_paper(u_big, b, 0.5, 1.0, saturation="scale")
    m_clip, _ = allocate_paper(u_big, b, 0.5, 1.0, saturation="clip")
    raw = np.cross(b, u_big) / (b @ b)
    assert np.max(np.abs(m_scale)) == pytest.approx(0.5) and np.allclose(np.cross(m_scale, raw), 0.0, atol=1e-9)
    assert np.all(np.abs(m_clip) <= 0.5)
    # the "xz" variant keeps the magnetorquers off the y demand
    m_xz, t_xz = allocate_paper(np.array([0.0, 1e-6, 0.0]), b, 0.5, 1.0, variant="xz")
    assert np.allclose(m_xz, 0.0) and t_xz == pytest.approx(1e-6)


def test_exact_allocation_realizes_any_demand_within_the_limits(rng):
    """m × b + T_w e_y = u_c for any u_c (not only ⊥ b) when b_y ≠ 0; the dipole is ⊥ b."""
    for _ in range(50):
        b = rng.normal(size=3) * 3e-5
        u = rng.normal(size=3) * 1e-6
        m, t_w = allocate_paper(u, b, max_dipole_am2=1e3, max_wheel_torque_nm=1.0, variant="exact")
        assert np.allclose(np.cross(m, b) + [0, t_w, 0], u, rtol=0, atol=1e-12 * np.linalg.norm(u))
        assert abs(m @ b) <= 1e-12 * np.linalg.norm(m) * np.linalg.norm(b)
        assert t_w == pytest.approx(u @ b / b[1])
        # the paper's allocation loses the x/z part of the component along b
        m_p, t_p = allocate_paper(u, b, max_dipole_am2=1e3, max_wheel_torque_nm=1.0)
        par = (u @ b) / (b @ b) * b
        assert np.allclose(np.cross(m_p, b) + [0, t_p, 0], u - par + [0, par[1], 0], atol=1e-12 * np.linalg.norm(u))
    # b ⊥ e_y: no wheel torque can make the along-b demand; the perpendicular part is still made
    b = np.array([3e-5, 0.0, 1e-5])
    u = np.array([1e-6, 0.0, 0.0])
    m, t_w = allocate_paper(u, b, 0.5, 2.3e-4, variant="exact")
    assert t_w == 0.0 and np.allclose(np.cross(m, b), u - (u @ b) / (b @ b) * b, rtol=0, atol=1e-18)


def test_exact_allocation_under_limits_is_never_worse_than_the_papers(rng):
    """Near b_y = 0 the exact wheel share is unbounded: the perpendicular part comes first, then
    as much of the along-b part as the limits allow (x/z: u_⊥ + k u_∥, y exact)."""
    for _ in range(200):
        b = np.array([rng.normal(), 0.05 * rng.normal(), rng.normal()]) * 3e-5
        u = rng.normal(size=3) * 3e-6
        made = {}
        for variant in ("paper", "exact"):
            m, t_w = allocate_paper(u, b, 0.5, 2.3e-4, variant=variant)
            assert np.all(np.abs(m) <= 0.5 + 1e-12) and abs(t_w) <= 2.3e-4
            made[variant] = np.cross(m, b) + [0, t_w, 0]
        perp = np.cross(b, u) / (b @ b)
        if np.max(np.abs(perp)) <= 0.5 and abs((u - np.cross(perp, b))[1]) <= 2.3e-4:
            par = (u @ b) / (b @ b) * b
            k = (made["exact"] - (u - par))[[0, 2]] @ par[[0, 2]] / (par[[0, 2]] @ par[[0, 2]])
            assert -1e-9 <= k <= 1 + 1e-9
            assert np.allclose(made["exact"][[0, 2]], (u - par)[[0, 2]] + k * par[[0, 2]], atol=1e-15)
            assert made["exact"][1] == pytest.approx(u[1], abs=1e-15)
            assert np.linalg.norm(made["exact"] - u) <= np.linalg.norm(made["paper"] - u) + 1e-15
    with pytest.raises(ValueError, match="variant must be one of"):
        allocate_paper(np.ones(3), np.ones(3), 0.5, 1.0, variant="least-squares")


def test_terminal_term_is_c1_at_epsilon_and_kappa_defaults_follow_spec():
    g = SlidingModeGains()
    assert g.kappa1 == pytest.approx((2 - 0.6) * 0.01 ** (-0.4)) and g.kappa1 == pytest.approx(8.834, abs=1e-3)
    assert g.kappa2 == pytest.approx(-252.4, abs=0.1)
    eps = g.epsilon
    below, d_below = terminal_term(np.array([eps * (1 - 1e-9)]), g)
    above, d_above = terminal_term(np.array([eps * (1 + 1e-9)]), g)
    assert below[0] == pytest.approx(above[0], rel=1e-6) and d_below[0] == pytest.approx(d_above[0], rel=1e-6)
    s, ds = terminal_term(np.array([-0.2, 0.0, 0.004]), g)
    assert s[0] == pytest.approx(-(0.2**0.6)) and s[1] == 0.0 and ds[1] == pytest.approx(g.kappa1)
    s_plain, _ = terminal_term(np.array([0.004]), g, modified=False)
    assert s_plain[0] == pytest.approx(0.004**0.6)  # the FTSMC stand-in has no modification
    overridden = AMNFTSMCPolicy(gym.make(MT, episode_duration_s=1.0), r=0.5).gains
    assert overridden.kappa1 == pytest.approx(1.5 * 0.01**-0.5)


def test_bad_gains_raise():
    with pytest.raises(ValueError, match=r"r must be in \(0, 1\)"):
        SlidingModeGains(r=1.2)
    with pytest.raises(ValueError, match="mu must be in"):
        SlidingModeGains(mu=-1.0)
    with pytest.raises(ValueError, match="allocation must be one of"):
        SlidingModeGains(allocation="y")


def _nominal_env():
    return gym.make(
        MT,
        orbit={"model": "circular", "mean_anomaly_deg": 0.0},
        disturbance={"kind": "constant", "torque_nm": [0.0, 0.0, 0.0]},  # set per step below
        time_varying_inertia=None,
        control_dt_s=0.01,
        episode_duration_s=2.0,
    ).unwrapped


def _sliding_history(apply_equivalent: bool) -> np.ndarray:
    env = _nominal_env()
    pol = MNFTSMCPolicy(env, rho2=1e-30)  # switching term negligible: u_c = u_eq
    q0 = np.array([0.02, -0.03, 0.05, 1.0])
    _, info = env.reset(seed=0, options={"attitude": q0 / np.linalg.norm(q0), "rate_rad_s": [1e-3, -2e-3, 1.5e-3]})
    s_values = []
    for _ in range(100):
        u_c, s, _ = pol.demand(info)
        s_values.append(s)
        if apply_equivalent:  # an ideal actuator: u_c enters as an external body torque
            env._disturbance.torque_nm = u_c.copy()
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    return np.array(s_values)


def test_equivalent_control_cancels_the_nominal_dynamics():
    """Eq. (23): with u_c = u_eq applied exactly, J_t Ṡ = u_c − u_eq = 0 on the nominal
    circular-orbit plant, so S stays put while it drifts without control."""
    controlled = np.max(np.abs(np.diff(_sliding_history(True), axis=0)))
    free = np.max(np.abs(np.diff(_sliding_history(False), axis=0)))
    assert free > 1e-8
    assert controlled < 2e-3 * free


def test_adaptive_gain_never_decreases_and_grows_with_the_error():
    env = gym.make(MT, faults=PAPER_FAULTS, episode_duration_s=100.0, control_dt_s=0.5).unwrapped
    pol = AMNFTSMCPolicy(env, record=True)
    rollout_result = rollout(env, pol, seed=0, options={"rate_rad_s": [2e-3, -1e-3, 3e-3]})
    gains = np.array(pol.history.gain)
    assert np.all(np.diff(gains) >= 0.0) and gains[0] == pytest.approx(0.605)
    assert gains[-1] > gains[0] + 1e-4
    assert np.isfinite(rollout_result["J"]) and rollout_result["steps"] == 200
    # eq. (22) integrated with explicit Euler over the control period: Ĥ_{k+1} − Ĥ_k = μ φ ‖S_k‖ dt ≥ μ‖S_k‖dt
    increments = np.diff(gains)
    norms = np.linalg.norm(np.array(pol.history.sliding)[:-1], axis=1)
    assert np.all(increments >= 0.1 * norms * 0.5 * (1 - 1e-12))


@pytest.mark.parametrize("policy_cls", [AMNFTSMCPolicy, MNFTSMCPolicy, FTSMCStandInPolicy, BDotPolicy])
def test_every_baseline_runs_through_the_evaluator(policy_cls):
    env = gym.make(MT, episode_duration_s=20.0, faults=PAPER_FAULTS)
    result = rollout(env, policy_cls(env), seed=1)
    assert result["steps"] == 200 and np.isfinite(result["J"]) and not result["terminated"]


def test_non_adaptive_laws_keep_tracking_a_short_slew_without_disturbance():
    env = gym.make(
        MT,
        disturbance=None,
        orbit={"model": "circular", "mean_anomaly_deg": 0.0},
        reference={"delta_deg": [2.0, 4.0, 2.0], "t_final_s": 200.0},
        episode_duration_s=300.0,
        control_dt_s=0.5,
    ).unwrapped
    # faster surface than the paper's default (γ1 = 0.01 s⁻¹ takes ~100 s per e-fold)
    policy = MNFTSMCPolicy(env, boundary_layer=1e-3, allocation="xz", gamma1=0.05, gamma2=0.005)
    trace = run_traced(env, policy, seed=0)
    err = np.linalg.norm(trace.q_e, axis=1)
    passive = np.linalg.norm(run_traced(env, _Zero(), seed=0).q_e, axis=1)
    assert passive[-1] > 0.03  # the 4° slew is ‖q‖ ≈ 0.04 away
    assert np.max(err) < 0.5 * np.max(passive) and err[-1] < 0.05 * passive[-1]


class _Zero:
    name = "zero"

    def reset(self, seed=None):
        pass

    def act(self, obs, info):
        return np.zeros(4, dtype=np.float32)


def test_bdot_detumbles():
    env = gym.make(
        MT,
        task="regulation",
        disturbance=None,
        time_varying_inertia=None,
        control_dt_s=1.0,
        episode_duration_s=1500.0,
    ).unwrapped
    pol = BDotPolicy(env)
    assert pol.gain_nms == pytest.approx(2 * env.model.orbital_rate_rad_s * (1 + np.sin(np.radians(69.5))) * 0.946)
    obs, info = env.reset(seed=0, options={"rate_rad_s": [0.02, -0.015, 0.01]})
    pol.reset(0)
    w0 = np.linalg.norm(info["truth"]["state"]["inertial_rate_rad_s"])
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(pol.act(obs, info))
        done = term or trunc
    assert np.linalg.norm(info["truth"]["state"]["inertial_rate_rad_s"]) < 0.5 * w0


def test_metrics_follow_eqs_42_to_44():
    dt = 0.1
    q_e = np.tile([0.03, 0.0, -0.04], (1000, 1))  # ‖q_e‖ = 0.05 for 100 s
    assert rms_eq42(q_e, dt) == pytest.approx(np.sqrt(0.05**2 * 100.0))
    tau = np.tile([1e-6, -2e-6, 0.0], (1000, 1))
    assert ast_eq43(tau, np.full(1000, -1e-4), dt) == pytest.approx((3e-6 + 1e-4) * 100.0)
    assert asm_eq44(np.tile([0.5, -0.5, 0.25], (1000, 1)), dt) == pytest.approx(1.25 * 100.0)
    assert chattering_index(np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 0.5]])) == pytest.approx(4.5)
    assert chattering_index(np.array([[0.5], [-0.5]]), scale=[0.5]) == pytest.approx(2.0)
    q = np.array([[0.1, 0.0, 0.0, -np.sqrt(0.99)]])  # sign-flipped: same attitude as [-0.1, 0, 0, +]
    assert np.allclose(additive_error(q, np.array([[0.0, 0, 0, 1.0]])), [[-0.1, 0, 0]])


def test_time_to_recover():
    t = np.arange(0.0, 100.0, 1.0)
    err = np.where((t > 50) & (t < 70), 0.1, 0.001)
    assert time_to_recover(t, err, 50.0, 0.01) == pytest.approx(20.0)
    assert time_to_recover(t, np.full_like(t, 0.001), 50.0, 0.01) == 0.0
    assert np.isnan(time_to_recover(t, np.where(t > 60, 0.1, 0.0), 50.0, 0.01))
    with pytest.raises(ValueError, match="fault_time_s"):
        time_to_recover(t, err, 500.0, 0.01)


def test_tracking_metrics_on_a_short_episode():
    env = gym.make(MT, episode_duration_s=10.0, faults=PAPER_FAULTS).unwrapped
    trace = run_traced(env, MNFTSMCPolicy(env), seed=0)
    met = tracking_metrics(trace, 0.5, 2.3e-4, fault_time_s=5.0)
    assert met["ASM"] == pytest.approx(np.sum(np.abs(trace.dipole_am2)) * 0.1)
    assert met["ASM"] <= met["ASM_commanded"] + 1e-12
    assert 0 < met["AST"] <= (3 * 0.5 * 6e-5 + 2.3e-4) * 10.0
    assert met["RMS"] == pytest.approx(np.sqrt(np.sum(trace.q_e**2) * 0.1))
