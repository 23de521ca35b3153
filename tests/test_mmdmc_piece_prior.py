"""The piece prior on f_s's scores (baselines/mmdmc/piece_prior.py): skeleton links by hand, the
prior's weights against a naive loop of its rule, pieces that get none, the zoo's own weights as an
independent reference, and an untrained f_s with the piece prior equal to it."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh
from scipy.special import softmax

from mimicbench.baselines.mmdmc.body import PRIOR_TAU, BodySkinning
from mimicbench.baselines.mmdmc.bone_distance import bone_distances
from mimicbench.baselines.mmdmc.piece_prior import OUTSIDE, body_parents, piece_prior, skeleton_hops


def softmax_rows(scores: np.ndarray) -> np.ndarray:
    return softmax(scores, axis=1)


def test_skeleton_hops_by_hand():
    # body 0 -> 1 -> 2; apparel 3 under 1; body 4 under apparel 3 (links to 1); body 5 under 4
    parents = np.array([-1, 0, 1, 1, 3, 4])
    body = np.array([True, True, True, False, True, True])
    assert body_parents(parents, body).tolist() == [-1, 0, 1, 1, 3]  # columns, not bone indices
    hops = skeleton_hops(parents, body)  # rows and columns: bones 0, 1, 2, 4, 5
    np.testing.assert_array_equal(hops, [[0, 1, 2, 2, 3],
                                         [1, 0, 1, 1, 2],
                                         [2, 1, 0, 2, 3],
                                         [2, 1, 2, 0, 1],
                                         [3, 2, 3, 1, 0]])
    two_roots = skeleton_hops(np.array([-1, -1]), np.array([True, True]))
    assert np.isinf(two_roots[0, 1]) and two_roots[0, 0] == 0
    with pytest.raises(ValueError, match="one entry per bone"):
        skeleton_hops(parents, body[:3])


# a chain of 4 body bones along y, 0.25 apart (unit-height frame); two separate ball pieces
CHAIN = np.array([[0, 0.0, 0], [0, 0.25, 0], [0, 0.5, 0], [0, 0.75, 0]], np.float64)
CHAIN_PARENTS = np.array([-1, 0, 1, 2])


def ball(centre, radius=0.06):
    m = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    return np.asarray(m.vertices) + centre, np.asarray(m.faces)


def two_balls(upper=0.62):
    (v0, f0), (v1, f1) = ball([0.0, 0.1, 0.02]), ball([0.0, upper, 0.0])
    return np.r_[v0, v1], np.r_[f0, f1 + len(v0)]


def segment_distance(p, a, b):
    """Distance from point p to segment a-b, by the textbook projection."""
    p, a, b = (np.asarray(x, np.float64) for x in (p, a, b))
    t = min(max(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0), 1.0)
    return float(np.linalg.norm(p - (a + t * (b - a))))


@pytest.mark.parametrize("upper, anchor_up", [(0.62, 2), (0.86, 3)])
def test_prior_weights_follow_the_rule_of_a_naive_loop(upper, anchor_up):
    """The upper ball sits on bone 2 (0.5 -> 0.75), or beyond the leaf joint 3 (0.75): then it hangs
    from the leaf, whose segment runs from its joint to twice the ball's centre."""
    v, f = two_balls(upper)
    body = np.ones(4, bool)
    b = bone_distances(v, CHAIN, CHAIN_PARENTS, body).astype(np.float64)
    w = softmax_rows(piece_prior(v, f, b, CHAIN, CHAIN_PARENTS, body).astype(np.float64))
    neighbours = {0: [0, 1], 1: [0, 1, 2], 2: [1, 2, 3], 3: [2, 3]}
    half = len(v) // 2
    for rows, expected_anchor in ((list(range(half)), 0), (list(range(half, len(v))), anchor_up)):
        means = [np.mean([b[i, k] for i in rows]) for k in range(4)]
        anchor = int(np.argmin(means))
        centre = v[rows].mean(axis=0)
        if anchor == 2 and np.dot(centre - CHAIN[2], CHAIN[3] - CHAIN[2]) > np.dot(CHAIN[3] - CHAIN[2], CHAIN[3] - CHAIN[2]):
            anchor = 3  # the piece's centre is beyond the leaf joint 3
        assert anchor == expected_anchor
        dist = {i: [b[i, k] for k in range(4)] for i in rows}
        if anchor == 3:  # the leaf's own segment, through the piece
            for i in rows:
                dist[i][3] = segment_distance(v[i], CHAIN[3], 2 * centre - CHAIN[3])
        thickness = np.mean([dist[i][anchor] for i in rows])
        for i in rows[::7]:
            expected = np.zeros(4)
            for k in neighbours[anchor]:
                expected[k] = (dist[i][k] + 0.5 * thickness + 1e-4) ** -4.0 * (1.5 if k == anchor else 1.0)
            expected /= expected.sum()
            np.testing.assert_allclose(w[i], expected, rtol=2e-5, atol=1e-12)
    # the lower ball wraps bone 0 (segment 0 -> 0.25): bones 2 and 3 get nothing; the upper one leaves out bone 0
    assert w[:half, 2:].max() < 1e-15 and w[half:, 0].max() < 1e-15
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-12)


