"""Controllers see what a flight computer sees: the sensor layer, never the ground truth.

Every state-feedback baseline is run on an env with sensors off and on the same env with
sensor noise, both reset with the same seed. The sensor layer draws from its own generator
(spawned from the env's RNG without advancing it), so both envs start in the same true state
and stay in it while the actions agree; only the measurement differs. A baseline that read
the truth would act identically; one that reads ``info["measured"]`` (or the observation)
does not. The evaluator hands ``act`` the policy view of the info, without ``"truth"``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents.ga_tuning import pid_episode
from attitude_envs.evaluation import Scenario, evaluate, record_episode, rollout
from attitude_envs.evaluation.tracking_metrics import run_traced
from attitude_envs.info import MEASURED, TRUTH, policy_view
from baselines.bdot import BDotPolicy
from baselines.fault_tolerant import FaultTolerantLQRPolicy
from baselines.feedback_linearization import FeedbackLinearizationPolicy
from baselines.fuzzy_slosh import FuzzySloshPDPolicy
from baselines.linear_lqr import LinearLQRPolicy
from baselines.lqr import LQRPolicy
from baselines.pid import PAPER_FIXED, PIDPolicy, paper_schedule
from baselines.quaternion_lqr import QuaternionLQRPolicy
from baselines.sliding_mode import AMNFTSMCPolicy, FTSMCStandInPolicy, MNFTSMCPolicy
from baselines.slosh import SloshLQRPolicy, SloshLyapunovPolicy, SloshPDPolicy
from experiments.campaign import episode

RW = "attitude_envs/ReactionWheel-v0"
AB = "attitude_envs/AirBearing-v0"
MT = "attitude_envs/Magnetorquer-v0"
FS = "attitude_envs/FuelSlosh-v0"
LS = "attitude_envs/LinearSystem-v0"
ENVS = (RW, AB, MT, FS, LS)

GYRO_STAR = {"gyro": {"noise_std": 1e-3}, "star_tracker": {"noise_std": 1e-3}}  # rad/s, rad
STATE = {"state": {"noise_std": 1e-3}}
MAGNETOMETER = {"magnetometer": {"noise_std": 1e-7}}  # T (the field is ~3e-5 T)


def mpc_policy(env):
    """The MPC baseline (CasADi is optional: skip without it)."""
    pytest.importorskip("casadi")
    from baselines.mpc import MPCPolicy  # optional dependency: imported once CasADi is known to be there

    return MPCPolicy(env, horizon_steps=5)


# name -> (env id, env kwargs, sensors, policy factory): every baseline mapping state -> action
BASELINES = {
    "quaternion-lqr": (RW, {}, GYRO_STAR, QuaternionLQRPolicy),
    "lqr": (RW, {}, GYRO_STAR, LQRPolicy),
    "lqr-ft": (RW, {}, GYRO_STAR, FaultTolerantLQRPolicy),
    "mpc": (RW, {}, GYRO_STAR, mpc_policy),
    "feedback-linearization": (RW, {}, GYRO_STAR, FeedbackLinearizationPolicy),
    "pid-fixed": (AB, {}, GYRO_STAR, lambda env: PIDPolicy(env, PAPER_FIXED)),
    "pid-state-dependent": (AB, {}, GYRO_STAR, lambda env: PIDPolicy(env, paper_schedule("rad"))),
    "amnftsmc": (MT, {}, GYRO_STAR, AMNFTSMCPolicy),
    "mnftsmc": (MT, {}, GYRO_STAR, MNFTSMCPolicy),
    "ftsmc-stand-in": (MT, {}, GYRO_STAR, FTSMCStandInPolicy),
    "b-dot": (MT, {}, MAGNETOMETER, BDotPolicy),
    "slosh-pd": (FS, {}, STATE, SloshPDPolicy),
    "slosh-lqr": (FS, {}, STATE, SloshLQRPolicy),
    "slosh-lyapunov": (FS, {}, STATE, SloshLyapunovPolicy),
    "slosh-fuzzy": (FS, {}, STATE, FuzzySloshPDPolicy),
    "linear-lqr": (LS, {}, STATE, LinearLQRPolicy),
}


def same(a, b) -> bool:
    """Equal nested dicts / arrays / numbers (exactly)."""
    if isinstance(a, dict) or isinstance(b, dict):
        return isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return np.array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("name", sorted(BASELINES))
def test_baseline_acts_on_the_measurement_not_the_truth(name):
    env_id, kwargs, sensors, make_policy = BASELINES[name]
    clean, noisy = gym.make(env_id, **kwargs), gym.make(env_id, sensors=sensors, **kwargs)
    pol_clean, pol_noisy = make_policy(clean), make_policy(noisy)
    (obs_c, info_c), (obs_n, info_n) = clean.reset(seed=3), noisy.reset(seed=3)
    pol_clean.reset(3)
    pol_noisy.reset(3)
    for _ in range(5):
        # same truth, different measurement (the sensor layer is the only difference)
        assert same(info_c[TRUTH]["state"], info_n[TRUTH]["state"])
        assert not same(info_c[MEASURED], info_n[MEASURED])
        a_c = np.asarray(pol_clean.act(obs_c, policy_view(info_c)))
        a_n = np.asarray(pol_noisy.act(obs_n, policy_view(info_n)))
        if not np.array_equal(a_c, a_n):
            return  # the action followed the measurement
        obs_c, _, term_c, trunc_c, info_c = clean.step(a_c)
        obs_n, _, term_n, trunc_n, info_n = noisy.step(a_n)
        assert not (term_c or trunc_c or term_n or trunc_n)
    pytest.fail(f"{name}: the same action with and without sensor noise for 5 steps (does it read the truth?)")


def measured_truth(info: dict):
    """The truth that ``info["measured"]`` measures: ``truth["state"]`` (the state the
    observation shows), plus Magnetorquer-v0's body-frame field."""
    truth = info[TRUTH]
    state = truth["state"]
    if isinstance(state, dict) and "magnetic_field_body_t" in info[MEASURED]:
        state = {**state, "magnetic_field_body_t": truth["magnetic_field_body_t"]}
    return state


