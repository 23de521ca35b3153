"""benchmark/motion_range.py: ranges of motion from clips, and the share of a predicted pose's bones
beyond them, on a hand-made leg whose clip reaches a known cone and hinge angle."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.benchmark.motion_range import (MARGIN_DEG, convex_hull_2d, distance_to_hull_2d, out_of_range_share,
                                    ranges_for_clips, ranges_for_dataset, swing_twist)
from mimicbench.benchmark.request import Rig
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_angle, quat_from_axis_angle, quat_multiply, quat_normalize
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.weights import SparseWeights

X, Y, Z = np.eye(3)


def leg() -> Rig:
    """pelvis (0, 2.2, 0) -> thigh (0, 2, 0) -> shin (0, 1, 0) -> foot (0, 0, 0): a leg hanging down
    (every bone's axis -Y), each bone a rigid tetrahedron of vertices below its keypoint."""
    kp = np.array([[0, 2.2, 0], [0, 2, 0], [0, 1, 0], [0, 0, 0]], np.float32)
    tet = np.array([[0.1, -0.1, 0], [0, -0.3, 0.1], [-0.1, -0.2, 0], [0, -0.15, -0.1]])
    verts = np.concatenate([k + tet for k in kp]).astype(np.float32)
    w = np.kron(np.eye(4), np.ones((4, 1)))
    faces = np.array([[4 * b, 4 * b + 1, 4 * b + 2] for b in range(4)], np.int32)
    return Rig("toy/leg", "humanoid", verts, faces, kp, np.array([-1, 0, 1, 2], np.int32),
               SparseWeights.from_dense(w), ("pelvis", "thigh", "shin", "foot"))


def rot(axis, degrees):
    return quat_from_axis_angle(np.asarray(axis, float), np.radians(degrees))


def clip_locals(n: int = 36) -> np.ndarray:
    """(n, 4, 4) local rotations: the thigh leans 45 degrees towards directions all around (a cone),
    the shin bends forward from 0 to 90 degrees about x (a hinge), the foot and pelvis never move."""
    frames = np.tile([1.0, 0, 0, 0], (n, 4, 1))
    for i in range(n):
        phi = 2 * np.pi * i / n
        frames[i, 1] = rot(np.cos(phi) * X + np.sin(phi) * Z, 45.0)
        frames[i, 2] = rot(X, 90.0 * i / (n - 1))
    return frames


def posed(rig: Rig, local: np.ndarray) -> np.ndarray:
    q, t = forward_kinematics(local, rig.keypoints, rig.parents)
    return linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, transforms_to_array(q, t))


def clip(rig: Rig) -> np.ndarray:
    """The clip as stored transforms (F, 4, 7)."""
    q, t = forward_kinematics(clip_locals(), rig.keypoints, rig.parents)
    return transforms_to_array(q, t)


def pose(thigh=None, shin=None, foot=None, pelvis=None) -> np.ndarray:
    """Local rotations (4, 4): the thigh leaning 30 degrees and the shin bent 45, unless given."""
    return np.stack([pelvis if pelvis is not None else rot(Y, 0),
                     thigh if thigh is not None else rot(np.cos(0.2) * X + np.sin(0.2) * Z, 30.0),
                     shin if shin is not None else rot(X, 45.0),
                     foot if foot is not None else rot(Y, 0)])


@pytest.fixture(scope="module")
def setup():
    rig = leg()
    return rig, ranges_for_clips(rig.character_id, rig, [clip(rig)])


def test_the_clips_own_frames_are_inside(setup):
    rig, ranges = setup
    assert ranges.scored.tolist() == [False, True, True, True]  # the pelvis is a root: a heading, not a joint
    for local in clip_locals():
        assert out_of_range_share(posed(rig, local), rig, ranges) == 0.0


