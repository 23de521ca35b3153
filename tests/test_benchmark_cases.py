import shutil

import numpy as np
import pytest

from mimicbench.benchmark.cases import build_cases, write_cases
from mimicbench.benchmark.normalisation import size_ratio
from mimicbench.benchmark.protocols.h2h import ground_truth_transforms, local_translations
from mimicbench.geometry.kinematics import array_to_transforms, local_from_global
from mimicbench.geometry.quaternion import quat_angle, quat_apply
from mimicbench.schemas.shards import read_records
from mimicbench.schemas.validate import validate_dataset
from tests.family_fixtures import add_family

HUMAN = ("humanoid", "apparel")


def test_cases_are_deterministic_and_cover_both_directions(small_zoo, tmp_path):
    a = build_cases(small_zoo, "test", cct_pairs=40, cct_poses=2)
    b = build_cases(small_zoo, "test", cct_pairs=40, cct_poses=2)
    assert [c.case_id for c in a["h2h"]] == [c.case_id for c in b["h2h"]] and a["h2h"]
    assert [c.case_id for c in a["cct"]] == [c.case_id for c in b["cct"]]
    assert any(c.source_category in HUMAN and c.target_category not in HUMAN for c in a["cct"])
    assert any(c.source_category not in HUMAN and c.target_category in HUMAN for c in a["cct"])
    assert all((c.source_category in HUMAN) != (c.target_category in HUMAN) for c in a["cct"])
    assert all(c.frame > 0 for c in a["h2h"] + a["cct"])
    # a protocol's cases do not depend on which other protocols are built
    only = build_cases(small_zoo, "test", cct_pairs=40, cct_poses=2, protocols=("cct",))
    assert [c.case_id for c in only["cct"]] == [c.case_id for c in a["cct"]]
    ds = tmp_path / "ds"
    shutil.copytree(small_zoo, ds)
    write_cases(ds, a, {"test": True})
    assert validate_dataset(ds) == []
    assert len(read_records(ds, "cases", "h2h")) == len(a["h2h"])


def test_all_pairs_means_every_pair_across_splits(small_zoo):
    cases = build_cases(small_zoo, "test", all_pairs=True, h2h_poses=1, cct_poses=1)
    chars = [c for c in read_records(small_zoo, "characters") if len(c.faces)]
    animated = {m.character_id for m in read_records(small_zoo, "motions")}
    split = {c.character_id: c.split for c in chars}
    # independent enumeration: ordered pairs of distinct characters of any split
    want_h2h = {(a.character_id, b.character_id) for a in chars for b in chars
                if a is not b and a.skeleton_id and a.skeleton_id == b.skeleton_id and a.character_id in animated}
    want_cct = {(a.character_id, b.character_id) for a in chars for b in chars
                if (a.category in HUMAN) != (b.category in HUMAN) and a.character_id in animated}
    got = {p: {(c.source_id, c.target_id) for c in cs} for p, cs in cases.items()}
    assert got["h2h"] == want_h2h and got["cct"] == want_cct
    assert any(split[s] != split[t] for s, t in got["cct"]), "expected pairs across splits"
    assert len(cases["cct"]) == len(want_cct)  # one pose per pair


def test_same_skeleton_cases_for_any_category(small_zoo, tmp_path):
    data, base, _ = add_family(small_zoo, tmp_path / "d", "quadruped", {"zoo/zebra-copy": 1.0, "zoo/foal": 0.6})
    h2h = build_cases(data, "all", h2h_pairs=None, h2h_poses=2)["h2h"]
    pairs = {(c.source_id, c.target_id) for c in h2h}
    assert {(base, "zoo/zebra-copy"), (base, "zoo/foal")} <= pairs
    assert {c.source_category for c in h2h} >= {"humanoid", "quadruped"}


def test_ground_truth_on_a_copy_is_the_source_pose_and_scales_with_size(small_zoo, tmp_path):
    data, base, moved = add_family(small_zoo, tmp_path / "d", "reptile", {"zoo/twin": 1.0, "zoo/big": 1.5})
    chars = {c.character_id: c for c in read_records(data, "characters")}
    clip = next(m for m in read_records(data, "motions") if m.character_id == base and m.name.endswith("-ik"))
    src = chars[base]
    batched = local_translations(clip.transforms, src.keypoints, src.parents)  # (F, K, 3) at once
    assert batched.shape == (clip.num_frames, len(src.parents), 3)
    for f in range(1, clip.num_frames, 7):
        np.testing.assert_allclose(batched[f], local_translations(clip.transforms[f], src.keypoints, src.parents))
        pose = clip.transforms[f]
        q, t = array_to_transforms(pose)
        # the clip translates non-root bones: rotations and the root alone do not give it back
        assert np.abs(local_translations(pose, src.keypoints, src.parents)[moved]).max() > 1e-3
        twin = ground_truth_transforms(src, chars["zoo/twin"], pose)
        np.testing.assert_allclose(twin, pose, atol=2e-5)
        # scaled about the origin by 1.5: same rotations, every position 1.5 times as far
        big = ground_truth_transforms(src, chars["zoo/big"], pose)
        qb, tb = array_to_transforms(big)
        assert quat_angle(qb, q).max() < 1e-4
        np.testing.assert_allclose(tb, 1.5 * t, atol=5e-5)


