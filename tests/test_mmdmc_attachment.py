"""Apparel skinning by chain attachment, f_c's bone inputs and its per-piece vote (MMDMC reference):
checked against hand-computed nearest bones and naive loops."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mmdmc.chain_attachment import attached_weights, chain_attachment
from mimicbench.baselines.mmdmc.data import prepare
from mimicbench.baselines.mmdmc.pipeline import apparel_probability, mesh_weights
from mimicbench.baselines.mmdmc.segmentation import ApparelSegmenter, segmenter_inputs

# body: 0 root (0,0,0) -> 1 (1,0,0) -> 2 leaf (1,1,0); apparel chain A: 3 (1,0,1) -> 4 (1,0,2), hanging
# from body bone 1; apparel chain B: 5 (0,-1,0) -> 6 (0,-2,0), hanging from the root 0
KEYPOINTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 0, 1], [1, 0, 2], [0, -1, 0], [0, -2, 0]], np.float64)
PARENTS = np.array([-1, 0, 1, 1, 3, 0, 5])
BODY = np.array([True, True, True, False, False, False, False])


def naive_attachment(v):
    """Per vertex: nearest apparel segment (3-4 or 5-6) by brute force, then its chain's body bone."""
    def seg_dist(p, a, b):
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        return np.linalg.norm(p - (a + t * (b - a)))
    out = []
    for p in v:
        da = seg_dist(p, KEYPOINTS[3], KEYPOINTS[4])
        db = seg_dist(p, KEYPOINTS[5], KEYPOINTS[6])
        out.append((1, da) if da < db else (0, db))  # body columns: bone 1 -> column 1, root -> column 0
    return out


def test_chain_attachment_matches_a_naive_loop():
    v = np.random.default_rng(0).uniform(-2, 2, (50, 3))
    columns, dist = chain_attachment(v, KEYPOINTS, PARENTS, BODY)
    expected = naive_attachment(v)
    assert columns.tolist() == [c for c, _ in expected]
    np.testing.assert_allclose(dist, [d for _, d in expected], rtol=1e-5)


def test_chain_attachment_by_hand_and_without_apparel_bones():
    columns, dist = chain_attachment(np.array([[1.0, 0.2, 1.5], [0.3, -1.5, 0.0]]), KEYPOINTS, PARENTS, BODY)
    assert columns.tolist() == [1, 0]
    np.testing.assert_allclose(dist, [0.2, 0.3], rtol=1e-6)
    columns, dist = chain_attachment(np.zeros((2, 3)), KEYPOINTS[:3], PARENTS[:3], BODY[:3])
    assert columns.tolist() == [-1, -1] and np.isinf(dist).all()
    # a chain hanging from no body bone gives no attachment
    columns, _ = chain_attachment(np.zeros((1, 3)), np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0.0]]),
                                  np.array([-1, -1, 1]), np.array([True, False, False]))
    assert columns.tolist() == [-1]


def test_attached_weights_move_only_masked_vertices_with_an_attachment():
    w = np.full((3, 3), 1 / 3)
    out = attached_weights(w, np.array([True, True, False]), np.array([2, -1, 0]))
    np.testing.assert_array_equal(out[0], [0, 0, 1])
    np.testing.assert_array_equal(out[1:], w[1:])  # no attachment / not masked: unchanged
    np.testing.assert_array_equal(w, 1 / 3)  # the input is left alone


