"""The cross-skeleton h2h ground truth: the source's local rotations carried through the hidden
roles onto a skeleton with other bones, checked by hand on small rigs."""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.protocols import answers
from mimicbench.benchmark.protocols.h2h_xskel import cross_skeleton_ground_truth
from mimicbench.geometry.kinematics import array_to_transforms, local_from_global
from mimicbench.geometry.quaternion import quat_angle
from tests.role_rigs import pose, t_pose_humanoid


def test_local_rotations_follow_the_roles_and_extra_bones_stay_at_rest():
    a, b = t_pose_humanoid("a"), t_pose_humanoid("b", extra_spine=True)
    src_t, _ = pose(a.rig, {a.names.index("l_fore"): ((0, 0, 1), 45), a.names.index("spine"): ((1, 0, 0), 20)},
                    root_shift=(0.0, 0.0, 0.5))
    gt = cross_skeleton_ground_truth(a.record, b.record, src_t)
    q_src, _ = array_to_transforms(src_t)
    q_gt, t_gt = array_to_transforms(gt)
    ls, lt = local_from_global(q_src, a.rig.parents), local_from_global(q_gt, b.rig.parents)
    assert quat_angle(lt[b.names.index("l_fore")], ls[a.names.index("l_fore")]) < 1e-6  # float32 transforms
    assert quat_angle(lt[b.names.index("spine")], ls[a.names.index("spine")]) < 1e-6  # float32 transforms
    # chest (spine/2) has no such role in a: by class and depth it is driven by a's only spine bone
    assert np.degrees(quat_angle(lt[b.names.index("chest")], ls[a.names.index("spine")])) < 1e-6
    # the root moves by the source's displacement times the size ratio (largest extents)
    ratio = np.ptp(b.rig.vertices, axis=0).max() / np.ptp(a.rig.vertices, axis=0).max()
    np.testing.assert_allclose(t_gt[0] - b.rig.keypoints[0], np.array([0, 0, 0.5]) * ratio, atol=1e-6)


def test_methods_that_answer_h2h_answer_the_cross_skeleton_protocol():
    assert answers(("h2h", "cct"), "h2h_xskel")
    assert not answers(("cct",), "h2h_xskel")
    assert not answers(("h2h",), "cct")
