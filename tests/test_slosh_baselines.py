"""Navabi & Davoodi fuel-slosh baselines: PD, LQR (paper / feasible), Lyapunov reconstruction, fuzzy PD."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from attitude_envs.envs.fuel_slosh import PAPER_INITIAL_STATE, FuelSloshEnv
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.plants.slosh_model import reduced_derivative
from baselines.base import Policy
from baselines.fuzzy_slosh import GAIN_RANGES, SIGMA, FuzzySloshPDPolicy
from baselines.slosh import SloshLQRPolicy, SloshLyapunovPolicy, SloshPDPolicy
from experiments.reproductions.fuel_slosh_runs import metrics, simulate_reduced

X0 = PAPER_INITIAL_STATE[1:]


@pytest.fixture(scope="module")
def env():
    return FuelSloshEnv(episode_duration_s=20.0)


def _all(env):
    return [
        SloshPDPolicy(env),
        SloshLQRPolicy(env, "paper"),
        SloshLQRPolicy(env, "feasible"),
        SloshLyapunovPolicy(env),
        FuzzySloshPDPolicy(env),
    ]


def test_every_baseline_runs_through_the_evaluator(env):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        results = {p.name: rollout(env, p, seed=0) for p in _all(env)}
    for name, res in results.items():
        assert res["steps"] == 200 and not res["terminated"], name
        assert np.isfinite(res["J"]) and res["J"] > 0, name
    zero = rollout(env, type("Zero", (), {"name": "z", "reset": lambda s, seed=None: None,
                                          "act": lambda s, o, i: np.zeros(2, np.float32)})(), seed=0)  # fmt: skip
    assert results["lqr-paper"]["J"] < zero["J"]  # the optimal design beats doing nothing


def test_policies_satisfy_protocol_and_work_with_hidden_slosh():
    hidden = FuelSloshEnv(observe_slosh=False, episode_duration_s=5.0)
    for p in _all(hidden):
        assert isinstance(p, Policy)
        res = rollout(hidden, p, seed=0)
        assert res["steps"] == 50 and np.isfinite(res["J"])


def test_pd_law_and_initial_inputs(env):
    pd = SloshPDPolicy(env)
    u = pd.new_inputs(X0, 3000.0)
    np.testing.assert_allclose(u, [-0.6, -5e-5 * math.radians(2)])
    obs, info = env.reset()
    action = pd.act(obs, info)
    # reconstruction notes (eqs. 11–13): δ(0) = −17.53°, M(0) = 859 N·m, normalized by 30° and 2000 N·m
    np.testing.assert_allclose(action, [-17.53 / 30.0, 859.16 / 2000.0], atol=2e-4)


def test_paper_lqr_gain_matches_the_reconstructed_reference(env):
    """Reference gain of eqs. 30–31 (reconstruction notes) and closed-loop poles (continuous design, v_x = 3000)."""
    lqr = SloshLQRPolicy(env, "paper", discretization="continuous")
    K_ref = np.array(
        [
            [-0.31753, -0.94825, -110.14, -70.945, -267.49, 70.575, -133.77],
            [0.94825, -0.31753, 320.58, -20.202, -95.995, 19.170, -40.126],
        ]
    )
    np.testing.assert_allclose(lqr.gain, K_ref, rtol=2e-4)
    lin = env.model.linearize()
    poles = np.sort(np.linalg.eigvals(lin.A - lin.B @ lqr.gain).real)
    assert poles[0] == pytest.approx(-448.47, rel=1e-4)
    assert poles[-1] == pytest.approx(-2.7149e-4, rel=1e-3)


def test_feasible_lqr_respects_transverse_authority_and_beats_pd():
    env = FuelSloshEnv()
    m = env.model
    runs = {}
    for p in (SloshLQRPolicy(env, "feasible", discretization="continuous"), SloshPDPolicy(env)):
        runs[p.name] = metrics(simulate_reduced(p, m.params, X0, 3000.0, 400.0, p.name == "pd", m.cost.Q, m.cost.R))
    feas = runs["lqr-feasible"]
    assert feas["peak abs u1 (m/s^2)"] <= 2.0  # F/m_t
    assert feas["peak abs delta (deg)"] <= 30.0
    assert max(feas["settling v_z (s)"], feas["settling theta (s)"], feas["settling psi1 (s)"]) < 200.0
    assert runs["pd"]["settling psi1 (s)"] == math.inf  # PD still sloshing > 0.5° at 400 s


def test_lyapunov_rate_formula_matches_numerical_derivative(env):
    lyap = SloshLyapunovPolicy(env, gamma=1e-3, k1=1e-6)  # a γ large enough to exercise the slosh terms
    rng = np.random.default_rng(0)
    p = env.model.params
    for _ in range(5):
        z = np.concatenate([[3000.0], rng.normal(size=7) * [10, 0.02, 1e-3, 0.3, 0.2, 0.3, 0.2]])
        u = rng.normal(size=2) * [0.5, 1e-4]
        dz = reduced_derivative(p, z, u)
        h = 1e-6
        vdot_num = (lyap.lyapunov(z[1:] + h * dz[1:]) - lyap.lyapunov(z[1:] - h * dz[1:])) / (2 * h)
        assert lyap.lyapunov_rate(z[1:], z[0], u) == pytest.approx(vdot_num, rel=1e-5)


def test_fuzzy_gains_at_zero_error_match_centroid_of_rule_outputs(env):
    """At e = ė = 0 exactly one rule fires per output (ZO, ZO) with strength 1, so K' is
    the centroid of that Gaussian on [0, 1] (computed here independently of scikit-fuzzy)."""
    fz = FuzzySloshPDPolicy(env)
    gains = fz.schedule(np.zeros(7), 3000.0)
    y = np.linspace(0.0, 1.0, 200001)
    big = np.exp(-((y - 1.0) ** 2) / (2 * SIGMA**2))
    k_big = float(np.sum(y * big) / np.sum(big))
    k_small = 1.0 - k_big
    assert 0.67 < k_big < 0.68  # reconstruction notes: output range "about [0.322, 0.678]"
    expected = [
        GAIN_RANGES["k1"][0] + (GAIN_RANGES["k1"][1] - GAIN_RANGES["k1"][0]) * k_small,  # two-rule base: S
        GAIN_RANGES["k2"][0] + (GAIN_RANGES["k2"][1] - GAIN_RANGES["k2"][0]) * k_big,  # Table 1 (ZO, ZO) = B
        GAIN_RANGES["k3"][0] + (GAIN_RANGES["k3"][1] - GAIN_RANGES["k3"][0]) * k_big,  # Table 2 (ZO, ZO) = B
    ]
    np.testing.assert_allclose(gains, expected, rtol=1e-3)


def test_fuzzy_schedule_is_odd_symmetric_and_varies(env):
    fz = FuzzySloshPDPolicy(env)
    x = np.array([30.0, math.radians(1.5), 1e-4, 0, 0, 0, 0])
    g_pos = fz.schedule(x, 3000.0)
    g_neg = fz.schedule(-x, 3000.0)
    np.testing.assert_allclose(g_pos, g_neg, rtol=1e-9)  # the rule tables are symmetric
    g_zero = fz.schedule(np.zeros(7), 3000.0)
    assert not np.allclose(g_pos, g_zero, rtol=1e-3)


@pytest.mark.parametrize(
    ("factory", "name"),
    [
        (lambda e: SloshPDPolicy(e, k1=-1.0), "k1"),
        (lambda e: SloshLQRPolicy(e, "optimal"), "weights"),
        (lambda e: SloshLQRPolicy(e, R=np.zeros((2, 2))), "R"),
        (lambda e: SloshLyapunovPolicy(e, c2=0.0), "c2"),
        (lambda e: SloshLyapunovPolicy(e, k4=1.0), "k4"),
        (lambda e: FuzzySloshPDPolicy(e, schedule_period_s=0.0), "schedule_period_s"),
        (lambda e: SloshPDPolicy(e, inversion="exact"), "inversion"),
    ],
)
def test_bad_controller_arguments_raise(env, factory, name):
    with pytest.raises(ValueError, match=name):
        factory(env)
