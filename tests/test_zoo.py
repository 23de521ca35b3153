"""The 40-character zoo end to end: CLI, validate, determinism, coverage, rigs, clips, LBS.

One build is shared by the module (about 10 s here); a second build checks byte-identical shards.
"""
import hashlib
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from mimicbench.datagen.zoo.templates.humanoid import H2H_SKELETON_ID
from mimicbench.cli import main
from mimicbench.geometry.kinematics import array_to_transforms, forward_kinematics, local_from_global, rest_transforms
from mimicbench.geometry.mesh import edge_lengths, unique_edges
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.character import CATEGORIES
from mimicbench.schemas.shards import read_records

pytestmark = pytest.mark.slow

MAX_STRETCH = 3.0  # no mesh edge may get longer than 3x its rest length in any frame of any clip


@pytest.fixture(scope="module")
def zoo(tmp_path_factory):
    out = tmp_path_factory.mktemp("zoo40") / "zoo"
    assert main(["zoo", "--out", str(out), "--characters", "40", "--seed", "0", "--quiet"]) == 0
    chars = read_records(out, "characters")
    motions = read_records(out, "motions")
    return out, chars, motions


def _shard_hashes(root: Path) -> dict:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.glob("*/*.parquet"))}


def test_validate_passes(zoo, capsys):
    out, _, _ = zoo
    assert main(["validate", str(out)]) == 0
    assert "OK" in capsys.readouterr().out
    card = (out / "CARD.md").read_text()
    assert "| humanoid |" in card and "joints min / mean / max" in card


def test_same_command_gives_byte_identical_shards(zoo, tmp_path):
    out, _, _ = zoo
    again = tmp_path / "zoo"
    assert main(["zoo", "--out", str(again), "--characters", "40", "--seed", "0", "--quiet"]) == 0
    first, second = _shard_hashes(out), _shard_hashes(again)
    assert first and first == second
    assert (out / "CARD.md").read_bytes() == (again / "CARD.md").read_bytes()


def test_coverage_sizes_and_h2h_family(zoo):
    _, chars, _ = zoo
    assert len(chars) == 40
    cats = {c.category for c in chars}
    assert cats == {"humanoid", "quadruped", "bird", "fish", "reptile", "insect", "apparel"}
    assert cats <= set(CATEGORIES)
    joints = [c.num_joints for c in chars]
    assert min(joints) <= 15 and max(joints) >= 150
    family = [c for c in chars if c.skeleton_id == H2H_SKELETON_ID]
    assert len(family) >= 8
    ref = family[0]
    for c in family:
        assert c.category == "humanoid"
        assert c.bone_names == ref.bone_names and np.array_equal(c.parents, ref.parents)
        assert c.bone_roles == ref.bone_roles
    # different proportions, same rest orientation (T-pose: arm bones horizontal)
    heights = {round(c.height, 3) for c in family}
    assert len(heights) == len(family)
    for c in family:
        ua, fa = c.bone_roles.index("left/upper_arm"), c.bone_roles.index("left/forearm")
        d = c.keypoints[fa] - c.keypoints[ua]
        assert abs(d[1]) < 1e-4 and d[0] > 0
    assert sum(c.split == "test" for c in family) >= 3
    ids = [c.character_id for c in chars]
    assert all(re.fullmatch(r"zoo/(humanoid|quadruped|bird|fish|reptile|insect|apparel)-\d{4}", i) for i in ids)


def test_bone_name_styles(zoo):
    _, chars, _ = zoo
    names = {n for c in chars for n in c.bone_names}
    for expected in ("mixamorig:LeftArm", "upper_arm.L", "Bip01 L UpperArm"):
        assert expected in names
    assert any(re.fullmatch(r"b_LeftUpperArm_\d\d", n) for n in names)
    assert any(re.fullmatch(r"Wing(\.\d{3})?\.L", n) for n in names)
    assert any(re.fullmatch(r"wing_l_\d\d", n) for n in names)
    assert any(re.fullmatch(r"FrontLeg\d\.R", n) for n in names)
    assert any(re.fullmatch(r"Tail\d\d", n) for n in names)
    for c in chars:
        assert len(set(c.bone_names)) == c.num_joints
        assert c.bone_roles is not None and len(c.bone_roles) == c.num_joints


