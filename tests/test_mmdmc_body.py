"""f_s of the MMDMC reference: vertex-bone distances, the body target's weights, and an untrained
f_s equal to its bone-distance prior; checked against hand-computed values and naive loops."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mmdmc.body import PRIOR_TAU, BodySkinning
from mimicbench.baselines.mmdmc.bone_distance import bone_distances, mesh_box
from mimicbench.baselines.mmdmc.data import body_target_weights, prepare
from mimicbench.baselines.mmdmc.rig import attachment_bones
from mimicbench.schemas.weights import SparseWeights

# joints: 0 root (0,0,0) -> 1 (1,0,0) -> 2 leaf (1,1,0); 3 apparel child of 1 at (1,0,1) -> 4 apparel (1,0,2)
KEYPOINTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 0, 1], [1, 0, 2]], np.float64)
PARENTS = np.array([-1, 0, 1, 1, 3])
BODY = np.array([True, True, True, False, False])


def test_bone_distances_by_hand():
    v = np.array([[0.5, 0.2, 0.0], [1.0, 0.5, 0.3], [2.0, 2.0, 0.0]])
    d = bone_distances(v, KEYPOINTS, PARENTS, BODY)
    assert d.shape == (3, 3) and d.dtype == np.float32
    # bone 0: segment (0,0,0)-(1,0,0); bone 1: (1,0,0)-(1,1,0) (its apparel child 3 is no segment end);
    # bone 2: a leaf, its joint's point
    expected = [[0.2, 0.5, np.hypot(0.5, 0.8)],
                [np.hypot(0.5, 0.3), 0.3, np.hypot(0.5, 0.3)],
                [np.hypot(1.0, 2.0), np.sqrt(2.0), np.sqrt(2.0)]]
    np.testing.assert_allclose(d, expected, rtol=1e-6)


def test_bone_distances_take_the_nearest_of_several_children():
    kp = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)  # root with two children
    d = bone_distances(np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.1]]), kp, np.array([-1, 0, 0]), np.ones(3, bool))
    np.testing.assert_allclose(d[:, 0], [0.5, 0.1], rtol=1e-6)


def test_a_child_joint_outside_the_mesh_box_ends_no_segment():
    """An MMD weight bone (a physics helper far below the model) must not stretch its parent's
    bone through the legs: with the mesh's box it is left out, and the parent is a point."""
    kp = np.array([[0, 1.5, 0], [0, 1.2, 0], [0, -6.0, 0]], np.float64)  # root, cloak joint, helper 7.2 m below
    parents = np.array([-1, 0, 1])
    mesh = np.array([[0.3, 0.0, 0.0], [-0.3, 1.6, 0.1], [0.0, 0.8, -0.1]])  # 1.6 m tall
    box = mesh_box(mesh)
    np.testing.assert_allclose(box, [[-0.46, -0.16, -0.26], [0.46, 1.76, 0.26]], atol=1e-12)  # grown by 0.1 x 1.6
    leg = np.array([[0.0, 0.2, 0.05]])
    free = bone_distances(leg, kp, parents, np.ones(3, bool))
    boxed = bone_distances(leg, kp, parents, np.ones(3, bool), box)
    assert free[0, 1] == pytest.approx(0.05)  # on the segment 1.2 -> -6.0
    assert boxed[0, 1] == pytest.approx(np.hypot(1.0, 0.05))  # the cloak joint's point
    np.testing.assert_array_equal(boxed[:, [0, 2]], free[:, [0, 2]])  # the others keep their segments


def test_bone_distances_say_what_was_expected():
    with pytest.raises(ValueError, match="expected"):
        bone_distances(np.zeros((2, 3)), KEYPOINTS, PARENTS[:3], BODY)


def test_attachment_bones():
    assert attachment_bones(PARENTS, BODY).tolist() == [0, 1, 2, 1, 1]
    # an apparel chain hanging from no body bone has no attachment
    assert attachment_bones(np.array([-1, 0, -1]), np.array([True, True, False])).tolist() == [0, 1, -1]
    with pytest.raises(ValueError, match="one entry per bone"):
        attachment_bones(PARENTS, BODY[:2])


def tiny_character():
    """A strip of 4 vertices along x; vertex 3 weighted mostly to the apparel bone 4."""
    v = np.array([[0.1, 0, 0], [0.6, 0, 0], [1.0, 0.4, 0], [1.0, 0.0, 1.5]], np.float32)
    faces = np.array([[0, 1, 2], [1, 2, 3]], np.int32)
    dense = np.zeros((4, 5), np.float32)
    dense[0, 0] = 1.0
    dense[1, [0, 1]] = [0.5, 0.5]
    dense[2, [1, 2]] = [0.25, 0.75]
    dense[3, [0, 3, 4]] = [0.2, 0.3, 0.5]
    return prepare("toy", v, faces, KEYPOINTS, PARENTS, BODY, weights=SparseWeights.from_dense(dense),
                   apparel=np.array([False, False, False, True])), dense


def test_body_target_moves_apparel_weight_to_the_attachment_bone():
    c, dense = tiny_character()
    t = body_target_weights(c)
    assert t.shape == (4, 3)
    np.testing.assert_allclose(t[:3], dense[:3, :3], atol=1e-6)  # body vertices keep their weights
    np.testing.assert_allclose(t[3], [0.2, 0.8, 0.0], atol=1e-6)  # bones 3 and 4 hang from bone 1
    np.testing.assert_allclose(t.sum(1), 1.0, atol=1e-6)


