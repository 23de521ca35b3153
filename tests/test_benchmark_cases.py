import shutil

import numpy as np

from benchmark.cases import build_cases, h2h_target_transforms, write_cases
from mimicbench.kinematics import array_to_transforms, forward_kinematics, local_from_global
from mimicbench.quaternion import quat_angle
from schemas.shards import read_records
from schemas.validate import validate_dataset


def test_cases_are_deterministic_and_cover_both_directions(small_zoo, tmp_path):
    a = build_cases(small_zoo, "test", cct_pairs=40, cct_poses=2)
    b = build_cases(small_zoo, "test", cct_pairs=40, cct_poses=2)
    assert [c.case_id for c in a["h2h"]] == [c.case_id for c in b["h2h"]] and a["h2h"]
    assert [c.case_id for c in a["cct"]] == [c.case_id for c in b["cct"]]
    human = ("humanoid", "apparel")
    assert any(c.source_category in human and c.target_category not in human for c in a["cct"])
    assert any(c.source_category not in human and c.target_category in human for c in a["cct"])
    assert all((c.source_category in human) != (c.target_category in human) for c in a["cct"])
    assert all(c.frame > 0 for c in a["h2h"] + a["cct"])
    ds = tmp_path / "ds"
    shutil.copytree(small_zoo, ds)
    write_cases(ds, a, {"test": True})
    assert validate_dataset(ds) == []
    assert len(read_records(ds, "cases", "h2h")) == len(a["h2h"])


def test_h2h_ground_truth_copies_local_rotations_and_scales_root(small_zoo):
    chars = {c.character_id: c for c in read_records(small_zoo, "characters")}
    case = build_cases(small_zoo, "test", h2h_poses=2)["h2h"][0]
    s, t = chars[case.source_id], chars[case.target_id]
    gt = h2h_target_transforms(s, t, case.source_transforms)
    qs, ts = array_to_transforms(case.source_transforms)
    qt, tt = array_to_transforms(gt)
    assert quat_angle(local_from_global(qs, s.parents), local_from_global(qt, t.parents)).max() < 1e-5
    hs = np.ptp(s.vertices[:, 1]); ht = np.ptp(t.vertices[:, 1])
    root = int(np.flatnonzero(s.parents < 0)[0])
    np.testing.assert_allclose(tt[root] - t.keypoints[root], (ts[root] - s.keypoints[root]) * ht / hs, atol=1e-5)
    # joint positions follow the target's own bone lengths
    _, pos = forward_kinematics(local_from_global(qt, t.parents), t.keypoints, t.parents, tt)
    np.testing.assert_allclose(pos, tt, atol=1e-5)
