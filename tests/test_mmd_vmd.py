"""VMD motions: reading exactly, Bezier sampling against hand-computed values, CCD IK on a
two-bone leg, grants, and Gene_stand.vmd on Gene.pmx (facts from LICENSES.md)."""
from __future__ import annotations

import struct
from collections import Counter

import numpy as np
import pytest

from mimicbench.datagen.mmd.bezier import bezier_weight, control_points
from mimicbench.datagen.mmd.errors import MMDFormatError
from mimicbench.datagen.mmd.model import BONE_GRANT_ROTATION, IKChain, IKLink, MMDBone, MMDModel
from mimicbench.datagen.mmd.motion import match_bones, pose_clip, sample_channels
from mimicbench.datagen.mmd.pose import MMDPoser
from mimicbench.datagen.mmd.vmd import parse_vmd, read_vmd
from tests.mmd_fixtures import vmd_bytes


def _model(bones) -> MMDModel:
    z = np.zeros((0, 3), np.float32)
    return MMDModel("PMX 2.0", "t", "t", "", z, z, np.zeros(0, np.int8), np.zeros((0, 4), np.int32),
                    np.zeros((0, 4), np.float32), np.zeros((0, 3), np.int64), bones)


def test_gene_stand_facts(assets_dir):
    v = read_vmd(assets_dir / "mmd" / "Gene_stand.vmd")
    assert len(v.frames) == 470 and len(set(v.bone_names)) == 222
    assert (v.frames.min(), v.frames.max()) == (0, 120)
    assert len(v.morph_frames) == 184 and v.num_camera_keys == 0
    # "2 keys repeat the same bone and frame": 3 keys on one (bone, frame), 2 of them repeats
    assert sum(n - 1 for n in Counter(zip(v.bone_names, v.frames.tolist())).values()) == 2
    from mimicbench.datagen.mmd.pmx import read_pmx

    gene = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    names = {b.name for b in gene.bones}
    assert sum(n in names for n in set(v.bone_names)) == 221
    mapping, report = match_bones(v.bone_names, gene)
    assert report["unmatched"] == [] and report["matched_by_prefix"] == ["前クローク2_1xc"]


def test_quaternions_and_curves_kept_exactly():
    q = (np.float32(0.123456789), np.float32(-0.5), np.float32(0.1), np.float32(0.85))
    data = vmd_bytes([("センター", 3, (1.5, 2.25, -3.0), q, {3: (64, 0, 64, 127)})], [("あ", 5, 0.5)])
    v = parse_vmd(data, "x.vmd")
    assert v.rotations[0].tobytes() == struct.pack("<4f", *q)
    assert v.bone_names == ["センター"] and v.frames.tolist() == [3] and v.morph_names == ["あ"]
    np.testing.assert_array_equal(control_points(v.interpolation[0])[3], np.array([64, 0, 64, 127]) / 127)
    assert bytes(v.interpolation[0]) == data[30 + 20 + 4 + 15 + 4 + 28:][:64]


def test_bezier_hand_computed():
    # x1 = x2 = 0, y1 = y2 = 1: x(s) = s^3, y(s) = 1 - (1 - s)^3; at u = 1/8, s = 1/2, y = 7/8
    assert bezier_weight(0.125, 0, 1, 0, 1) == pytest.approx(0.875, abs=1e-9)
    # x1 = x2 = 1, y1 = y2 = 0: x(s) = 1 - (1 - s)^3, y(s) = s^3; at u = 7/8, s = 1/2, y = 1/8
    assert bezier_weight(0.875, 1, 0, 1, 0) == pytest.approx(0.125, abs=1e-9)
    # equal control coordinates: the identity
    np.testing.assert_allclose(bezier_weight(np.linspace(0, 1, 7), 0.3, 0.3, 0.8, 0.8), np.linspace(0, 1, 7), atol=1e-9)
    assert bezier_weight(0.0, 0.2, 0.9, 0.4, 0.1) == pytest.approx(0, abs=1e-9)
    assert bezier_weight(1.0, 0.2, 0.9, 0.4, 0.1) == pytest.approx(1, abs=1e-9)