def test_untrained_body_module_is_the_bone_distance_prior():
    c, _ = tiny_character()
    torch.manual_seed(0)
    f_s = BodySkinning(hidden=8)
    w = f_s(torch.as_tensor(c.rest_norm)[None], torch.as_tensor(c.joints_norm)[None], torch.as_tensor(c.geo)[None],
            torch.as_tensor(c.bone)[None])[0].detach().numpy()
    b = bone_distances(c.rest, KEYPOINTS, PARENTS, BODY, mesh_box(c.rest)) / c.height  # as prepare() reads them
    expected = np.exp(-(b - b.min(1, keepdims=True)) / PRIOR_TAU)
    expected /= expected.sum(1, keepdims=True)
    np.testing.assert_allclose(w, expected, atol=1e-5)


def test_weight_smoothing_matches_a_naive_loop():
    from mimicbench.baselines.mmdmc.weight_smoothing import smooth_weights

    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(3), size=5)
    edges = np.array([[0, 1], [1, 2], [2, 3], [0, 2]])  # vertex 4 in no edge
    expected = w.copy()
    for _ in range(3):
        nxt = expected.copy()
        for i in range(4):
            nb = [b if a == i else a for a, b in edges if i in (a, b)]
            nxt[i] = 0.5 * (expected[i] + np.mean([expected[j] for j in nb], axis=0))
        expected = nxt
    got = smooth_weights(w, edges, 3)
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    np.testing.assert_allclose(got.sum(1), 1.0, rtol=1e-6)  # rows stay convex combinations
    np.testing.assert_allclose(got[4], w[4], rtol=1e-6)  # a vertex in no edge keeps its weights
    np.testing.assert_allclose(smooth_weights(w, edges, 0), w, rtol=1e-6)
    with pytest.raises(ValueError, match="iterations >= 0"):
        smooth_weights(w, edges, -1)


def _strip(step: float, length: float = 2.0, width: float = 0.2):
    """A flat strip x in [-length/2, length/2], z in [0, width] triangulated on a grid of ``step``."""
    xs = np.linspace(-length / 2, length / 2, int(round(length / step)) + 1)
    zs = np.linspace(0.0, width, int(round(width / step)) + 1)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    v = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], 1)
    nz = len(zs)
    faces = []
    for i in range(len(xs) - 1):
        for j in range(nz - 1):
            a, b, c, d = i * nz + j, (i + 1) * nz + j, (i + 1) * nz + j + 1, i * nz + j + 1
            faces += [[a, b, c], [a, c, d]]
    return v, np.array(faces)


@pytest.mark.parametrize("step", [0.01, 0.04])
def test_weight_diffusion_matches_the_screened_poisson_solution_at_any_resolution(step):
    from mimicbench.baselines.mmdmc.weight_smoothing import diffuse_weights

    # a step in the weights along x; (1 - r^2 d^2/dx^2) u = step has the closed form
    # u = 1 - exp(-x/r)/2 for x >= 0 and exp(x/r)/2 for x < 0, on a fine mesh and a coarse one alike
    v, f = _strip(step)
    r = 0.1
    step_w = (v[:, 0] > 1e-9).astype(np.float64) + 0.5 * (np.abs(v[:, 0]) <= 1e-9)
    w = np.stack([step_w, 1.0 - step_w], 1)
    got = diffuse_weights(w, v, f, r)
    x = v[:, 0]
    expected = np.where(x >= 0, 1.0 - 0.5 * np.exp(-x / r), 0.5 * np.exp(x / r))
    inner = np.abs(x) < 0.6  # away from the strip's ends
    assert np.abs(got[inner, 0] - expected[inner]).max() < 0.03
    np.testing.assert_allclose(got.sum(1), 1.0, rtol=1e-5)
    assert (got >= 0).all()


def test_weight_diffusion_keeps_pieces_apart_and_lonely_vertices():
    from mimicbench.baselines.mmdmc.weight_smoothing import diffuse_weights

    v, f = _strip(0.05)
    n = len(v)
    v2 = np.concatenate([v, v + [0, 0.5, 0], [[9.0, 9.0, 9.0]]])  # a second piece above, one vertex in no face
    f2 = np.concatenate([f, f + n])
    rng = np.random.default_rng(1)
    w = np.concatenate([np.tile([1.0, 0.0, 0.0], (n, 1)), rng.dirichlet(np.ones(3), size=n + 1)])
    got = diffuse_weights(w, v2, f2, 0.2)
    np.testing.assert_allclose(got[:n], w[:n], atol=1e-6)  # constant on its own piece: the other piece's weights stay out
    np.testing.assert_allclose(got[-1], w[-1], rtol=1e-6)
    assert np.abs(got[n:-1] - w[n:-1]).max() > 0.05  # the random piece was smoothed
    np.testing.assert_allclose(got.sum(1), 1.0, rtol=1e-5)
    np.testing.assert_allclose(diffuse_weights(w, v2, f2, 0.0), w, rtol=1e-6)
    with pytest.raises(ValueError, match="radius >= 0"):
        diffuse_weights(w, v2, f2, -0.1)
