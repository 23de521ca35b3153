"""Round trips through PMX: Gene (with its physics) and a zoo apparel character (with physics made
here for its apparel chains) are written with mimicbench.datagen.mmd.pmx_writer and read back."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.mmd.physics import physics_records
from mimicbench.datagen.mmd.pmx import parse_pmx, read_pmx
from mimicbench.datagen.mmd.pmx_writer import pmx_bytes, write_pmx
from mimicbench.datagen.mmd.records import character_from_mmd
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord


def _read_back(data: bytes, cid: str):
    m = parse_pmx(data, f"{cid}.pmx")
    c = character_from_mmd(m, cid, f"{cid}.pmx", "train")
    new_index = np.empty(len(m.bones), np.int64)
    new_index[c.meta["mmd"]["file_bone_index"]] = np.arange(len(m.bones))
    return c, *physics_records(m, cid, new_index)


def _same_physics(a, b):
    for x, y in zip(a, b):
        for col in type(x).COLUMNS:
            u, v = getattr(x, col.name), getattr(y, col.name)
            if col.name in ("rotation",):  # a quaternion and its negation are one rotation
                assert abs(abs(float(np.dot(u, v))) - 1) < 1e-5, (x.name, col.name)
            elif isinstance(u, np.ndarray):
                np.testing.assert_allclose(u, v, atol=2e-6, err_msg=f"{x.name} {col.name}")
            elif isinstance(u, float):
                assert u == pytest.approx(v, abs=1e-6), (x.name, col.name)
            else:
                assert u == v, (x.name, col.name)


def test_gene_round_trip(assets_dir, tmp_path):
    m = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    c = character_from_mmd(m, "assets/Gene", "Gene.pmx", "train")
    bodies, joints = physics_records(m, "assets/Gene", np.arange(len(m.bones)))
    path = write_pmx(tmp_path / "gene_again.pmx", c, bodies, joints)
    c2, bodies2, joints2 = _read_back(path.read_bytes(), "assets/Gene")
    np.testing.assert_allclose(c2.vertices, c.vertices, atol=1e-6)
    np.testing.assert_array_equal(c2.faces, c.faces)
    np.testing.assert_allclose(c2.keypoints, c.keypoints, atol=1e-6)
    assert c2.bone_names == c.bone_names and np.array_equal(c2.parents, c.parents)
    np.testing.assert_allclose(c2.weights.to_dense(), c.weights.to_dense(), atol=1e-6)
    np.testing.assert_array_equal(c2.apparel_bone_mask, c.apparel_bone_mask)
    np.testing.assert_array_equal(c2.apparel_vertex_mask, c.apparel_vertex_mask)
    assert len(bodies2) == 87 and len(joints2) == 92
    _same_physics(bodies, bodies2)
    _same_physics(joints, joints2)


def _zoo_apparel_physics(c):
    """Capsules on every apparel bone (dynamic) and on each chain's parent (static), a joint from
    each body to its parent's, with limits and springs (written here, independently of
    mimicbench.datagen.mmd.chain_physics, with asymmetric limits and a tilted orientation)."""
    bodies, joints, body_of = [], [], {}
    kp = np.asarray(c.keypoints, np.float64)
    parents = np.asarray(c.parents)
    apparel = np.flatnonzero(c.apparel_bone_mask)
    anchors = sorted({int(parents[k]) for k in apparel if parents[k] >= 0 and not c.apparel_bone_mask[parents[k]]})
    for k in anchors + [int(k) for k in apparel]:
        dyn = bool(c.apparel_bone_mask[k])
        body_of[k] = len(bodies)
        bodies.append(RigidBodyRecord(c.character_id, len(bodies), f"b{k}", "", k, "capsule", np.float32([0.02, 0.05, 0]),
                                      kp[k].astype(np.float32), np.float32([np.cos(0.2), 0, np.sin(0.2), 0]),
                                      0.5, 0.5, 0.5, 0.0, 0.5, 2 if dyn else 0, 0xFFFB if dyn else 0xFFFF,
                                      "dynamic" if dyn else "static"))
    for k in apparel:
        p = int(parents[k])
        if p in body_of:
            joints.append(JointRecord(c.character_id, len(joints), f"j{k}", "", "spring_6dof", body_of[p], body_of[int(k)],
                                      kp[k].astype(np.float32), np.float32([1, 0, 0, 0]), np.float32([0, 0, -0.01]),
                                      np.float32([0, 0, 0.02]), np.float32([-0.3, -0.1, -0.5]), np.float32([0.2, 0.1, 0.4]),
                                      np.float32([0, 0, 0]), np.float32([10, 20, 30])))
    return bodies, joints


def test_zoo_apparel_character_round_trip():
    from mimicbench.datagen.zoo.build import build_character
    from mimicbench.datagen.zoo.plan import plan_zoo

    spec = [s for s in plan_zoo(24, seed=0) if s.category == "apparel"][0]
    c = build_character(spec, "train", 0, 10).record
    assert c.apparel_bone_mask.any()
    bodies, joints = _zoo_apparel_physics(c)
    c2, bodies2, joints2 = _read_back(pmx_bytes(c, bodies, joints), c.character_id)
    np.testing.assert_allclose(c2.vertices, c.vertices, atol=2e-6)
    np.testing.assert_array_equal(c2.faces, c.faces)
    np.testing.assert_allclose(c2.keypoints, c.keypoints, atol=2e-6)
    assert c2.bone_names == c.bone_names and np.array_equal(c2.parents, c.parents)
    # PMX keeps 4 influences a vertex: the 4 largest, renormalised
    dense = c.weights.to_dense().astype(np.float64)
    top = np.argsort(-dense, axis=1)[:, :4]
    expected = np.zeros_like(dense)
    np.put_along_axis(expected, top, np.take_along_axis(dense, top, axis=1), axis=1)
    expected /= expected.sum(1, keepdims=True)
    np.testing.assert_allclose(c2.weights.to_dense(), expected, atol=1e-6)
    # the apparel comes back from the physics alone
    np.testing.assert_array_equal(c2.apparel_bone_mask, c.apparel_bone_mask)
    _same_physics(bodies, bodies2)
    _same_physics(joints, joints2)


def test_zoo_export_pmx_brings_the_apparel_back(tmp_path):
    """``zoo --export pmx``: the apparel chains travel as rigid bodies and joints, and ingesting the
    file finds the same apparel bones and vertices."""
    from mimicbench.datagen.mmd.ingest import ingest_mmd
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import read_records

    build_zoo(tmp_path / "zoo", 2, seed=3, categories=["apparel"], clips_per_character=1, export=("pmx",),
              progress=False)
    zoo = {c.character_id.split("/", 1)[1]: c for c in read_records(tmp_path / "zoo", "characters")}
    files = sorted((tmp_path / "zoo" / "export").glob("*.pmx"))
    assert len(files) == 2
    out = ingest_mmd(files)
    assert [s.status for s in out.statuses] == ["ok", "ok"]
    for c in out.characters:
        src = zoo[c.character_id.split("/", 1)[1]]
        np.testing.assert_allclose(c.vertices, src.vertices, atol=2e-6)
        assert c.bone_names == src.bone_names
        np.testing.assert_array_equal(c.apparel_bone_mask, src.apparel_bone_mask)
        assert c.apparel_vertex_mask.sum() > 0
    dynamic = [b for b in out.rigid_bodies if b.mode == "dynamic"]
    assert len(dynamic) == sum(int(c.apparel_bone_mask.sum()) for c in out.characters)
    assert out.joints and all(j.body_a != j.body_b for j in out.joints)
