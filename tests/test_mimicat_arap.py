"""Test-time ARAP refinement: invariants with known answers (rest stays rest, a rigid motion of
the whole mesh stays that rigid motion) and a real glTF character."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.baselines.mimicat.arap import ArapRefiner
from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_to_matrix
from tests.mimicat_toys import bend, posed, tube_rig


def test_rest_and_rigid_motions_are_fixed_points():
    rig = tube_rig("t", 4)
    ref = ArapRefiner(rigid=0.9)
    v = np.asarray(rig.vertices, np.float64)
    np.testing.assert_allclose(ref.refine("t", v, rig.faces, rig.weights.values, v), v, atol=1e-5)
    r = quat_to_matrix(quat_from_axis_angle(np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2]), 0.9))
    moved = v @ r.T + [0.4, -0.1, 2.0]
    np.testing.assert_allclose(ref.refine("t", v, rig.faces, rig.weights.values, moved), moved, atol=1e-4)


def test_handles_hold_and_every_component_gets_one():
    rig = tube_rig("t", 4)
    ref = ArapRefiner(rigid=0.9)
    b = ref.handles(rig.faces, rig.weights.values, len(rig.vertices))
    top = np.asarray(rig.weights.values).max(axis=1)
    assert set(np.flatnonzero(top >= 0.9)) <= set(b)
    # two copies of the tube side by side, all weights blended: three handles per copy
    faces = np.concatenate([rig.faces, rig.faces + len(rig.vertices)])
    blended = np.full((2 * len(rig.vertices), 2), 0.5)
    assert len(ref.handles(faces, blended, 2 * len(rig.vertices))) == 6
    pose = posed(rig, bend(rig, 0.8, 1))
    out = ref.refine("t", rig.vertices, rig.faces, rig.weights.values, pose)
    bb = ref.held("t", rig.vertices, rig.faces, rig.weights.values)
    assert set(ref.handles(rig.faces, rig.weights.values, len(rig.vertices))) <= set(bb)
    np.testing.assert_allclose(out[bb], pose[bb], atol=1e-5)
    assert np.isfinite(out).all()
    with pytest.raises(ValueError, match="rigid"):
        ArapRefiner(rigid=0)


def test_default_holds_every_vertex_one_bone_dominates():
    """The default holds exactly the vertices whose largest skin weight is at least one half (a
    bone carries the majority: every two-bone blend, no even three-bone one), by a naive loop
    over hand-made weight rows on the tube (one connected component with plenty held)."""
    rig = tube_rig("t", 4)
    kinds = np.array([[1.0, 0, 0], [0.6, 0.4, 0], [0.5, 0.5, 0], [0.4, 0.3, 0.3], [1 / 3, 1 / 3, 1 / 3]])
    values = kinds[np.arange(len(rig.vertices)) % len(kinds)]
    expected = [i for i in range(len(values)) if max(values[i]) >= 0.5]
    assert 0 < len(expected) < len(values)
    assert ArapRefiner().handles(rig.faces, values, len(values)).tolist() == expected


def _faces(ref, prims):
    out, offset = [], 0
    for p in prims:
        spec = ref.json["meshes"][p.mesh]["primitives"][p.index]
        if spec.get("mode", 4) == 4:  # triangles, indexed or not (glTF 2.0, 3.7.2.1)
            idx = ref.accessor(spec["indices"]) if "indices" in spec else np.arange(len(p.positions))
            out.append(idx.reshape(-1, 3).astype(np.int64) + offset)
        offset += len(p.positions)
    return np.concatenate(out)


def _weight_values(p) -> np.ndarray:
    """(V, 8) normalised weight values of a primitive (one rigid influence when unskinned)."""
    w = np.ones((len(p.positions), 1)) if p.weights is None else p.weights / np.maximum(p.weights.sum(1, keepdims=True), 1e-12)
    return np.pad(w, ((0, 0), (0, 8 - w.shape[1])))


@pytest.mark.parametrize("name", ["Fox", "CesiumMan", "Quaternius_Horse", "Quaternius_Dolphin", "Quaternius_Stegosaurus",
                                  "Quaternius_Triceratops", "Quaternius_MantaRay", "Quaternius_Rat", "Quaternius_Husky",
                                  "RobotExpressive"])
def test_real_gltf_characters(assets_dir, name):
    """Every real glTF character with a clip: skinned by an independent glTF evaluator at rest and
    mid-clip; ARAP keeps rest at rest, holds its handles and stays finite."""
    from tests.gltf_reference import GltfReference

    ref = GltfReference(assets_dir / "glb" / f"{name}.glb")
    prims = ref.primitives()
    if not ref.animations or not any(p.skin is not None for p in prims):
        pytest.fail(f"{name}: expected a skinned glTF with clips")
    rest = ref.vertices(None)
    lo, hi = ref.clip_range(0)
    pose = ref.vertices(0, (lo + hi) / 2)
    faces = _faces(ref, prims)
    values = np.concatenate([_weight_values(p) for p in prims])
    refiner = ArapRefiner()
    size = float((rest.max(0) - rest.min(0)).max())
    np.testing.assert_allclose(refiner.refine(name + "/rest", rest, faces, values, rest), rest, atol=1e-4 * size)
    out = refiner.refine(name, rest, faces, values, pose)
    b = refiner.held(name, rest, faces, values)
    assert set(np.flatnonzero(values.max(axis=1) >= refiner.rigid)) <= set(b)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[b], pose[b], atol=1e-4 * size)
    assert np.abs(out - pose).max() < 0.5 * size  # a refinement, not a different pose


def _zipped_tube(gap: float):
    """The tube with its middle ring doubled ``gap`` apart (new vertices take the ring's weights)
    and the two copies joined by thin triangles (a decimator's leftovers): the faces above the
    ring use the copy. Returns the rig, vertices (N + S, 3), faces, weight values, the ring's and
    the copy's vertex indices."""
    from tests.toys import make_tube

    t = make_tube(num_bones=4, rings=12, segments=8)
    v, f = np.asarray(t["vertices"], np.float64), np.asarray(t["faces"], np.int64)
    values = np.asarray(t["weights"].values, np.float64)
    ring = np.arange(6 * 8, 7 * 8)
    copy = len(v) + np.arange(8)
    upper = np.isin(f, np.arange(7 * 8, 12 * 8)).any(axis=1) & np.isin(f, ring).any(axis=1)
    remap = np.arange(len(v) + 8)
    remap[ring] = copy
    f = np.concatenate([np.where(upper[:, None], remap[f], f)] +
                       [np.array([[ring[s], ring[(s + 1) % 8], copy[s]], [ring[(s + 1) % 8], copy[(s + 1) % 8], copy[s]]])
                        for s in range(8)])
    v = np.concatenate([v, v[ring] + [0.0, gap, 0.0]])
    return t, v, f, np.concatenate([values, values[ring]]), ring, copy


def test_edges_shorter_than_the_weld_deform_as_lbs_did():
    """A seam of edges 1e-9 of the size (zero-area triangles, as decimation leaves them): ARAP
    solved on the welded mesh gives each short edge exactly its LBS edge vector, so its length
    ratio to the LBS one is 1; without the weld, ARAP moves the two sides independently and the
    short edges' lengths change by orders of magnitude (what sent mimicat's ELS to -600 on real
    characters). Vertices away from the seam stay within the refinement's reach of LBS."""
    from mimicbench.benchmark.metrics import els
    from mimicbench.geometry.mesh import unique_edges
    from mimicbench.geometry.skinning import linear_blend_skinning
    from mimicbench.geometry.weights import SparseWeights

    t, v, f, values, ring, copy = _zipped_tube(1e-9)
    idx = np.concatenate([np.asarray(t["weights"].indices), np.asarray(t["weights"].indices)[ring]])
    weights = SparseWeights(idx.astype(np.int32), values.astype(np.float32), t["weights"].num_keypoints)
    rig = tube_rig("t", 4)
    pose = linear_blend_skinning(v, t["keypoints"], weights, bend(rig, 0.9, 3))
    edges = unique_edges(f)
    short = edges[np.isin(edges[:, 0], np.concatenate([ring, copy])) & np.isin(edges[:, 1], copy)
                  | np.isin(edges[:, 1], np.concatenate([ring, copy])) & np.isin(edges[:, 0], copy)]
    short = short[np.linalg.norm(v[short[:, 0]] - v[short[:, 1]], axis=1) < 1e-6]
    assert len(short) >= 8
    welded = ArapRefiner(rigid=0.9).refine("w", v, f, values, pose)
    np.testing.assert_allclose(welded[short[:, 0]] - welded[short[:, 1]], pose[short[:, 0]] - pose[short[:, 1]],
                               atol=1e-6)
    assert els(welded, pose, edges) > 0.9
    apart = ArapRefiner(rigid=0.9, weld=0.0).refine("a", v, f, values, pose)
    assert els(apart, pose, edges) < 0.0  # the failure the weld removes, seen by the same metric
    with pytest.raises(ValueError, match="weld"):
        ArapRefiner(weld=1.5)


def test_clusters_by_a_naive_loop():
    """Weld clusters against a loop over every vertex pair (union-find by hand)."""
    _, v, f, values, ring, copy = _zipped_tube(2e-4)
    ref = ArapRefiner(weld=1e-3)
    label = ref.clusters(v, f)
    tol = 1e-3 * (v.max(0) - v.min(0)).max()
    root = list(range(len(v)))

    def find(a):
        while root[a] != a:
            a = root[a]
        return a
    for i in range(len(v)):
        for j in range(i + 1, len(v)):
            if np.linalg.norm(v[i] - v[j]) <= tol:
                root[find(i)] = find(j)
    expected = np.array([find(i) for i in range(len(v))])
    same = label[:, None] == label[None, :]
    np.testing.assert_array_equal(same, expected[:, None] == expected[None, :])
    assert (label[ring] == label[copy]).all() and len(np.unique(label)) == len(v) - len(copy)
