"""The semantic agreement score (benchmark/semantic.py) on small labelled rigs, against values
worked out by hand: a whole arm turned by 90 degrees about its shoulder swings its direction by 90."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.benchmark.semantic import (character_role_classes, part_motion, part_regions, semantic_disagreement,
                                semantic_scores, shortest_rotation)
from tests.role_rigs import pose, quadruped, t_pose_humanoid


def motion(char, posed):
    classes = character_role_classes(char.record)
    return part_motion(char.rig.vertices, posed, part_regions(char.rig.weights, char.rig.parents, classes))


def test_shortest_rotation_by_hand():
    np.testing.assert_allclose(shortest_rotation(np.array([1.0, 0, 0]), np.array([0, 0, 1.0])),
                               [0, -np.pi / 2, 0], atol=1e-12)
    assert np.linalg.norm(shortest_rotation(np.array([0, 1.0, 0]), np.array([0, -1.0, 0]))) == pytest.approx(np.pi)


def test_the_same_motion_scores_zero_and_the_target_at_rest_scores_the_source_swing():
    h = t_pose_humanoid()
    l_arm = h.names.index("l_arm")
    _, posed = pose(h.rig, {l_arm: ((0, 1, 0), -90)})  # the left arm swung from +x to +z: forward
    src = motion(h, posed)
    assert np.degrees(np.linalg.norm(src.swings["left/forelimb"])) == pytest.approx(90, abs=1e-6)
    same = semantic_scores(src, motion(h, posed))
    assert same["semantic_deg"] == pytest.approx(0, abs=1e-9)
    # parts scored: body, head, both forelimbs, both hindlimbs
    assert same["role_classes_scored"] == 6
    rest = semantic_scores(src, motion(h, h.rig.vertices))
    assert rest["semantic_deg"] == pytest.approx(90 / 6, abs=1e-6)


def test_a_mirrored_transfer_scores_worse_than_the_target_at_rest():
    h = t_pose_humanoid()
    _, posed = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -90)})
    _, mirrored = pose(h.rig, {h.names.index("r_arm"): ((0, 1, 0), 90)})  # the right arm forward instead
    src = motion(h, posed)
    parts = semantic_disagreement(src, motion(h, mirrored))
    assert parts["left/forelimb"] == pytest.approx(90, abs=1e-6)
    assert parts["right/forelimb"] == pytest.approx(90, abs=1e-6)
    assert semantic_scores(src, motion(h, mirrored))["semantic_deg"] > semantic_scores(src, motion(h, h.rig.vertices))[
        "semantic_deg"]


def test_an_arm_raised_forward_agrees_with_a_foreleg_raised_forward():
    h, d = t_pose_humanoid(), quadruped()
    _, arm_fwd = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -90)})  # +x -> +z
    _, leg_fwd = pose(d.rig, {d.names.index("l_front"): ((1, 0, 0), -90)})  # -y -> +z
    _, leg_back = pose(d.rig, {d.names.index("l_front"): ((1, 0, 0), 90)})  # -y -> -z
    parts = semantic_disagreement(motion(h, arm_fwd), motion(d, leg_fwd))
    assert parts["left/forelimb"] == pytest.approx(0, abs=1e-6)
    parts_back = semantic_disagreement(motion(h, arm_fwd), motion(d, leg_back))
    assert parts_back["left/forelimb"] == pytest.approx(180, abs=1e-6)


def test_the_body_frame_removes_a_turn_of_the_whole_body():
    h = t_pose_humanoid()
    hips = h.names.index("hips")
    _, turned = pose(h.rig, {hips: ((0, 1, 0), 40)})
    m = motion(h, turned)
    assert all(np.linalg.norm(w) < 1e-6 for w in m.swings.values())
    parts = semantic_disagreement(motion(h, h.rig.vertices), m)
    assert parts["body"] == pytest.approx(40, abs=1e-4)  # float32 vertices


def test_a_character_without_labels_has_no_classes():
    h = t_pose_humanoid()
    h.record.bone_roles = None
    assert character_role_classes(h.record) is None
    h.record.bone_roles = [""] * len(h.names)
    assert character_role_classes(h.record) is None