def test_sampling_uses_the_later_keys_curve():
    bones = [MMDBone("センター", "", np.zeros(3, np.float32), -1)]
    ease = {0: (0, 127, 0, 127)}  # x channel: y = 1 - (1 - s)^3 with x = s^3
    data = vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {}), ("センター", 10, (10, 4, 0), (0, 0, 0, 1), ease),
                      ("センター", 10, (10, 4, 0), (0, 0, 0, 1), ease)])
    rot, trans, report = sample_channels(parse_vmd(data, "e.vmd"), _model(bones))
    s = 0.5 ** (1 / 3)  # x(s) = s^3 = u = 0.5
    assert trans[5, 0, 0] == pytest.approx(10 * (1 - (1 - s) ** 3), abs=1e-6)
    assert trans[5, 0, 1] == pytest.approx(2.0, abs=1e-6)  # y channel linear curve: u
    assert trans.shape == (11, 1, 3) and report["duplicate_keys"] == 1
    # rotation: slerp with the rotation curve's weight
    half = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])  # 90 degrees about z, as (x, y, z, w) below
    data = vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {}), ("センター", 4, (0, 0, 0), (0, 0, half[3], half[0]), {})])
    rot, _, _ = sample_channels(parse_vmd(data, "r.vmd"), _model(bones))
    np.testing.assert_allclose(rot[2, 0], [np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)], atol=1e-6)


def _leg():
    """MMD-frame leg: hip at y=10, knee at y=5 (slightly forward, -z), ankle at y=0; IK bone at the
    ankle; knee limited to x in [-pi, -0.5 deg] as MMD's standard knee."""
    hip = MMDBone("左足", "", np.array([0, 10, 0], np.float32), -1)
    knee = MMDBone("左ひざ", "", np.array([0, 5, -0.2], np.float32), 0)
    ankle = MMDBone("左足首", "", np.array([0, 0, 0], np.float32), 1)
    ik = MMDBone("左足ＩＫ", "", np.array([0, 0, 0], np.float32), -1)
    ik.ik = IKChain(2, 40, 2.0, [IKLink(1, np.array([-np.pi, 0, 0], np.float32), np.array([-np.radians(0.5), 0, 0], np.float32)),
                                 IKLink(0)])
    return _model([hip, knee, ankle, ik])


def test_ccd_leg_reaches_target_and_respects_knee_limit():
    m = _leg()
    p = MMDPoser(m)
    rot = np.tile([1.0, 0, 0, 0], (4, 1))
    for goal in ([0, 3, 1.0], [0.5, 2, -2.0], [1.0, 4, 0.5]):
        trans = np.zeros((4, 3))
        trans[3] = goal  # the IK bone moves from its rest position (the origin)
        R, t = p.evaluate(rot, trans)
        assert np.linalg.norm(t[2] - np.array(goal)) < 0.05, (goal, t[2])
        knee_local = R[0].T @ R[1]
        angle = np.arctan2(knee_local[2, 1], knee_local[2, 2])
        np.testing.assert_allclose(knee_local[:, 0], [1, 0, 0], atol=1e-9)  # the knee turns about x only
        assert -np.pi - 1e-9 <= angle <= -np.radians(0.5) + 1e-9


def test_grant_rotation_share():
    a = MMDBone("腕捩", "", np.zeros(3, np.float32), -1)
    b = MMDBone("腕捩連", "", np.array([1, 0, 0], np.float32), -1, flags=0x001A | BONE_GRANT_ROTATION,
                grant_parent=0, grant_ratio=0.5)
    c = MMDBone("逆", "", np.array([2, 0, 0], np.float32), -1, flags=0x001A | BONE_GRANT_ROTATION,
                grant_parent=0, grant_ratio=-0.25)
    p = MMDPoser(_model([a, b, c]))
    rot = np.tile([1.0, 0, 0, 0], (3, 1))
    rot[0] = [np.cos(0.4), np.sin(0.4), 0, 0]  # 0.8 rad about x
    R, _ = p.evaluate(rot, np.zeros((3, 3)))
    assert np.arctan2(R[1][2, 1], R[1][2, 2]) == pytest.approx(0.4)
    assert np.arctan2(R[2][2, 1], R[2][2, 2]) == pytest.approx(-0.2)


