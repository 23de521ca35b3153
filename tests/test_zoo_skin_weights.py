"""Zoo skin weights: distances against a naive loop, invariants, smoothness, apparel isolation."""
import numpy as np

from mimicbench.datagen.zoo.mesh_builder import build_mesh
from mimicbench.datagen.zoo.skeleton import SkeletonBuilder
from mimicbench.datagen.zoo.skin_weights import skin_weights
from mimicbench.geometry.mesh import unique_edges
from mimicbench.geometry.segments import point_segment_distance


def _naive_distance(p, a, b):
    best = np.inf
    for t in np.linspace(0, 1, 4001):
        best = min(best, np.linalg.norm(p - (a + t * (b - a))))
    return best


def test_point_segment_distance_matches_dense_sampling():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(5, 3))
    a, b = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    d = point_segment_distance(pts, a, b)
    for i in range(5):
        for j in range(3):
            assert abs(d[i, j] - _naive_distance(pts[i], a[j], b[j])) < 2e-3


def _arm_with_skirt():
    b = SkeletonBuilder()
    hips = b.add("hips", -1, (0, 1, 0), (0, 1.2, 0), 0.1)
    up = b.add("left/upper_arm", hips, (0, 1.2, 0), (0.3, 1.2, 0), 0.05)
    b.add("left/forearm", up, (0.3, 1.2, 0), (0.6, 1.2, 0), 0.04)
    b.add("apparel/skirt/1/1", hips, (0, 1.0, 0.1), (0, 0.8, 0.12), 0.02, apparel=True)
    return b.build()


def test_weights_invariants_and_apparel_isolation():
    skel = _arm_with_skirt()
    v, f, owner = build_mesh(skel, 4000)
    w = skin_weights(skel, v, owner)
    assert w.indices.shape == (len(v), 8)
    assert np.allclose(w.values.sum(1), 1, atol=1e-5)
    assert (w.values >= 0).all() and ((w.values > 0).sum(1) >= 1).all()
    dense = w.to_dense()
    body = ~skel.apparel[owner]
    assert np.all(dense[body][:, 3] == 0)  # the body never follows the skirt
    # the joint between upper arm and forearm blends: vertices near the elbow take both bones
    elbow = np.linalg.norm(v - [0.3, 1.2, 0], axis=1) < 0.06
    assert (np.minimum(dense[elbow, 1], dense[elbow, 2]) > 0.2).any()


def test_weights_are_smooth_along_edges():
    skel = _arm_with_skirt()
    v, f, owner = build_mesh(skel, 6000)
    dense = skin_weights(skel, v, owner).to_dense()
    e = unique_edges(f)
    # neighbouring vertices never jump by more than 0.3 in any weight (no hard seams)
    assert np.abs(dense[e[:, 0]] - dense[e[:, 1]]).max() < 0.3
