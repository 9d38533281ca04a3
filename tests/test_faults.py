"""Every actuator fault reaches the plant exactly as specified, from its onset on and not before."""

import gymnasium as gym
import numpy as np
import pytest

RW = "attitude_envs/ReactionWheel-v0"
MAX = 0.5  # pyramid-4wheel wheel torque limit, N·m
CMD = np.array([0.4, -0.6, 0.2, 0.8])  # normalized; physical = CMD * MAX


def applied_history(fault, steps=30, action=CMD, **kwargs):
    env = gym.make(RW, faults=[fault], max_wheel_speed_rad_s=np.inf, **kwargs).unwrapped
    env.reset(seed=0)
    rows = []
    for _ in range(steps):
        t = env._t
        _, _, _, _, info = env.step(action)
        rows.append((t, info["truth"]["applied"].copy(), info["truth"]["faults"]))
    return rows


@pytest.mark.parametrize(
    "fault,expected",
    [
        ({"kind": "loss_of_effectiveness", "index": 2, "value": 0.3}, lambda u, t: 0.7 * u),
        ({"kind": "effectiveness", "index": 2, "value": 0.6}, lambda u, t: 0.6 * u),
        ({"kind": "bias", "index": 2, "value": 0.05}, lambda u, t: u + 0.05),
        ({"kind": "drift", "index": 2, "value": 0.01}, lambda u, t: u + 0.01 * (t - 1.0)),
        ({"kind": "stuck", "index": 2, "value": -0.2}, lambda u, t: -0.2),
        ({"kind": "outage", "index": 2}, lambda u, t: 0.0),
        ({"kind": "saturation", "index": 2, "value": 0.1}, lambda u, t: np.clip(u, -0.05, 0.05)),
    ],
)
def test_fault_changes_applied_torque_exactly_from_onset(fault, expected):
    rows = applied_history(dict(fault, onset_s=1.0))
    u = CMD * MAX
    for t, applied, faults in rows:
        others = np.delete(applied, 2)
        assert np.allclose(others, np.delete(u, 2), rtol=0, atol=1e-15)  # other wheels untouched
        # info["faults"] is reported at the end of the step (info["time_s"] = t + 0.1)
        assert faults[0]["active"] == (t + 0.1 >= 1.0 - 1e-9)
        if t < 1.0 - 1e-9:
            assert applied[2] == pytest.approx(u[2], abs=1e-15)
        else:
            assert applied[2] == pytest.approx(expected(u[2], t), abs=1e-12)


def test_stuck_without_value_holds_the_command_at_onset():
    env = gym.make(RW, faults=[{"kind": "stuck", "index": 0, "onset_s": 0.5}]).unwrapped
    env.reset(seed=0)
    commands = np.linspace(-1, 1, 12)
    applied = [env.step(np.array([c, 0, 0, 0]))[4]["truth"]["applied"][0] for c in commands]
    assert np.allclose(applied[:5], commands[:5] * MAX)
    assert np.allclose(applied[5:], commands[5] * MAX)


def test_duration_gives_recovery():
    rows = applied_history({"kind": "outage", "index": 1, "onset_s": 0.5, "duration_s": 1.0})
    for t, applied, _ in rows:
        broken = 0.5 - 1e-9 <= t < 1.5 - 1e-9
        assert applied[1] == pytest.approx(0.0 if broken else CMD[1] * MAX)


def test_intermittent_switches_on_and_off_and_is_seeded():
    fault = {"kind": "intermittent", "index": 3, "onset_s": 0.0, "mean_on_s": 0.5, "mean_off_s": 0.5}
    a = np.array([row[1][3] for row in applied_history(fault, steps=100)])
    b = np.array([row[1][3] for row in applied_history(fault, steps=100)])
    assert np.array_equal(a, b)
    assert set(np.round(a, 12)) == {0.0, round(CMD[3] * MAX, 12)}
    assert 5 <= np.count_nonzero(np.diff(a)) <= 60  # switches, about once per 0.5 s over 10 s


def test_paper_magnetorquer_style_schedule_and_all_index():
    fault = {"kind": "effectiveness", "index": "all", "schedule": [[0, 1.0], [1.0, 1.0], [1.0001, 0.5]]}
    rows = applied_history(fault, steps=20)
    assert np.allclose(rows[5][1], CMD * MAX)
    assert np.allclose(rows[15][1], 0.5 * CMD * MAX)
    assert len(rows[0][2]) == 4