def test_hostile_vmd():
    good = vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {})])
    with pytest.raises(MMDFormatError, match="^bad.vmd: wrong magic"):
        parse_vmd(b"Vocaloid Motion Data 0003" + good[25:], "bad.vmd")
    with pytest.raises(MMDFormatError, match="^bad.vmd: .*truncated"):
        parse_vmd(good[:80], "bad.vmd")
    with pytest.raises(MMDFormatError, match="count of bone keys is 1000000"):
        parse_vmd(good[:50] + struct.pack("<I", 1000000) + good[54:], "bad.vmd")
    with pytest.raises(MMDFormatError, match="zero rotation"):
        parse_vmd(vmd_bytes([("a", 0, (0, 0, 0), (0, 0, 0, 0), {})]), "bad.vmd")
    with pytest.raises(MMDFormatError, match="non-finite"):
        parse_vmd(vmd_bytes([("a", 0, (float("inf"), 0, 0), (0, 0, 0, 1), {})]), "bad.vmd")
    rng = np.random.default_rng(3)
    for _ in range(200):
        b = bytearray(good)
        if rng.random() < 0.5:
            b = b[:int(rng.integers(0, len(b)))]
        else:
            b[int(rng.integers(0, len(b)))] ^= int(rng.integers(1, 256))
        try:
            parse_vmd(bytes(b), "fuzz.vmd")
        except MMDFormatError as e:
            assert str(e).startswith("fuzz.vmd")


@pytest.mark.slow
def test_gene_stand_plays_with_feet_on_the_ik_goals(assets_dir):
    from mimicbench.datagen.mmd.pmx import read_pmx

    gene = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    v = read_vmd(assets_dir / "mmd" / "Gene_stand.vmd")
    R, t, report = pose_clip(v, gene, 121)
    names = [b.name for b in gene.bones]
    for side in "左右":
        ankle, goal = names.index(f"{side}足首"), names.index(f"{side}足ＩＫ")
        gap = np.linalg.norm(t[:, ankle] - t[:, goal], axis=1) * 0.08
        rest_gap = np.linalg.norm(gene.bones[ankle].position - t[:, goal], axis=1) * 0.08
        assert gap.max() < 0.005 and rest_gap.min() > 0.02  # IK pulls the foot 2+ cm onto its goal
    assert np.isfinite(R).all() and report["duplicate_keys"] == 2


def test_rest_pose_evaluates_to_rest(assets_dir):
    from mimicbench.datagen.mmd.pmx import read_pmx

    gene = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    p = MMDPoser(gene)
    k = len(gene.bones)
    R, t = p.evaluate(np.tile([1.0, 0, 0, 0], (k, 1)), np.zeros((k, 3)))
    # Gene's leg IK goals sit 0.0005 units from the ankles at rest, so IK moves the legs that much
    np.testing.assert_allclose(t, p.rest, atol=1e-3)
    legs = {i for i, b in enumerate(gene.bones) if any(s in b.name for s in ("ひざ", "足首", "足先", "つま先"))}
    others = [i for i in range(k) if i not in legs]
    np.testing.assert_allclose(t[others], p.rest[others], atol=1e-5)
    np.testing.assert_allclose(R[others], np.tile(np.eye(3), (len(others), 1, 1)), atol=1e-6)


def test_motion_record_skins_like_mmd_in_the_dataset_frame():
    """The stored transforms, used by the dataset's linear blend skinning, give the vertices that
    MMD's own BDEF skinning gives in MMD's frame, mirrored and scaled (a small evaluator here)."""
    from mimicbench.datagen.mmd.motion import motion_from_vmd
    from mimicbench.datagen.mmd.pmx import parse_pmx
    from mimicbench.datagen.mmd.records import character_from_mmd
    from mimicbench.geometry.skinning import linear_blend_skinning
    from tests.mmd_fixtures import pmx_bytes

    m = parse_pmx(pmx_bytes(), "f.pmx")
    c = character_from_mmd(m, "f", "f.pmx", "train")
    q = (0.0, np.sin(0.3), 0.0, np.cos(0.3))  # 0.6 rad about y on センター, as (x, y, z, w)
    leg = (np.sin(0.2), 0.0, np.sin(0.1), np.sqrt(1 - np.sin(0.2) ** 2 - np.sin(0.1) ** 2))
    v = parse_vmd(vmd_bytes([("センター", 0, (0.5, -1, 2), q, {}), ("左足", 0, (0, 0, 0), leg, {}),
                             ("左足ＩＫ", 0, (0, 0, 0), (0, 0, 0, 1), {})]), "f.vmd")
    rec, _ = motion_from_vmd(v, m, c, "pose")
    R, t, _ = pose_clip(v, m, 1)
    # MMD's skinning in its own frame: v' = sum_k w_k (G_k (v - rest_k)) with G_k = (R_k, t_k)
    rest = np.array([b.position for b in m.bones], np.float64)
    mmd = np.zeros((len(m.positions), 3))
    for i, (p, bones, w) in enumerate(zip(m.positions, m.weight_bones, m.weight_values)):
        for b, wi in zip(bones, w):
            if b >= 0 and wi > 0:
                mmd[i] += wi * (R[0, b] @ (p - rest[b]) + t[0, b])
    ours = linear_blend_skinning(c.vertices, c.keypoints, c.weights, rec.transforms[0])
    np.testing.assert_allclose(ours, mmd * [0.08, 0.08, -0.08], atol=1e-5)