def test_a_piece_spanning_the_body_or_a_fragment_gets_no_prior():
    body = np.ones(4, bool)
    tube = trimesh.creation.cylinder(radius=0.05, height=0.9, sections=12)
    tube.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    tv = np.asarray(tube.vertices) + [0, 0.4, 0]  # one piece 0.9 tall: the whole chain
    bv, bf = ball([0.0, 0.62, 0.0])
    tri = np.array([[0.0, 0.1, 0.05], [0.01, 0.1, 0.05], [0.0, 0.11, 0.05]])  # a split face: 3 vertices
    v = np.r_[tv, bv, tri]
    f = np.r_[np.asarray(tube.faces), bf + len(tv), np.array([[0, 1, 2]]) + len(tv) + len(bv)]
    p = piece_prior(v, f, bone_distances(v, CHAIN, CHAIN_PARENTS, body), CHAIN, CHAIN_PARENTS, body)
    rows = np.isnan(p).all(axis=1)
    assert rows[:len(tv)].all() and rows[-3:].all()  # the tube and the fragment: no prior
    assert not np.isnan(p[len(tv):len(tv) + len(bv)]).any()  # the ball wraps bone 2
    assert (p[len(tv):len(tv) + len(bv), 0] == OUTSIDE).all()


def test_piece_prior_is_near_the_zoo_weights_the_bone_prior_is_not(tmp_path):
    """The zoo weights its capsules (one piece a bone) from true segment tails and capsule radii
    (datagen/zoo/skin_weights.py), which the prior never reads: an independent reference."""
    from mimicbench.baselines.mmdmc.data import TrainingData, body_target_weights
    from mimicbench.cli import main

    assert main(["zoo", "--out", str(tmp_path / "z"), "--characters", "2", "--categories", "apparel",
                 "--seed", "303", "--quiet"]) == 0
    data = TrainingData.load(tmp_path / "z", simulated=False)
    for c in data.characters.values():
        body = ~c.apparel
        target = body_target_weights(c)[body]
        piece = c.prior.astype(np.float64)
        wrapped = ~np.isnan(piece[:, 0])
        assert wrapped[body].mean() > 0.95  # every zoo capsule is a piece of its own
        fallback = -c.bone.astype(np.float64) / PRIOR_TAU
        piece_w = softmax_rows(np.where(wrapped[:, None], piece, fallback))[body]
        bone_w = softmax_rows(fallback)[body]
        l1_piece = np.abs(piece_w - target).sum(1).mean()
        l1_bone = np.abs(bone_w - target).sum(1).mean()
        assert l1_piece < 0.25 and l1_bone > 0.45, (l1_piece, l1_bone)  # validation zoo: 0.13 against 0.57


