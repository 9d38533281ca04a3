"""ConstrainedSlew-v0, its constraints (g ≤ 0 satisfied) and the Safety-Gymnasium 6-tuple."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from attitude_envs import quaternion
from attitude_envs.constraints import BodyRateLimit, KeepOutCone, WheelSpeedLimit
from attitude_envs.envs.constrained_slew import CONE_FEATURES, MAX_CONES, ConstrainedSlewEnv
from attitude_envs.wrappers.safety import SafetyGymnasiumWrapper

Z = np.array([0.0, 0.0, 1.0])
X = np.array([1.0, 0.0, 0.0])


def about_x(angle_deg: float) -> np.ndarray:
    return quaternion.from_axis_angle(X, math.radians(angle_deg))


@pytest.fixture(scope="module")
def env():
    e = ConstrainedSlewEnv()
    yield e
    e.close()


def test_keep_out_cone_sign_and_margin():
    # body z rotated 90° about x points along inertial −y (to_matrix: body to inertial)
    assert np.allclose(quaternion.to_matrix(about_x(90.0)) @ Z, [0.0, -1.0, 0.0])
    cone = KeepOutCone(Z, [0.0, -1.0, 0.0], 30.0, name="sun")
    inside, outside = about_x(80.0), about_x(45.0)
    assert cone.value(inside) > 0.0 and cone.violated(inside)
    assert cone.value(outside) < 0.0 and not cone.violated(outside)
    # angle between the boresight and the direction: 10° and 45°; margin = angle − 30°
    assert cone.margin_deg(inside) == pytest.approx(-20.0, abs=1e-9)
    assert cone.margin_deg(outside) == pytest.approx(15.0, abs=1e-9)
    assert cone.value(about_x(90.0)) == pytest.approx(1.0 - math.cos(math.radians(30.0)), abs=1e-12)
    # a full state row and info's mapping give the same value
    row = np.concatenate([inside, [0.1, 0.0, 0.0], np.zeros(4)])
    mapping = {"attitude": inside, "rate_rad_s": np.zeros(3), "wheel_speed_rad_s": np.zeros(4)}
    assert cone.value(row) == cone.value(mapping) == cone.value(inside)
    with pytest.raises(ValueError, match="half_angle_deg"):
        KeepOutCone(Z, X, 95.0)
    with pytest.raises(ValueError, match="body_axis"):
        KeepOutCone([1.0, 1.0, 0.0], X, 30.0)


def test_rate_and_wheel_limits_sign():
    row = np.concatenate([[0.0, 0.0, 0.0, 1.0], [0.02, -0.06, 0.0], [100.0, -300.0, 0.0, 50.0]])
    assert BodyRateLimit(0.05).value(row) == pytest.approx(0.01)
    assert BodyRateLimit(0.1).value(row) == pytest.approx(-0.04)
    assert WheelSpeedLimit(250.0).value(row) == pytest.approx(50.0)
    assert np.allclose(WheelSpeedLimit(250.0, per_wheel=True).value(row), [-150.0, 50.0, -250.0, -200.0])
    with pytest.raises(ValueError, match="limit_rad_s"):
        BodyRateLimit(0.0)


def test_drawn_episodes_start_and_end_outside_the_cones(env):
    counts = set()
    for seed in range(25):
        obs, info = env.reset(seed=seed)
        q0, target = info["truth"]["state"]["attitude"], info["truth"]["state"]["target_attitude"]
        assert quaternion.error_angle_rad(q0, target) <= math.pi + 1e-12
        assert 1 <= len(env.cones) <= MAX_CONES
        counts.add(len(env.cones))
        for cone in env.cones:
            assert cone.margin_deg(q0) >= env.cone_margin_deg
            assert cone.margin_deg(target) >= env.cone_margin_deg
            assert info["constraints"][cone.name] < 0.0
        assert info["constraint_cost"] == 0.0 and info["violations"] == 0
        # the observation's cone block: directions in body axes, cos(half-angle), mask
        block = obs[-CONE_FEATURES * MAX_CONES :].reshape(MAX_CONES, CONE_FEATURES)
        for i, cone in enumerate(env.cones):
            assert np.allclose(block[i, :3], cone.direction_in_body(q0), atol=1e-6)
            assert block[i, 3] == pytest.approx(cone.cos_half_angle) and block[i, 4] == 1.0
        assert not block[len(env.cones) :].any()
    assert counts == {1, 2, 3}


def test_same_seed_same_cones(env):
    other = ConstrainedSlewEnv()
    a, _ = env.reset(seed=11)
    cones_a = [(c.name, c.inertial_direction.copy(), c.half_angle_deg) for c in env.cones]
    b, _ = other.reset(seed=11)
    assert np.array_equal(a, b)
    assert len(cones_a) == len(other.cones)
    for (name, d, angle), cone in zip(cones_a, other.cones, strict=True):
        assert name == cone.name and np.array_equal(d, cone.inertial_direction) and angle == cone.half_angle_deg
    other.reset(seed=12)
    assert not all(np.array_equal(d, c.inertial_direction) for (_, d, _), c in zip(cones_a, other.cones, strict=False))


def test_violations_counted_on_a_scripted_rotation_through_a_cone(env):
    # a free rotation about the principal x axis at 0.05 rad/s (below the 5 °/s limit): the
    # star tracker boresight (body z) sweeps through a 30° cone about inertial −y
    rate = 0.05
    obs, info = env.reset(
        seed=0,
        options={
            "attitude": about_x(0.0),
            "target_attitude": about_x(180.0),
            "rate_rad_s": [rate, 0.0, 0.0],
            "keep_out_cones": [{"inertial_direction": [0.0, -1.0, 0.0], "half_angle_deg": 30.0}],
        },
    )
    assert [c.name for c in env.cones] == ["keep_out_sun_star_tracker"]
    costs, expected = [], 0
    for k in range(1, 121):
        obs, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
        angle = math.degrees(rate * k * env.control_dt_s)  # rotation so far; boresight−cone angle |angle − 90|
        assert abs(abs(angle - 90.0) - 30.0) > 0.05  # no sample on the boundary
        inside = abs(angle - 90.0) < 30.0
        expected += inside
        assert info["constraint_cost"] == float(inside)
        assert info["constraint_margins_deg"]["keep_out_sun_star_tracker"] == pytest.approx(
            abs(angle - 90.0) - 30.0, abs=1e-6
        )
        assert (info["constraints"]["keep_out_sun_star_tracker"] > 0.0) == inside
        costs.append(info["constraint_cost"])
        assert not terminated and not truncated  # a violation ends nothing
    assert expected > 0
    assert info["violations"] == expected == sum(costs)
    assert info["violations_by_constraint"] == {"keep_out_sun_star_tracker": expected, "wheel_speed": 0, "body_rate": 0}


def test_rate_violation_counted(env):
    env.reset(seed=1, options={"rate_rad_s": [0.0, 0.0, 0.2], "keep_out_cones": []})
    _, _, _, _, info = env.step(np.zeros(3, dtype=np.float32))
    assert info["constraints"]["body_rate"] > 0.0
    assert info["constraint_cost"] == 1.0 and info["violations_by_constraint"]["body_rate"] == 1


def test_safety_gymnasium_six_tuple(env):
    wrapped = SafetyGymnasiumWrapper(env)
    obs, info = wrapped.reset(seed=3, options={"rate_rad_s": [0.2, 0.0, 0.0]})
    out = wrapped.step(wrapped.action_space.sample())
    assert len(out) == 6
    obs, reward, cost, terminated, truncated, info = out
    assert isinstance(cost, float) and cost == info["constraint_cost"] == 1.0
    assert reward == -info["cost"]
    assert obs.shape == wrapped.observation_space.shape
    with pytest.raises(ValueError, match="cost_key"):
        SafetyGymnasiumWrapper(env, cost_key="")


def test_check_env():
    check_env(ConstrainedSlewEnv(cone_count=3), skip_render_check=True)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"cone_count": 5}, "cone_count"),
        ({"sun_exclusion_deg": 95.0}, "sun_exclusion_deg"),
        ({"star_tracker_boresight": [1.0, 1.0, 0.0]}, "star_tracker_boresight"),
        ({"slew_angle_deg": 200.0}, "slew_angle_deg"),
        ({"body_rate_limit_rad_s": -1.0}, "body_rate_limit_rad_s"),
    ],
)
def test_bad_keywords_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ConstrainedSlewEnv(**kwargs)


def test_cbf_filter_removes_the_violations_of_the_eigenaxis_slew(env):
    pytest.importorskip("clarabel")
    from attitude_envs.info import policy_view
    from baselines.cbf import CBFSafetyFilterPolicy, EigenaxisSlewPolicy

    violations = {}
    for cls in (EigenaxisSlewPolicy, CBFSafetyFilterPolicy):
        policy = cls(env)
        obs, info = env.reset(seed=7)  # a 1-cone episode whose eigenaxis path crosses the Sun cone
        policy.reset()
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(policy.act(obs, policy_view(info)))
        assert info["truth"]["error_angle_deg"] < 2.0
        violations[cls.name] = info["violations"]
    assert violations["eigenaxis-slew"] > 0
    assert violations["cbf-eigenaxis-slew"] == 0
