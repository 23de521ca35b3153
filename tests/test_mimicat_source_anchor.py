"""baselines/mimicat/source_anchor.py: the source keypoints the structured initialisation reads
translations from, on hand-made rigs whose root and body own no vertices (the shape of the shared
RobotExpressive and Quaternius dinosaur rigs), against hand-computed poses."""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.baselines.mimicat.initialisation import local_translations_torch
from mimicbench.baselines.mimicat.method import Mimicat
from mimicbench.baselines.mimicat.source_anchor import anchor_source_keypoints
from mimicbench.baselines.posing import source_pose
from mimicbench.benchmark.request import Rig, TransferRequest
from mimicbench.geometry.kinematics import subtree_sums, transforms_to_array
from mimicbench.geometry.quaternion import quat_apply, quat_from_axis_angle, quat_multiply
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.weights import SparseWeights

X, Z = np.array([1.0, 0, 0]), np.array([0.0, 0, 1])
IDENTITY = np.array([1.0, 0, 0, 0])


def _locals(q, t, rig) -> np.ndarray:
    """(K, 3) local translations as the structured initialisation reads them."""
    rest = torch.tensor(np.array(rig.keypoints, np.float64))
    return local_translations_torch(torch.tensor(np.array(q)), torch.tensor(np.array(t)), rest, rig.parents).numpy()


def _rig() -> Rig:
    """root (0, 0, 0) -> Body (0, 1, 0) -> legs at (-0.5, 1, 0) and (0.5, 1, 0); root and Body own
    no vertices, each leg a rigidly bound tetrahedron."""
    kp = np.array([[0.0, 0, 0], [0, 1, 0], [-0.5, 1, 0], [0.5, 1, 0]], np.float32)
    tet = np.array([[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1], [-0.05, -0.05, -0.05]])
    verts = np.concatenate([kp[b] + tet for b in (2, 3)]).astype(np.float32)
    w = np.zeros((8, 4))
    w[:4, 2] = w[4:, 3] = 1
    faces = np.array([[0, 1, 2], [4, 5, 6]], np.int32)
    return Rig("toy", "quadruped", verts, faces, kp, np.array([-1, 0, 1, 1], np.int32), SparseWeights.from_dense(w),
               ("root", "Body", "Leg.L", "Leg.R"))


def _clip_pose(rig: Rig, d: np.ndarray, body_deg: float) -> TransferRequest:
    """The clip moves the weightless root by ``d`` and turns Body about x; every local
    translation of the true pose is zero."""
    q_body = quat_from_axis_angle(X, np.radians(body_deg))
    q_legs = [quat_multiply(q_body, quat_from_axis_angle(Z, np.radians(a))) for a in (5.0, -5.0)]
    q = np.stack([IDENTITY, q_body, *q_legs])
    kp = rig.keypoints.astype(np.float64)
    t = np.empty((4, 3))
    t[0] = kp[0] + d
    t[1] = t[0] + (kp[1] - kp[0])
    t[2:] = t[1] + quat_apply(q_body, kp[2:] - kp[1])
    verts = linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, transforms_to_array(q, t))
    return TransferRequest(rig, verts.astype(np.float32), rig, "toy")


def test_the_read_off_alone_reads_the_roots_motion_as_the_legs_stretch():
    """The defect: the weightless root stays at rest in the read-off, so the clip's displacement
    shows up as local translations of the legs (true value zero)."""
    rig = _rig()
    d = np.array([0.3, 0.0, 2.0])
    q, t = source_pose(_clip_pose(rig, d, 100.0))
    local = _locals(q, t, rig)
    assert np.allclose(t[0], 0.0, atol=1e-6)
    assert np.linalg.norm(local[2:], axis=1).min() > 0.9 * np.linalg.norm(d)


def test_anchoring_moves_the_root_and_leaves_no_stretch_under_a_weightless_parent():
    rig = _rig()
    d = np.array([0.3, 0.0, 2.0])
    request = _clip_pose(rig, d, 100.0)
    q, t = Mimicat()._source_pose(request)
    local = _locals(q, t, rig)
    # hand values: the root moved by d (both legs agree, equal weight), no bone translated locally
    assert np.allclose(t[0], d, atol=0.01 * np.linalg.norm(d))
    assert np.abs(local[1:]).max() < 1e-9
    # the legs stay where the mesh put them up to the read-off's error on Body's turn (0.2 degrees)
    q_read, t_read = source_pose(request)
    assert np.abs(t[2:] - t_read[2:]).max() < 0.01 * np.linalg.norm(d)
    assert np.allclose(q, q_read)


def test_the_root_takes_the_skin_weighted_mean_of_its_top_bones_hand_computed():
    """A root turned 90 degrees about z (completed), two weighted children with local
    translations l1 = (1, 0, 0) and l2 = (0, 0, 2) read in the root's frame, weights 3 and 1:
    the root moves by R (3 l1 + l2) / 4 = (0, 0.75, 0.5), the children carry nothing."""
    parents = np.array([-1, 0, 0])
    rest = np.array([[0.0, 0, 0], [0, 1, 0], [1, 0, 0]])
    r = quat_from_axis_angle(Z, np.pi / 2)
    q = np.stack([r, r, r])
    t = np.stack([np.zeros(3), quat_apply(r, rest[1] + [1, 0, 0]), quat_apply(r, rest[2] + [0, 0, 2])])
    out = anchor_source_keypoints(q, t, rest, parents, np.array([False, True, True]), np.array([4.0, 3.0, 1.0]))
    assert np.allclose(out[0], [0, 0.75, 0.5])
    assert np.allclose(out[1], out[0] + quat_apply(r, rest[1]))
    assert np.allclose(out[2], out[0] + quat_apply(r, rest[2]))


def test_a_rig_whose_bones_are_all_determined_is_unchanged_and_weights_sum_below():
    parents = np.array([-1, 0, 1, 1])
    rng = np.random.default_rng(0)
    q = rng.normal(size=(4, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    t, rest = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
    assert np.array_equal(anchor_source_keypoints(q, t, rest, parents, np.ones(4, bool), np.ones(4)), t)
    rig = _rig()
    assert np.allclose(subtree_sums(rig.weights.to_dense().sum(axis=0), rig.parents), [8, 8, 4, 4])