def test_show_ik_section_read_exactly_and_bounded():
    keys = [("センター", 0, (0, 0, 0), (0, 0, 0, 1), {})]
    ik = [(0, 1, [("左足ＩＫ", 1), ("右足ＩＫ", 1)]), (12, 1, [("左足ＩＫ", 0)]), (30, 0, [])]
    v = parse_vmd(vmd_bytes(keys, ik=ik), "ik.vmd")
    assert v.ik_frames.tolist() == [0, 12, 30] and v.num_shadow_keys == 0
    assert v.ik_states == [{"左足ＩＫ": True, "右足ＩＫ": True}, {"左足ＩＫ": False}, {}]
    assert parse_vmd(vmd_bytes(keys), "none.vmd").ik_states == []  # no section: every IK bone on
    data = vmd_bytes(keys, ik=ik)
    with pytest.raises(MMDFormatError, match="^ik.vmd: .*(truncated|show/IK)"):
        parse_vmd(data[:-5], "ik.vmd")
    with pytest.raises(MMDFormatError, match="IK flag 2"):
        parse_vmd(vmd_bytes(keys, ik=[(0, 1, [("左足ＩＫ", 2)])]), "ik.vmd")


def test_gene_stand_show_ik_section_names_its_six_ik_bones(assets_dir):
    v = read_vmd(assets_dir / "mmd" / "Gene_stand.vmd")
    # LICENSES.md: Gene has 6 IK chains; the clip's one show/IK key at frame 0 turns them all on
    assert v.ik_frames.tolist() == [0] and len(v.ik_states[0]) == 6 and all(v.ik_states[0].values())
    assert {"左足ＩＫ", "右足ＩＫ", "左つま先ＩＫ", "右つま先ＩＫ"} <= set(v.ik_states[0])


@pytest.mark.slow
def test_ik_off_keys_leave_the_leg_to_its_keys(assets_dir):
    from mimicbench.datagen.mmd.pmx import read_pmx

    gene = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    names = [b.name for b in gene.bones]
    ankle, goal = names.index("左足首"), names.index("左足ＩＫ")
    # the left foot's IK goal lifted 3 units and moved 2 back; IK on, off from frame 4, on from 7
    lift = [("左足ＩＫ", f, (0, 3, -2), (0, 0, 0, 1), {}) for f in (0, 10)]
    ik = [(0, 1, [("左足ＩＫ", 1)]), (4, 1, [("左足ＩＫ", 0)]), (7, 1, [("左足ＩＫ", 1), ("髪ＩＫ", 0)])]
    v = parse_vmd(vmd_bytes(lift, ik=ik), "lift.vmd")
    R, t, report = pose_clip(v, gene, 11)
    on = np.array([f < 4 or f >= 7 for f in range(11)])
    gap = np.linalg.norm(t[:, ankle] - t[:, goal], axis=1) * 0.08  # metres
    assert gap[on].max() < 0.01 and (np.linalg.norm(t[:, goal] - gene.bones[ankle].position, axis=1) > 3).all()
    # IK off: no key moves the leg, so the ankle stays where the rest pose has it
    np.testing.assert_allclose(t[~on, ankle], np.tile(gene.bones[ankle].position, (3, 1)), atol=1e-4)
    assert report["ik_keys"] == 3 and report["ik_off_frames"] == {"左足ＩＫ": 3}
    assert report["ik_unmatched"] == ["髪ＩＫ"]