def test_random_draws_follow_the_seed_and_the_ranges():
    fault = {
        "kind": "loss_of_effectiveness",
        "index": "random",
        "value": {"uniform": [0.2, 0.8]},
        "onset_s": {"uniform": [10, 40]},
    }
    env = gym.make(RW, faults=[fault]).unwrapped
    draws = []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        f = info["truth"]["faults"][0]
        assert 0.2 <= f["value"] <= 0.8 and 10 <= f["onset_s"] <= 40 and f["index"] in range(4)
        draws.append((f["index"], f["value"], f["onset_s"]))
    assert len(set(draws)) == 20
    expected = {"kind": "loss_of_effectiveness", "target": "actuator", "duration_s": None, "active": False}
    expected.update(zip(["index", "value", "onset_s"], draws[3], strict=True))
    assert env.reset(seed=3)[1]["truth"]["faults"][0] == expected


def test_faults_given_per_episode_replace_the_constructed_ones():
    env = gym.make(RW, faults=[{"kind": "outage", "index": 0}]).unwrapped
    _, info = env.reset(seed=0, options={"faults": [{"kind": "bias", "index": 1, "value": 0.01}]})
    assert [f["kind"] for f in info["truth"]["faults"]] == ["bias"]
    assert env.step(np.zeros(4))[4]["truth"]["applied"][1] == pytest.approx(0.01)
    _, info = env.reset(seed=0)
    assert [f["kind"] for f in info["truth"]["faults"]] == ["outage"]


def test_faults_reach_the_linear_system_too():
    env = gym.make(
        "attitude_envs/LinearSystem-v0",
        faults=[{"kind": "loss_of_effectiveness", "index": 0, "value": 0.5, "onset_s": 0.05}],
    )
    env.reset(seed=0)
    applied = [env.step(np.array([0.5, 0.5, 0.5]))[4]["truth"]["applied"] for _ in range(10)]
    assert np.allclose(applied[4], [1.0, 1.0, 1.0]) and np.allclose(applied[5], [0.5, 1.0, 1.0])


@pytest.mark.parametrize(
    "fault,match",
    [
        ({"kind": "melted", "index": 0}, r"faults\[0\].kind must be one of"),
        ({"kind": "outage", "index": 4}, r"faults\[0\].index must be an integer in \[0, 3\]"),
        ({"kind": "loss_of_effectiveness", "index": 0, "value": 1.5}, r"faults\[0\].value must be in \[0.0, 1.0\]"),
        ({"kind": "loss_of_effectiveness", "index": 0}, r"faults\[0\].value is required"),
        ({"kind": "bias", "index": 0, "value": 0.1, "onset_s": -1}, r"faults\[0\].onset_s must be in \[0.0, inf\]"),
        ({"kind": "bias", "index": 0, "value": {"uniform": [1, 0]}}, "low <= high"),
        ({"kind": "bias", "index": 0, "value": 0.1, "target": "thruster"}, r"faults\[0\].target must be one of"),
        ({"kind": "bias", "index": 0, "value": 0.1, "target": "sensor"}, r"faults\[0\].sensor must be one of"),
        ({"kind": "outage", "index": 0, "severity": 1}, "unknown keys"),
        ({"kind": "effectiveness", "index": 0, "schedule": [[0, 1.2]]}, "effectiveness values must be in"),
    ],
)
def test_bad_fault_configs_name_the_field(fault, match):
    with pytest.raises(ValueError, match=match):
        gym.make(RW, faults=[fault])


def test_faults_reach_the_fuel_slosh_actuators():
    fault = {"kind": "stuck", "index": 0, "value": 0.1, "onset_s": 0.2}
    # a wide pitch-rate limit: the half-scale moment would end the episode on step 2 (0.5 rad/s)
    env = gym.make("attitude_envs/FuelSlosh-v0", faults=[fault], max_pitch_rate_rad_s=100.0)
    env.reset(seed=0)
    steps = [env.step(np.array([0.5, 0.5])) for _ in range(4)]
    assert not any(s[2] or s[3] for s in steps)  # one episode throughout
    applied = [s[4]["truth"]["applied"] for s in steps]
    assert applied[1][0] == pytest.approx(0.5 * np.radians(30.0)) and applied[2][0] == pytest.approx(0.1)
    assert applied[3][1] == pytest.approx(1000.0)  # the moment actuator is untouched