def test_a_pose_inside_the_cone_and_the_hinge_is_inside(setup):
    rig, ranges = setup
    assert out_of_range_share(posed(rig, pose()), rig, ranges) == 0.0
    # turning the whole body (the root) changes no joint
    assert out_of_range_share(posed(rig, pose(pelvis=rot(Y, 90.0))), rig, ranges) == 0.0


@pytest.mark.parametrize("name, local, bone", [
    ("knee bent backwards 30 degrees", pose(shin=rot(X, -30.0)), 2),
    ("knee bent 30 degrees past the clip's 90", pose(shin=rot(X, 120.0)), 2),
    ("thigh 30 degrees beyond the 45-degree cone", pose(thigh=rot(X, 75.0)), 1),
    ("foot that never moves turned 30 degrees", pose(foot=rot(Z, 30.0)), 3),
])
def test_a_bone_30_degrees_past_its_range_is_one_of_the_scored_bones(setup, name, local, bone):
    rig, ranges = setup
    q, _ = forward_kinematics(local, rig.keypoints, rig.parents)
    excess = ranges.excess_degrees(q)
    # 30 degrees by hand: the hinge's swing vectors form a segment from 0 to 90 degrees about x (a
    # backward bend is 30 degrees from its rest end); the cone's 36 samples at 45 degrees make a
    # polygon with a vertex towards x (75 is 30 from it); the foot's range is the rest pose
    assert excess[bone] == pytest.approx(30.0, abs=1e-4), name  # the clip is stored as float32
    assert np.nan_to_num(np.delete(excess, bone)).max() < 1e-4
    assert out_of_range_share(posed(rig, local), rig, ranges) == pytest.approx(1 / 3)


def test_twist_beyond_the_reached_twists(setup):
    rig, ranges = setup
    local = pose(shin=quat_multiply(rot(X, 45.0), rot(Y, 30.0)))  # bent 45 inside the hinge, twisted 30
    q, _ = forward_kinematics(local, rig.keypoints, rig.parents)
    # the clips reach twist bin [0, 1) degrees only, so the excess is 29 to 30
    assert 29.0 <= ranges.excess_degrees(q)[2] <= 30.0
    assert out_of_range_share(posed(rig, local), rig, ranges) == pytest.approx(1 / 3)


def test_the_margin(setup):
    rig, ranges = setup
    slightly = posed(rig, pose(shin=rot(X, -8.0)))
    assert MARGIN_DEG == 10.0
    assert out_of_range_share(slightly, rig, ranges) == 0.0
    assert out_of_range_share(slightly, rig, ranges, margin_deg=5.0) == pytest.approx(1 / 3)