def test_meshes_closed_nondegenerate_and_large(zoo):
    _, chars, _ = zoo
    for c in chars:
        assert len(c.faces) > 5000, c.character_id
        f = c.faces
        assert (f[:, 0] != f[:, 1]).all() and (f[:, 1] != f[:, 2]).all() and (f[:, 0] != f[:, 2]).all()
        m = trimesh.Trimesh(c.vertices, f, process=False)
        assert m.area_faces.min() > 1e-9 * c.height ** 2, c.character_id
        assert m.is_watertight and m.is_winding_consistent, c.character_id
        assert np.isclose(c.height, np.ptp(c.vertices[:, 1]))
        assert np.all(c.parents < np.arange(c.num_joints)) and (c.parents < 0).sum() == 1


def test_weight_invariants(zoo):
    _, chars, _ = zoo
    for c in chars:
        v = c.weight_values.astype(np.float64)
        assert c.weight_indices.shape == (len(c.vertices), 8)
        assert np.allclose(v.sum(1), 1.0, atol=1e-5), c.character_id
        assert (v >= 0).all() and ((v > 0).sum(1) >= 1).all() and ((v > 0).sum(1) <= 8).all()
        assert c.weight_indices.min() >= 0 and c.weight_indices.max() < c.num_joints
        owned = np.zeros(c.num_joints, bool)
        owned[np.unique(c.weight_indices[v > 0])] = True
        assert owned.all(), f"{c.character_id}: joints without any weight"


def test_apparel_mask_nonempty_exactly_for_apparel(zoo):
    _, chars, _ = zoo
    for c in chars:
        is_apparel = c.category == "apparel"
        assert bool(c.apparel_vertex_mask.any()) == is_apparel, c.character_id
        assert bool(c.apparel_bone_mask.any()) == is_apparel, c.character_id
        if is_apparel:
            dense = c.weights.to_dense()
            # apparel vertices are those driven by apparel bones; body vertices never are
            assert np.all(dense[~c.apparel_vertex_mask][:, c.apparel_bone_mask] == 0)
            assert np.all(dense[c.apparel_vertex_mask][:, c.apparel_bone_mask].sum(1) > 0)
            roles = [r for r, a in zip(c.bone_roles, c.apparel_bone_mask) if a]
            assert all(r.startswith("apparel/") for r in roles)


def test_clips_rest_start_fps_and_fk(zoo):
    _, chars, motions = zoo
    by_char = {}
    for m in motions:
        by_char.setdefault(m.character_id, []).append(m)
    for c in chars:
        clips = by_char[c.character_id]
        assert len(clips) >= 3
        for m in clips:
            assert m.fps == 30 and m.num_joints == c.num_joints and m.transforms.shape == (m.num_frames, c.num_joints, 7)
            assert np.allclose(m.transforms[0], rest_transforms(c.keypoints), atol=1e-5), m.motion_id
            q, t = array_to_transforms(m.transforms)
            local = local_from_global(q, c.parents)
            _, pos = forward_kinematics(local, c.keypoints, c.parents, t)
            assert np.abs(pos - t).max() < 1e-4, m.motion_id  # positions are FK of the rotations


def test_lbs_of_every_clip_is_finite_without_stretched_edges(zoo):
    _, chars, motions = zoo
    cmap = {c.character_id: c for c in chars}
    worst = 0.0
    for m in motions:
        c = cmap[m.character_id]
        edges = unique_edges(c.faces)
        rest = edge_lengths(c.vertices, edges)
        for f0 in range(0, m.num_frames, 9):
            posed = linear_blend_skinning(c.vertices, c.keypoints, c.weights, m.transforms[f0:f0 + 9])
            assert np.isfinite(posed).all(), m.motion_id
            for v in posed:
                ratio = float((edge_lengths(v, edges) / rest).max())
                worst = max(worst, ratio)
                assert ratio <= MAX_STRETCH, f"{m.motion_id} frame {f0}: an edge stretched {ratio:.2f}x"
    assert worst > 1.0  # the clips do deform the meshes
