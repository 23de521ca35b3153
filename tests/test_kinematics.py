import numpy as np
import pytest

from mimicbench.geometry.kinematics import (
    array_to_transforms, forward_kinematics, local_from_global, rest_transforms, subtree_sums, transforms_to_array,
)
from mimicbench.geometry.quaternion import quat_angle, quat_normalize, quat_to_matrix


def naive_fk(local_q, rest, parents, root_pos):
    """Per-joint loop with 4x4 matrices: world_k = world_parent * [L_k | offset]."""
    k = len(parents)
    rots, pos = [None] * k, [None] * k
    for j in range(k):
        lr = quat_to_matrix(local_q[j])
        if parents[j] < 0:
            rots[j], pos[j] = lr, root_pos[j]
        else:
            p = parents[j]
            rots[j] = rots[p] @ lr
            pos[j] = pos[p] + rots[p] @ (rest[j] - rest[p])
    return np.array(rots), np.array(pos)


def random_skeleton(k, seed):
    rng = np.random.default_rng(seed)
    parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, k)])
    rest = rng.normal(size=(k, 3))
    return parents, rest


def test_fk_matches_naive_loop_over_frames():
    parents, rest = random_skeleton(30, 0)
    rng = np.random.default_rng(1)
    local = quat_normalize(rng.normal(size=(6, 30, 4)))
    root = rng.normal(size=(6, 30, 3))
    g_rot, g_pos = forward_kinematics(local, rest, parents, root)
    for f in range(6):
        r, p = naive_fk(local[f], rest, parents, root[f])
        np.testing.assert_allclose(quat_to_matrix(g_rot[f]), r, atol=1e-10)
        np.testing.assert_allclose(g_pos[f], p, atol=1e-10)


def test_identity_pose_is_rest_and_local_global_round_trip():
    parents, rest = random_skeleton(12, 2)
    ident = np.tile([1.0, 0, 0, 0], (12, 1))
    g_rot, g_pos = forward_kinematics(ident, rest, parents)
    np.testing.assert_allclose(g_pos, rest, atol=1e-12)
    np.testing.assert_allclose(rest_transforms(rest), transforms_to_array(ident, rest))
    local = quat_normalize(np.random.default_rng(3).normal(size=(4, 12, 4)))
    g_rot, _ = forward_kinematics(local, rest, parents)
    assert quat_angle(local_from_global(g_rot, parents), local).max() < 1e-6


def test_transform_array_round_trip_and_unit_quaternions():
    q = quat_normalize(np.random.default_rng(4).normal(size=(3, 5, 4)))
    t = np.random.default_rng(5).normal(size=(3, 5, 3))
    arr = transforms_to_array(q, t)
    assert arr.shape == (3, 5, 7) and arr.dtype == np.float32
    q2, t2 = array_to_transforms(arr)
    np.testing.assert_allclose(np.linalg.norm(q2, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(q2, q, atol=1e-6)
    np.testing.assert_allclose(t2, t, atol=1e-6)


def test_parents_must_be_topological():
    with pytest.raises(ValueError, match="topological"):
        forward_kinematics(np.tile([1.0, 0, 0, 0], (3, 1)), np.zeros((3, 3)), np.array([-1, 2, 0]))


def test_subtree_sums_by_hand():
    # 0 -> 1 -> 2, 0 -> 3, and a second root 4 -> 5
    parents = np.array([-1, 0, 1, 0, -1, 4])
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    np.testing.assert_allclose(subtree_sums(values, parents), [10.0, 5.0, 3.0, 4.0, 11.0, 6.0])
