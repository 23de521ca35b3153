import numpy as np
from scipy.spatial.transform import Rotation

from mimicbench.geometry.quaternion import quat_angle, quat_from_axis_angle, quat_normalize
from mimicbench.geometry.rotation_average import weighted_quaternion_average


def test_average_of_q_and_minus_q_is_q():
    q = quat_normalize(np.random.default_rng(0).normal(size=(20, 4)))
    for qi in q:
        avg = weighted_quaternion_average(np.stack([qi, -qi, qi]), np.array([[0.2], [0.5], [0.3]]))
        assert quat_angle(avg[0], qi) < 1e-6


def test_matches_naive_eigen_loop_and_scipy_mean():
    rng = np.random.default_rng(1)
    q = quat_normalize(rng.normal(size=(7, 4)))
    m = rng.random((7, 5))
    fast = weighted_quaternion_average(q, m)
    for j in range(5):
        a = sum(m[i, j] * np.outer(q[i], q[i]) for i in range(7))
        vals, vecs = np.linalg.eigh(a)
        naive = vecs[:, np.argmax(vals)]
        assert quat_angle(fast[j], naive) < 1e-6
        ref = Rotation.from_quat(np.roll(q, -1, axis=1)).mean(weights=m[:, j]).as_quat()
        assert quat_angle(fast[j], np.roll(ref, 1)) < 1e-6


def test_concentrated_rotations_average_near_their_centre_and_zero_column_is_identity():
    axis = np.array([0.0, 1.0, 0.0])
    q = quat_from_axis_angle(np.tile(axis, (3, 1)), np.array([0.1, 0.2, 0.3]))
    avg = weighted_quaternion_average(q, np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]))
    assert quat_angle(avg[0], quat_from_axis_angle(axis, 0.2)) < 1e-3
    np.testing.assert_allclose(avg[1], [1, 0, 0, 0])
