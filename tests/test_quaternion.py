import numpy as np
from scipy.spatial.transform import Rotation

from attitude_envs import quaternion


def test_multiply_matches_scipy(rng):
    for _ in range(20):
        p, q = Rotation.random(2, random_state=int(rng.integers(1 << 30)))
        ours = quaternion.multiply(p.as_quat(), q.as_quat())
        ref = (p * q).as_quat()
        assert np.allclose(ours * np.sign(ours[3]), ref * np.sign(ref[3]), atol=1e-14)


def test_to_matrix_and_euler_match_scipy(rng):
    q = Rotation.random(random_state=3).as_quat()
    assert np.allclose(quaternion.to_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-14)
    ours = quaternion.from_euler_321_deg(20.0, -30.0, -40.0)
    ref = Rotation.from_euler("ZYX", [-40.0, -30.0, 20.0], degrees=True).as_quat()
    assert np.allclose(ours, ref, atol=1e-14)
    # the feedback-linearization paper's Table 1, maneuver 1 target
    assert np.allclose(ours, [0.07044, -0.29688, -0.28311, 0.90926], atol=1e-5)
    assert np.allclose(quaternion.to_euler_321_deg(ours), [20.0, -30.0, -40.0], atol=1e-10)


def test_error_quaternion_convention():
    target = quaternion.from_axis_angle([1, 0, 0], 0.2)
    assert np.allclose(quaternion.error(target, target), [0, 0, 0, 1])
    # body rotated past the target by δ about x: q_e,vec ≈ +δ/2 · x, w ≥ 0 always
    q = quaternion.multiply(target, quaternion.from_axis_angle([1, 0, 0], 0.01))
    assert np.allclose(quaternion.error(q, target), [np.sin(0.005), 0, 0, np.cos(0.005)], atol=1e-15)
    assert quaternion.error(-q, target)[3] > 0
    assert np.isclose(quaternion.error_angle_rad(q, target), 0.01)


def test_random_within_angle_respects_bound(rng):
    for _ in range(200):
        q = quaternion.random_within_angle(rng, 30.0)
        assert np.isclose(np.linalg.norm(q), 1.0)
        assert quaternion.error_angle_rad(q, np.array([0, 0, 0, 1.0])) <= np.radians(30.0) + 1e-12
