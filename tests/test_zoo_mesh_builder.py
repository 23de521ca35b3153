"""Capsule meshes of the zoo: closed, outward, no degenerate faces, counts as documented."""
import numpy as np
import trimesh

from mimicbench.datagen.zoo.mesh_builder import build_mesh, capsule
from mimicbench.datagen.zoo.skeleton import SkeletonBuilder


def test_capsule_is_closed_outward_and_counts_match():
    s, b, c = 12, 5, 3
    v, f = capsule([0, 0, 0], [0.3, 0.2, 0.1], 0.1, 0.05, s, b, c, aspect=(1.5, 0.7), side_ref=(1, 0, 0))
    r = 2 * c + b
    assert v.shape == (2 + s * r, 3) and f.shape == (2 * s * r, 3)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume > 0  # outward normals
    assert m.area_faces.min() > 1e-8


def test_capsule_spans_head_minus_radius_to_tail_plus_radius():
    v, _ = capsule([0, 0, 0], [0, 1, 0], 0.1, 0.2, 16, 4, 4)
    assert np.isclose(v[:, 1].min(), -0.1) and np.isclose(v[:, 1].max(), 1.2)
    # radius at the middle of the body interpolates the two radii
    mid = v[np.isclose(v[:, 1], 0.6, atol=1e-9)]
    assert len(mid) and np.allclose(np.linalg.norm(mid[:, [0, 2]], axis=1), 0.16)


def test_build_mesh_reaches_target_faces_with_one_closed_component_per_bone():
    b = SkeletonBuilder()
    r = b.add("root", -1, (0, 0, 0), (0, 0.5, 0), 0.1)
    b.add("tail/1", r, (0, 0.5, 0), (0, 0.8, 0.2), 0.08, 0.04)
    skel = b.build()
    v, f, owner = build_mesh(skel, target_faces=6000)
    assert len(f) >= 6000
    assert set(np.unique(owner)) == {0, 1}
    for k in (0, 1):
        rows = np.nonzero(owner == k)[0]
        sel = np.isin(f, rows).all(1)
        sub = trimesh.Trimesh(v, f[sel], process=False)
        sub.remove_unreferenced_vertices()
        assert sub.is_watertight and sub.volume > 0
    assert np.isin(f, np.arange(len(v))).all()
