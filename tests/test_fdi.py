"""IMM actuator FDI: isolates a 50 % wheel loss within the documented delay, no false alarms.

Documented delay (benchmarks/fdi_detection.py, 40 seeds, every wheel, wheel-degraded
scenario with noisy gyro / star tracker / tachometers, LQR on the measured state):
median 0.3 s (the 3-step confirmation), p90 2.3 s, max 9.2 s; 0/40 healthy runs alarmed.
The delay is long only when the faulty wheel is barely commanded: a loss of
effectiveness is invisible at zero command.
"""

import numpy as np
import pytest

from attitude_envs.estimation.fdi import ActuatorFDI, run_fdi_episode
from attitude_envs.scenarios import load_scenario, make_scenario_env
from baselines.lqr import LQRPolicy

DOCUMENTED_MAX_DELAY_S = 10.0
SEEDS = range(6)


@pytest.fixture(scope="module")
def setup():
    sc = load_scenario("wheel-degraded")
    env = make_scenario_env(dict(sc, faults=[]), episode_duration_s=12.0)
    return env, LQRPolicy(env), sc["faults"][0]


def test_fdi_isolates_a_50_percent_wheel_loss_within_the_documented_delay(setup):
    env, policy, fault = setup
    delays = []
    for seed in SEEDS:
        fdi = ActuatorFDI.for_env(env)
        r = run_fdi_episode(env, policy, fdi, seed=seed, options={"faults": [dict(fault, index=seed % 4)]})
        assert r["fault_index"] == seed % 4 and r["onset_s"] == 2.0
        assert r["correct"] and not r["false_alarm"], r
        # never before the onset plus the 3-step confirmation, never later than documented
        assert 0.3 - 1e-9 <= r["delay_s"] <= DOCUMENTED_MAX_DELAY_S
        assert fdi.probabilities[1 + seed % 4] == max(fdi.probabilities)
        delays.append(r["delay_s"])
    assert np.median(delays) <= 1.5  # measured 0.75 on these seeds (0.3 median over 40)


def test_fdi_raises_no_alarm_on_healthy_runs(setup):
    env, policy, _ = setup
    for seed in SEEDS:
        fdi = ActuatorFDI.for_env(env)
        r = run_fdi_episode(env, policy, fdi, seed=seed)
        assert r["detected_index"] is None and not r["false_alarm"]
        assert fdi.probabilities[0] > 0.5
        assert np.isclose(fdi.probabilities.sum(), 1.0)


def test_fdi_parameters_are_checked():
    env = make_scenario_env("wheel-degraded")
    for kwargs, match in [
        ({"degraded_effectiveness": 1.0}, r"degraded_effectiveness must be in \[0, 1\)"),
        ({"p_fault": 0.0}, r"p_fault must be in \(0, 1\)"),
        ({"threshold": 0.4}, r"threshold must be in \(0.5, 1\)"),
        ({"confirm_steps": 0}, r"confirm_steps must be >= 1"),
        ({"rate_noise_std": -1.0}, r"rate_noise_std must be in \[0, inf\)"),
    ]:
        with pytest.raises(ValueError, match=match):
            ActuatorFDI.for_env(env, **kwargs)


def test_a_multi_level_bank_isolates_a_25_percent_loss_and_estimates_its_level(setup):
    # With only the 50 % hypothesis a 25 % loss is isolated in 1 of 8 seeds; with levels
    # (0.75, 0.5, 0) in 5 of 8 (benchmark in the README), e.g. seeds 1 and 4 below.
    env, policy, fault = setup
    for seed in (1, 4):
        fdi = ActuatorFDI.for_env(env, degraded_effectiveness=(0.75, 0.5, 0.0))
        r = run_fdi_episode(env, policy, fdi, seed=seed, options={"faults": [dict(fault, index=seed % 4, value=0.25)]})
        assert r["correct"] and r["delay_s"] <= DOCUMENTED_MAX_DELAY_S
        assert fdi.detection["effectiveness"] == 0.75
        assert len(fdi.hypothesis_probabilities) == 1 + 3 * 4
        assert fdi.probabilities.shape == (5,) and np.isclose(fdi.probabilities.sum(), 1.0)
