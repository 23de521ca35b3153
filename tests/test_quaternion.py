import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimicbench.geometry.quaternion import (
    matrix_to_quat, quat_angle, quat_apply, quat_canonical, quat_from_axis_angle, quat_inverse,
    quat_multiply, quat_normalize, quat_slerp, quat_to_matrix,
)


def random_quats(n, seed=0):
    return quat_normalize(np.random.default_rng(seed).normal(size=(n, 4)))


def scipy_matrix(q):
    # scipy uses (x, y, z, w)
    return Rotation.from_quat(np.roll(q, -1, axis=-1)).as_matrix()


def test_to_matrix_matches_scipy_and_is_orthonormal():
    q = random_quats(200)
    m = quat_to_matrix(q)
    np.testing.assert_allclose(m, scipy_matrix(q), atol=1e-12)
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)


def test_matrix_round_trip_including_near_180_degrees():
    q = random_quats(500, seed=1)
    near_pi = quat_from_axis_angle(np.random.default_rng(2).normal(size=(50, 3)), np.pi - 1e-7)
    q = np.concatenate([q, near_pi, [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]])
    back = matrix_to_quat(quat_to_matrix(q))
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), 1.0, atol=1e-12)
    assert quat_angle(back, q).max() < 1e-6


def test_product_composes_rotations_and_inverse_undoes():
    a, b = random_quats(100, 3), random_quats(100, 4)
    np.testing.assert_allclose(quat_to_matrix(quat_multiply(a, b)), quat_to_matrix(a) @ quat_to_matrix(b), atol=1e-12)
    ident = quat_multiply(a, quat_inverse(a))
    np.testing.assert_allclose(quat_canonical(ident), np.tile([1.0, 0, 0, 0], (100, 1)), atol=1e-12)
    v = np.random.default_rng(5).normal(size=(100, 3))
    np.testing.assert_allclose(quat_apply(a, v), np.einsum("nij,nj->ni", scipy_matrix(a), v), atol=1e-12)


def test_slerp_endpoints_midpoint_and_constant_speed():
    a, b = random_quats(50, 6), random_quats(50, 7)
    np.testing.assert_allclose(quat_angle(quat_slerp(a, b, 0.0), a), 0, atol=1e-6)
    np.testing.assert_allclose(quat_angle(quat_slerp(a, b, 1.0), b), 0, atol=1e-6)
    total = quat_angle(a, b)
    for t in (0.25, 0.5, 0.8):
        mid = quat_slerp(a, b, t)
        np.testing.assert_allclose(quat_angle(a, mid), t * total, atol=1e-6)
        np.testing.assert_allclose(quat_angle(mid, b), (1 - t) * total, atol=1e-6)


def test_validation_message_names_expected_shape():
    with pytest.raises(ValueError, match=r"expected shape \(\.\.\., 4\)"):
        quat_to_matrix(np.zeros((3, 3)))
