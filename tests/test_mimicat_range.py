"""MimiCAT's range model: nearest point on a hull, the projection of a pose into predicted ranges
(checked with the evaluator's own excess), fit / predict / save / load on a toy leg."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.baselines.mimicat.range_model import (PredictedRanges, RangeModel, bone_features, nearest_on_hull_2d,
                                                      project_pose)
from mimicbench.benchmark.motion_range import BoneRanges, convex_hull_2d, ranges_for_clips
from mimicbench.benchmark.request import Rig
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_angle, quat_from_axis_angle, quat_multiply
from mimicbench.schemas.weights import SparseWeights

X, Y, Z = np.eye(3)


def leg(character_id: str = "toy/leg", scale: float = 1.0) -> Rig:
    """pelvis -> thigh -> shin -> foot hanging down -Y, each bone a rigid tetrahedron below its keypoint."""
    kp = np.array([[0, 2.2, 0], [0, 2, 0], [0, 1, 0], [0, 0, 0]], np.float32) * scale
    tet = np.array([[0.1, -0.1, 0], [0, -0.3, 0.1], [-0.1, -0.2, 0], [0, -0.15, -0.1]]) * scale
    verts = np.concatenate([k + tet for k in kp]).astype(np.float32)
    w = np.kron(np.eye(4), np.ones((4, 1)))
    faces = np.array([[4 * b, 4 * b + 1, 4 * b + 2] for b in range(4)], np.int32)
    return Rig(character_id, "humanoid", verts, faces, kp, np.array([-1, 0, 1, 2], np.int32),
               SparseWeights.from_dense(w), ("pelvis", "thigh", "shin", "foot"))


def rot(axis, degrees):
    return quat_from_axis_angle(np.asarray(axis, float), np.radians(degrees))


def hinge_clip(rig: Rig, n: int = 19) -> np.ndarray:
    """Transforms (n, 4, 7): the shin bends forward about x from 0 to 90 degrees, nothing else moves."""
    local = np.tile([1.0, 0, 0, 0], (n, 4, 1))
    for i in range(n):
        local[i, 2] = rot(X, 90.0 * i / (n - 1))
    q, t = forward_kinematics(local, rig.keypoints, rig.parents)
    return transforms_to_array(q, t)


def test_nearest_on_hull_by_hand():
    square = convex_hull_2d(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    assert np.allclose(nearest_on_hull_2d(square, [0.5, 0.25]), [0.5, 0.25])
    assert np.allclose(nearest_on_hull_2d(square, [2.0, 0.5]), [1.0, 0.5])
    assert np.allclose(nearest_on_hull_2d(square, [-1.0, -3.0]), [0.0, 0.0])
    segment = np.array([[0.0, 0.0], [2.0, 0.0]])
    assert np.allclose(nearest_on_hull_2d(segment, [1.0, 1.0]), [1.0, 0.0])
    assert np.allclose(nearest_on_hull_2d(segment, [3.0, -1.0]), [2.0, 0.0])
    assert np.allclose(nearest_on_hull_2d(np.array([[0.3, 0.4]]), [5.0, 5.0]), [0.3, 0.4])


@pytest.fixture(scope="module")
def hinge():
    rig = leg()
    ranges = ranges_for_clips(rig.character_id, rig, [hinge_clip(rig)])
    predicted = PredictedRanges(ranges, ranges.hulls, np.array([_arc(ranges, k) for k in range(4)]))
    return rig, ranges, predicted


def _arc(ranges: BoneRanges, k: int):
    from mimicbench.benchmark.motion_range import _twist_arc

    return _twist_arc(ranges.twist[k])


def _pose(shin_local, thigh_local=None):
    local = np.tile([1.0, 0, 0, 0], (4, 1))
    local[2] = shin_local
    if thigh_local is not None:
        local[1] = thigh_local
    return local


@pytest.mark.parametrize("slack", [0.0, 5.0])
def test_projection_lands_slack_degrees_outside_the_range(hinge, slack):
    rig, ranges, predicted = hinge
    # the shin bent 40 degrees backwards (the hinge reaches 0..90 forwards) and twisted 30 degrees
    shin = quat_multiply(rot(X, -40.0), rot(-Y, 30.0))
    q, t = forward_kinematics(_pose(shin), rig.keypoints, rig.parents)
    before = ranges.excess_degrees(q)
    assert before[2] > 30
    q2, t2 = project_pose(q, t, rig.parents, predicted, slack)
    after = ranges.excess_degrees(q2)
    assert after[2] == pytest.approx(slack, abs=1e-6)
    # the foot keeps its local rotation (identity relative to the shin) and its offset in the shin's frame
    assert quat_angle(q2[2], q2[3]) == pytest.approx(0.0, abs=1e-6)
    expect = t2[2] + _apply(q2[2], rig.keypoints[3] - rig.keypoints[2])
    assert np.allclose(t2[3], expect, atol=1e-9)
    assert np.allclose(q2[:2], q[:2]) and np.allclose(t2[:3], t[:3])


def _apply(q, v):
    from mimicbench.geometry.quaternion import quat_apply

    return quat_apply(np.asarray(q, float), np.asarray(v, float))


def test_a_pose_inside_the_range_is_left_alone(hinge):
    rig, ranges, predicted = hinge
    q, t = forward_kinematics(_pose(rot(X, 60.0)), rig.keypoints, rig.parents)
    q2, t2 = project_pose(q, t, rig.parents, predicted, 5.0)
    assert np.allclose(q2, q, atol=1e-12) and np.allclose(t2, t, atol=1e-12)


def test_parts_move_only_what_they_say(hinge):
    rig, ranges, predicted = hinge
    shin = quat_multiply(rot(X, -40.0), rot(-Y, 30.0))
    q, t = forward_kinematics(_pose(shin), rig.keypoints, rig.parents)
    swing_only, _ = project_pose(q, t, rig.parents, predicted, 0.0, parts="swing")
    twist_only, _ = project_pose(q, t, rig.parents, predicted, 0.0, parts="twist")
    from mimicbench.benchmark.motion_range import swing_twist

    s0, tau0 = swing_twist(ranges.local_rotations(q), ranges.axes, ranges.basis)
    s1, tau1 = swing_twist(ranges.local_rotations(swing_only), ranges.axes, ranges.basis)
    s2, tau2 = swing_twist(ranges.local_rotations(twist_only), ranges.axes, ranges.basis)
    assert tau1[2] == pytest.approx(tau0[2]) and np.degrees(np.linalg.norm(s1[2])) == pytest.approx(0.0, abs=1e-6)
    assert np.allclose(s2[2], s0[2]) and np.degrees(tau2[2]) == pytest.approx(predicted.arcs[2][1], abs=1e-6)


def test_fit_predict_and_round_trip(tmp_path):
    a, b = leg("toy/a"), leg("toy/b", scale=1.5)
    ranges = {c.character_id: ranges_for_clips(c.character_id, c, [hinge_clip(c)]) for c in (a, b)}
    model = RangeModel.fit({"toy/a": a, "toy/b": b}, ranges, k=1, slack_deg=5.0)
    assert len(model.features) == 6  # thigh, shin, foot of each leg: the bones with a reference
    # the same shape at another size has the same features, so its nearest bones are its twin's
    assert np.allclose(bone_features(a), bone_features(b))
    pred = model.predict(leg("toy/c", scale=0.5))
    for k in (1, 2, 3):
        assert np.allclose(pred.hulls[k], ranges["toy/a"].hulls[k], atol=1e-6)
    assert pred.arcs[2] == pytest.approx(_arc(ranges["toy/a"], 2))
    model.save(tmp_path / "range.safetensors")
    back = RangeModel.load(tmp_path / "range.safetensors")
    assert back.k == 1 and back.slack_deg == 5.0 and back.parts == "both"
    assert np.array_equal(back.twist, model.twist) and np.array_equal(back.characters, model.characters)
    assert np.allclose(back.hull_points, model.hull_points)
    excluded = back.predict(a, exclude="toy/a")  # leave-one-out: only toy/b's bones remain
    for k in (1, 2, 3):
        assert np.allclose(excluded.hulls[k], ranges["toy/b"].hulls[k], atol=1e-6)


def test_load_refuses_another_file(tmp_path):
    from safetensors.numpy import save_file

    save_file({"x": np.zeros(2, np.float32)}, str(tmp_path / "other.safetensors"), metadata={"format": "x"})
    with pytest.raises(ValueError, match="mimicat-range"):
        RangeModel.load(tmp_path / "other.safetensors")
    with pytest.raises(FileNotFoundError, match="fit one"):
        RangeModel.load(tmp_path / "missing.safetensors")


def test_interpolate_free_shares_the_turn_by_hand():
    from mimicbench.baselines.mimicat.range_model import interpolate_free

    # 0 -> 1 -> 2 -> 3 and 1 -> 4: bones 0 and 3 fixed, 1 and 2 free, 4 a free leaf with no fixed descendant
    parents = np.array([-1, 0, 1, 2, 1])
    q = np.stack([rot(Z, 0.0), rot(Z, 0.0), rot(Z, 0.0), rot(Z, 90.0), rot(X, 10.0)])
    out = interpolate_free(q, parents, np.array([True, False, False, True, False]))
    for k, deg in ((0, 0.0), (1, 30.0), (2, 60.0), (3, 90.0)):
        assert quat_angle(out[k], rot(Z, deg)) == pytest.approx(0.0, abs=1e-9), k
    assert np.allclose(out[4], q[4])
    # every bone fixed, or none: nothing moves
    assert np.allclose(interpolate_free(q, parents, np.ones(5, bool)), q)
    assert np.allclose(interpolate_free(q, parents, np.zeros(5, bool)), q)


def test_refine_free_keeps_matched_bones_and_offsets(hinge):
    from mimicbench.baselines.mimicat.range_model import refine_free

    rig, ranges, predicted = hinge
    # thigh fixed, shin free and bent backwards out of its hinge, foot fixed
    local = _pose(rot(X, -40.0))
    q, t = forward_kinematics(local, rig.keypoints, rig.parents)
    fixed = np.array([True, True, False, True])
    q2, t2 = refine_free(q, t, rig.parents, fixed, None, 0.0)
    # the shin shares the turn from the thigh (identity) to the foot (-40 degrees about x): -20
    assert quat_angle(q2[2], rot(X, -20.0)) == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(q2[fixed], q[fixed])
    q3, t3 = refine_free(q, t, rig.parents, fixed, predicted, 0.0)
    assert ranges.excess_degrees(q3)[2] == pytest.approx(0.0, abs=1e-6)  # the free shin moved into its range
    assert np.allclose(q3[fixed], q[fixed])
    for qq, tt in ((q2, t2), (q3, t3)):
        assert np.allclose(tt[3], tt[2] + _apply(qq[2], rig.keypoints[3] - rig.keypoints[2]), atol=1e-9)