def test_ground_truth_copies_local_rotations_and_translations_by_hand(small_zoo, tmp_path):
    data, base, moved = add_family(small_zoo, tmp_path / "d", "humanoid", {}, shared=True)
    chars = {c.character_id: c for c in read_records(data, "characters")}
    clip = next(m for m in read_records(data, "motions") if m.character_id == base and m.name.endswith("-ik"))
    fam = [c for c in chars.values() if c.skeleton_id == chars[base].skeleton_id]
    s = chars[base]
    t_char = next(c for c in fam if c.character_id != base and np.ptp(c.vertices[:, 1]) != np.ptp(s.vertices[:, 1]))
    pose = clip.transforms[clip.num_frames // 2]
    gt = ground_truth_transforms(s, t_char, pose)
    qs, ts = array_to_transforms(pose)
    qt, tt = array_to_transforms(gt)
    assert quat_angle(local_from_global(qs, s.parents), local_from_global(qt, t_char.parents)).max() < 1e-5
    ratio = np.ptp(t_char.vertices, axis=0).max() / np.ptp(s.vertices, axis=0).max()
    assert np.isclose(size_ratio(s.vertices, t_char.vertices), ratio)
    # bone by bone, in words: the target's offset from its parent is its own rest offset plus the
    # source's extra offset scaled by the ratio, both turned by the parent's rotation
    for k, p in enumerate(s.parents):
        if p < 0:
            np.testing.assert_allclose(tt[k] - t_char.keypoints[k], (ts[k] - s.keypoints[k]) * ratio, atol=1e-5)
            continue
        extra_src = quat_apply(qs[p] * [1, -1, -1, -1], ts[k] - ts[p]) - (s.keypoints[k] - s.keypoints[p])
        want = tt[p] + quat_apply(qt[p], t_char.keypoints[k] - t_char.keypoints[p] + ratio * extra_src)
        np.testing.assert_allclose(tt[k], want, atol=1e-5)
    # bones the clip does not translate keep the target's own bone lengths
    still = [k for k in range(len(s.parents)) if s.parents[k] >= 0 and
             np.abs(local_translations(pose, s.keypoints, s.parents)[k]).max() < 1e-5]
    assert still and np.allclose(np.linalg.norm(tt[still] - tt[s.parents[still]], axis=1),
                                 np.linalg.norm(t_char.keypoints[still] - t_char.keypoints[s.parents[still]], axis=1),
                                 atol=1e-5)


def test_ground_truth_refuses_different_skeletons(small_zoo):
    chars = read_records(small_zoo, "characters")
    a = next(c for c in chars if c.category == "bird")
    b = next(c for c in chars if c.category == "fish")
    with pytest.raises(ValueError, match="do not share a skeleton"):
        ground_truth_transforms(a, b, np.zeros((len(a.parents), 7), np.float32))


def test_cases_read_their_poses_from_the_motions_table_and_the_pool_holds_no_transforms(small_zoo):
    """The pool keeps clip IDs and lengths only; each case's source pose is read back by
    streaming the motions table. Checked against every motion loaded whole."""
    from mimicbench.benchmark.protocols.base import CasePool, MotionInfo

    pool = CasePool.load(small_zoo, "all")
    infos = [m for ms in pool.motions.values() for m in ms]
    assert infos and all(type(m) is MotionInfo and not hasattr(m, "transforms") for m in infos)
    cases = build_cases(small_zoo, "all", h2h_pairs=6, h2h_poses=3, cct_pairs=8, cct_poses=2)
    whole = {m.motion_id: m for m in read_records(small_zoo, "motions")}
    checked = 0
    for c in cases["h2h"] + cases["cct"]:
        m = whole[c.motion_id]
        assert c.case_id.endswith(f"/{m.name}#{c.frame}") and m.character_id == c.source_id
        np.testing.assert_array_equal(np.asarray(c.source_transforms).reshape(-1, 7),
                                      np.asarray(m.transforms[c.frame]).reshape(-1, 7))
        checked += 1
    assert checked == len(cases["h2h"]) + len(cases["cct"]) > 10
