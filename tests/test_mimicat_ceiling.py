"""analyses/mimicat_ceiling.py's pose surgery: 6D rotations and the return leg with lost bones changed,
against hand-computed transforms."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from mimicbench.geometry.kinematics import array_to_transforms
from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_to_matrix

_spec = importlib.util.spec_from_file_location("mimicat_ceiling",
                                               Path(__file__).resolve().parents[1] / "analyses" / "mimicat_ceiling.py")
ceiling = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ceiling)


def _quat_close(a, b, tol=1e-9):
    return np.allclose(a, b, atol=tol) or np.allclose(a, -b, atol=tol)


def test_6d_round_trip_and_columns():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    x = ceiling.rot6d(q)
    m = quat_to_matrix(q)
    assert np.allclose(x[:, :3], m[:, :, 0], atol=1e-12) and np.allclose(x[:, 3:], m[:, :, 1], atol=1e-12)
    back = ceiling.quat_from_6d(x)
    assert all(_quat_close(a, b) for a, b in zip(back, q))
    # a perturbed 6D vector still gives a rotation: Gram-Schmidt of (2 e_x, e_x + e_y) is the identity
    assert _quat_close(ceiling.quat_from_6d(np.array([2.0, 0, 0, 1, 1, 0])), np.array([1.0, 0, 0, 0]))


def _chain():
    """Root at the origin, bone 1 at (0, 1, 0), bone 2 at (0, 2, 0), bone 3 at (0, 3, 0)."""
    rest = np.array([[0.0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0]])
    return rest, np.array([-1, 0, 1, 2])


def test_recompose_unchanged_keeps_the_pose():
    rest, parents = _chain()
    z = quat_from_axis_angle(np.array([0.0, 0, 1]), np.pi / 2)
    q = np.array([[1.0, 0, 0, 0], z, z, z])
    t = np.array([[0.5, 0, 0], [0.5, 1, 0], [-0.5, 1, 0], [-1.5, 1, 0]])  # root moved by x 0.5, bone 1 turned
    out = ceiling.recompose(q, t, rest, parents, np.zeros(4, bool), np.tile([1.0, 0, 0, 0], (4, 1)))
    q2, t2 = array_to_transforms(out)
    assert all(_quat_close(a, b) for a, b in zip(q2, q))
    assert np.allclose(t2, t, atol=1e-12)


def test_recompose_changes_a_lost_bone_and_its_descendants_follow():
    rest, parents = _chain()
    ident = np.tile([1.0, 0, 0, 0], (4, 1))
    t = rest.copy()  # the returned pose: at rest (the lost bone 1 took its parent's rotation)
    z = quat_from_axis_angle(np.array([0.0, 0, 1]), np.pi / 2)
    local = ident.copy()
    local[1] = z
    change = np.array([False, True, False, False])
    q2, t2 = array_to_transforms(ceiling.recompose(ident, t, rest, parents, change, local))
    # bone 1 turns 90 degrees about z at (0, 1, 0): its child, bone 2, swings to (-1, 1, 0); bones 2
    # and 3 keep their returned global rotations (identity), so bone 3 sits one unit up from bone 2
    assert _quat_close(q2[1], z) and _quat_close(q2[2], ident[2]) and _quat_close(q2[3], ident[3])
    assert np.allclose(t2, [[0, 0, 0], [0, 1, 0], [-1, 1, 0], [-1, 2, 0]], atol=1e-12)
    # with a local translation given too, the changed bone moves by it (parent's frame: the root's, identity)
    moved = np.zeros((4, 3))
    moved[1] = [0.0, 0.0, 0.25]
    _, t3 = array_to_transforms(ceiling.recompose(ident, t, rest, parents, change, local, moved))
    assert np.allclose(t3, [[0, 0, 0], [0, 1, 0.25], [-1, 1, 0.25], [-1, 2, 0.25]], atol=1e-12)