@pytest.mark.parametrize("env_id", ENVS)
def test_measured_equals_the_truth_with_sensors_off(env_id):
    env = gym.make(env_id)
    _, info = env.reset(seed=0)
    assert same(info[MEASURED], measured_truth(info))
    for _ in range(3):
        _, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        assert same(info[MEASURED], measured_truth(info))


class Spy:
    """A zero policy that records every info it is handed."""

    name = "spy"

    def __init__(self, env, action=None) -> None:
        self.action = np.zeros(env.action_space.shape, dtype=np.float32) if action is None else action
        self.infos: list[dict] = []

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs, info):
        self.infos.append(info)
        return self.action

    def check(self) -> None:
        assert self.infos
        for info in self.infos:
            assert TRUTH not in info and MEASURED in info


SHORT = {
    RW: {"episode_duration_s": 0.5},
    AB: {"episode_duration_s": 0.1},
    MT: {"episode_duration_s": 0.5},
    FS: {"episode_duration_s": 0.5},
    LS: {"episode_steps": 5},
}


@pytest.mark.parametrize("env_id", ENVS)
def test_rollout_hands_the_policy_no_truth(env_id):
    env = gym.make(env_id, **SHORT[env_id])
    spy = Spy(env)
    rollout(env, spy, seed=0)
    spy.check()


def test_record_episode_and_evaluate_hand_the_policy_no_truth():
    env = gym.make(RW, **SHORT[RW])
    spy = Spy(env)
    trace = record_episode(env, spy, seed=0)
    spy.check()
    assert len(spy.infos) == trace.steps
    spies: list[Spy] = []

    def factory(e):
        spies.append(Spy(e))
        return spies[-1]

    evaluate(RW, {"spy": factory}, [Scenario("short", env_kwargs=SHORT[RW])], seeds=(0,))
    spies[0].check()


def test_run_traced_hands_the_policy_no_truth():
    env = gym.make(MT, **SHORT[MT])
    spy = Spy(env)
    run_traced(env, spy, seed=0)
    spy.check()


def test_ga_episode_hands_the_pid_no_truth():
    env = gym.make(AB, **SHORT[AB]).unwrapped
    spy = Spy(env)
    pid_episode(env, spy, seed=0)
    spy.check()


@pytest.mark.parametrize("env_id", [MT, FS, LS])
def test_campaign_episodes_hand_the_policy_no_truth(env_id):
    env = gym.make(env_id, **SHORT[env_id])
    spy = Spy(env)
    job = {"key": {"seed": 0}, "options": {}, "metrics": {}, "env_kwargs": {}, "success_error_deg": 2.0}
    row = episode._generic_metrics(env, spy, job)
    spy.check()
    assert row["steps"] == len(spy.infos)