def test_swing_twist_rebuilds_the_rotation():
    rng = np.random.default_rng(0)
    q = quat_normalize(rng.normal(size=(50, 3, 4)))
    axes = rng.normal(size=(3, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    e1 = np.cross(axes, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    basis = np.stack([e1, np.cross(axes, e1)], axis=1)
    swing, tau = swing_twist(q, axes, basis)
    vector = np.einsum("fkb,kba->fka", swing, basis)  # back to 3-D rotation vectors
    assert np.abs(np.einsum("fka,ka->fk", vector, axes)).max() < 1e-9  # the swing is perpendicular
    angle = np.linalg.norm(vector, axis=-1)
    swing_q = quat_from_axis_angle(vector, angle)
    rebuilt = quat_multiply(swing_q, quat_from_axis_angle(np.broadcast_to(axes, vector.shape), tau))
    assert quat_angle(rebuilt, q).max() < 1e-9


def test_distance_to_hull_against_the_support_function():
    """Reference: the distance from x to a convex set is max over unit u of u.x - max_p u.p
    (0 inside), over 20,000 directions; none of it shares the polygon code."""
    rng = np.random.default_rng(1)
    u = np.stack([np.cos(a := np.linspace(0, 2 * np.pi, 20000, endpoint=False)), np.sin(a)], 1)
    for n in (1, 2, 3, 12):
        points = rng.normal(size=(n, 2))
        if n == 3:
            points[2] = points[0] + 0.3 * (points[1] - points[0])  # collinear: a segment
        hull = convex_hull_2d(points)
        queries = rng.normal(size=(200, 2)) * 2
        reference = np.maximum((queries @ u.T - (points @ u.T).max(0)).max(1), 0.0)
        got = distance_to_hull_2d(hull, queries)
        # the sampled directions miss the best one by up to 1.6e-4 rad: the reference is low by at
        # most that times the polygon's diameter
        assert (got - reference).min() > -1e-9 and (got - reference).max() < 1e-3
        assert (got == 0).sum() == (reference == 0).sum()


def test_ranges_for_dataset_streams_what_a_whole_read_gives(small_zoo):
    """Every character's ranges by streaming the motions table equal those of its clips read whole,
    and each character's own clip frames are inside."""
    import pyarrow.parquet as pq

    from mimicbench.benchmark.rigs import load_characters

    chars = load_characters(small_zoo)
    streamed = ranges_for_dataset(small_zoo, chars)
    table = pq.read_table(small_zoo / "motions", columns=["character_id", "num_frames", "num_joints",
                                                           "transforms"]).to_pylist()
    assert set(streamed) == {m["character_id"] for m in table}
    for cid in sorted(streamed)[:4]:
        rig = chars[cid].rig
        clips = [np.asarray(m["transforms"], np.float32).reshape(m["num_frames"], m["num_joints"], 7)
                 for m in table if m["character_id"] == cid]
        whole = ranges_for_clips(cid, rig, clips)
        got = streamed[cid]
        assert got.frames == whole.frames == sum(len(c) for c in clips)
        assert (got.twist == whole.twist).all()
        for a, b in zip(got.hulls, whole.hulls):
            np.testing.assert_allclose(np.sort(a, axis=0), np.sort(b, axis=0), atol=1e-12)
        for frame in clips[0][1::20]:
            verts = linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, frame)
            assert out_of_range_share(verts, rig, got) == 0.0


def test_ranges_for_dataset_leaves_out_simulated_clips_and_characters_without_clips(tmp_path):
    """A dataset of the leg (its clip, and a simulated ``@sim`` twin that bends the knee 30 degrees
    backwards) and a second leg without clips: only the first gets ranges, from its kinematic clip
    alone, so the twin's pose is out of range."""
    from mimicbench.schemas.character import CharacterRecord
    from mimicbench.schemas.motion import MotionRecord
    from mimicbench.schemas.shards import write_records

    rig = leg()
    records = [CharacterRecord(
        character_id=cid, category="humanoid", source="test", split="train", vertices=rig.vertices,
        faces=rig.faces, keypoints=rig.keypoints, parents=rig.parents, bone_names=list(rig.bone_names),
        weight_indices=rig.weights.indices, weight_values=rig.weights.values,
        apparel_vertex_mask=np.zeros(len(rig.vertices), bool), apparel_bone_mask=np.zeros(4, bool),
        height=float(np.ptp(rig.vertices[:, 1])), meta={}) for cid in ("toy/leg", "toy/still")]
    kin = clip(rig)
    q, t = forward_kinematics(np.stack([pose(shin=rot(X, -30.0))] * 3), rig.keypoints, rig.parents)
    motions = [MotionRecord("toy/leg/walk", "toy/leg", "walk", "train", 30.0, len(kin), 4, kin, "test"),
               MotionRecord("toy/leg/walk@sim", "toy/leg", "walk@sim", "train", 30.0, 3, 4,
                            transforms_to_array(q, t), "test")]
    write_records(tmp_path, "characters", records, split="train")
    write_records(tmp_path, "motions", motions, split="train")
    ranges = ranges_for_dataset(tmp_path)
    assert list(ranges) == ["toy/leg"] and ranges["toy/leg"].frames == len(kin)
    assert out_of_range_share(posed(rig, pose(shin=rot(X, -30.0))), rig, ranges["toy/leg"]) == pytest.approx(1 / 3)