def test_body_module_scores_wrapped_pieces_by_the_prior_alone():
    """With the piece prior, a vertex of a wrapped piece is scored by the prior (the head cannot move
    it); any other vertex, and every vertex when no prior is handed in (training), by the learnt path."""
    v, f = two_balls()
    v = np.r_[v, [[0.3, 0.3, 0.3]]]  # a vertex in no face: its own one-vertex piece, no prior
    body = np.ones(4, bool)
    b = bone_distances(v, CHAIN, CHAIN_PARENTS, body)
    p = piece_prior(v, f, b, CHAIN, CHAIN_PARENTS, body)
    assert np.isnan(p[-1]).all() and not np.isnan(p[:-1]).any()
    t = lambda a: torch.as_tensor(np.asarray(a, np.float32))[None]  # noqa: E731
    geo = np.linalg.norm(v[:, None] - CHAIN[None], axis=-1)
    torch.manual_seed(0)
    f_s = BodySkinning(hidden=8, prior="piece")
    w = f_s(t(v), t(CHAIN), t(geo), t(b), piece=t(p))[0].detach().numpy()
    np.testing.assert_allclose(w[:-1], softmax_rows(p[:-1].astype(np.float64)), atol=1e-5)
    np.testing.assert_allclose(w[-1], softmax_rows(-b[-1:].astype(np.float64) / PRIOR_TAU)[0], atol=1e-5)
    with torch.no_grad():
        f_s.head_out[-1].weight.normal_(0.0, 0.05)
    moved = f_s(t(v), t(CHAIN), t(geo), t(b), piece=t(p))[0].detach().numpy()
    np.testing.assert_array_equal(moved[:-1], w[:-1])  # the head does not reach wrapped pieces
    assert np.abs(moved[-1] - w[-1]).max() > 1e-3
    learnt = f_s(t(v), t(CHAIN), t(geo), t(b))[0].detach().numpy()  # no prior handed in: the learnt path
    bone_mode = BodySkinning(hidden=8)
    bone_mode.load_state_dict(f_s.state_dict())
    np.testing.assert_array_equal(learnt, bone_mode(t(v), t(CHAIN), t(geo), t(b))[0].detach().numpy())
    with pytest.raises(ValueError, match="piece prior scores"):
        f_s(t(v), t(CHAIN), t(geo), t(b), piece=t(p[:, :3]))
    with pytest.raises(ValueError, match="expected one of"):
        BodySkinning(prior="nearest")


class RoughSkinning(torch.nn.Module):
    """A stand-in f_s with the piece prior whose weights change from vertex to vertex."""

    prior = "piece"

    def __init__(self):
        super().__init__()
        self.p = torch.nn.Parameter(torch.zeros(1))

    def forward(self, points, joints, geo, bone, piece=None):
        assert piece is not None and piece.shape == bone.shape  # the pipeline hands it the prior
        w = torch.rand(geo.shape, generator=torch.Generator().manual_seed(0)) + self.p * 0
        return w / w.sum(-1, keepdim=True)


def test_mesh_weights_leave_the_pieces_the_prior_wraps_unsmoothed():
    from mimicbench.baselines.mmdmc.data import prepare
    from mimicbench.baselines.mmdmc.pipeline import mesh_weights, skinning_weights

    tube = trimesh.creation.cylinder(radius=0.05, height=0.9, sections=12)
    tube.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    tv = np.asarray(tube.vertices) + [0.2, 0.4, 0]
    bv, bf = ball([0.0, 0.62, 0.0])
    v = np.r_[tv, bv]
    f = np.r_[np.asarray(tube.faces), bf + len(tv)]
    prep = prepare("toy/tube-and-ball", v, f, CHAIN, CHAIN_PARENTS, np.ones(4, bool))
    wrapped = ~np.isnan(prep.prior[:, 0])
    assert wrapped.tolist() == [False] * len(tv) + [True] * len(bv)
    f_s = RoughSkinning()
    raw = skinning_weights(f_s, prep).numpy()
    out = mesh_weights(f_s, prep, None, radius=0.05).numpy()
    np.testing.assert_array_equal(out[wrapped], raw[wrapped])
    assert np.abs(out[~wrapped] - raw[~wrapped]).max() > 0.05  # the tube is diffused
    mask = np.zeros(len(v), bool)
    mask[len(tv):len(tv) + 10] = True  # apparel vertices are smoothed wherever they are
    masked = mesh_weights(f_s, prep, mask, radius=0.05).numpy()
    np.testing.assert_array_equal(masked[wrapped & ~mask], raw[wrapped & ~mask])
    assert np.abs(masked[mask] - raw[mask]).max() > 0.01
