"""Test-time ARAP refinement: invariants with known answers (rest stays rest, a rigid motion of
the whole mesh stays that rigid motion) and a real glTF character."""
from __future__ import annotations

import numpy as np
import pytest

from baselines.mimicat.arap import ArapRefiner
from mimicbench.quaternion import quat_from_axis_angle, quat_to_matrix
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
    bb = ref.handles(rig.faces, rig.weights.values, len(rig.vertices))
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
    b = refiner.handles(refiner.solvable_faces(rest, faces), values, len(rest))
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[b], pose[b], atol=1e-4 * size)
    assert np.abs(out - pose).max() < 0.5 * size  # a refinement, not a different pose