def character():
    v = np.array([[0.5, 0.1, 0], [1.0, 0.5, 0.1], [1.05, 0.0, 1.5], [0.1, -1.5, 0.0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    return prepare("toy", v, faces, KEYPOINTS, PARENTS, BODY)


class UniformSkinning(torch.nn.Module):
    """A stand-in f_s giving every vertex equal weights on the 3 body bones."""

    def __init__(self):
        super().__init__()
        self.p = torch.nn.Parameter(torch.zeros(1))

    def forward(self, points, joints, geo, bone):
        return torch.full(geo.shape, 1 / 3) + self.p * 0


def test_mesh_weights_attach_the_masked_vertices_then_smooth():
    prep = character()
    body = UniformSkinning()
    mask = np.array([False, False, True, True])
    np.testing.assert_allclose(mesh_weights(body, prep, mask, "fs").numpy(), 1 / 3)
    attached = mesh_weights(body, prep, mask, "attachment").numpy()
    np.testing.assert_allclose(attached[:2], 1 / 3)
    np.testing.assert_array_equal(attached[2:], [[0, 1, 0], [1, 0, 0]])
    np.testing.assert_allclose(mesh_weights(body, prep, None, "attachment").numpy(), 1 / 3)  # no mask: f_s's
    # smoothing comes after the attachment: one step by hand on the faces (0,1,2), (0,2,3)
    nb = {0: [1, 2, 3], 1: [0, 2], 2: [0, 1, 3], 3: [0, 2]}
    expected = np.array([0.5 * (attached[i] + attached[nb[i]].mean(0)) for i in range(4)])
    np.testing.assert_allclose(mesh_weights(body, prep, mask, "attachment", 1).numpy(), expected, rtol=1e-6)
    with pytest.raises(ValueError, match="expected 'fs' or 'attachment'"):
        mesh_weights(body, prep, mask, "nearest")


def test_segmenter_bone_inputs_by_hand():
    prep = character()
    x = segmenter_inputs(prep, 5)
    assert x.shape == (4, 5) and x.dtype == np.float32
    np.testing.assert_allclose(x[:, :3], prep.rest_norm)
    # the mesh's box, grown by 0.1 x its largest extent 2.0: x -0.1..1.25, y -1.7..0.7, z -0.2..1.7, leaves
    # joints 2 (1,1,0), 4 (1,0,2) and 6 (0,-2,0) out, so bones 1, 3 and 5 end no segment there.
    # vertex 2 (1.05, 0, 1.5): nearest body point the joint (1,0,0), hypot(0.05, 1.5) away; nearest apparel
    # point joint 3 (1,0,1) or 4 (1,0,2), hypot(0.05, 0.5) away (0.05 with the segment 3-4); divided by the
    # height (the Y extent, 2.0)
    np.testing.assert_allclose(x[2, 3:], np.minimum([np.hypot(0.05, 1.5) / 2.0, np.hypot(0.05, 0.5) / 2.0], 1.0),
                               rtol=1e-5)
    assert (x[:, 3:] <= 1).all()
    np.testing.assert_array_equal(segmenter_inputs(prep, 3), prep.rest_norm)
    with pytest.raises(ValueError, match="input channels"):
        segmenter_inputs(prep, 4)
    seg = ApparelSegmenter(8, 5)
    assert seg(torch.as_tensor(x)[None]).shape == (1, 4)
    with pytest.raises(ValueError, match=r"expected \(B, N, 5\)"):
        seg(torch.zeros(1, 4, 3))


class FixedLogits(torch.nn.Module):
    """A stand-in f_c answering given logits (N,), whatever its input."""

    def __init__(self, logits):
        super().__init__()
        self.logits = torch.nn.Parameter(torch.as_tensor(logits, dtype=torch.float32))
        self.channels = 3

    def forward(self, x):
        return self.logits[None].expand(len(x), -1)


def test_piece_vote_averages_the_probability_over_each_mesh_piece():
    # two pieces: triangles (0,1,2) and (3,4,5); vertex 6 in no face is a piece of its own
    v = np.random.default_rng(1).uniform(0, 1, (7, 3)).astype(np.float32)
    faces = np.array([[0, 1, 2], [3, 4, 5]], np.int32)
    prep = prepare("pieces", v, faces, KEYPOINTS, PARENTS, BODY)
    logits = np.array([3.0, -1.0, 0.5, -4.0, 2.0, -2.0, 1.0])
    seg = FixedLogits(logits)
    p = 1 / (1 + np.exp(-logits))
    np.testing.assert_allclose(apparel_probability(seg, prep), p, rtol=1e-6)
    voted = apparel_probability(seg, prep, by_piece=True)
    expected = np.empty(7)
    for piece in ([0, 1, 2], [3, 4, 5], [6]):
        expected[piece] = np.mean(p[piece])
    np.testing.assert_allclose(voted, expected, rtol=1e-6)
    assert (voted > 0.5).tolist() == [True] * 3 + [False] * 3 + [True]
