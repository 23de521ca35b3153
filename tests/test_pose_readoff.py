"""The one read-off (mimicbench/geometry/transform_estimation.py's joint fit, mimicbench/geometry/pose_readoff.py's
completion from the skeleton) against the transforms a mesh was posed with."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.geometry.kabsch import kabsch_transforms
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.pose_readoff import read_pose
from mimicbench.geometry.quaternion import quat_angle, quat_apply, quat_from_axis_angle, quat_multiply, quat_normalize
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.geometry.transform_estimation import estimate_transforms, weight_support
from mimicbench.schemas.weights import SparseWeights

FLOAT_DEG = 1e-3
"""Float precision of a read-off from float32 vertices: posed vertices carry about 1e-7 m of
rounding, the stored quaternions about 1e-5 degrees."""


def blended_rig(k: int, seed: int, few: int = 3, per_bone: int = 30):
    """A random tree of ``k`` bones, each owning ``per_bone`` vertices around its segment, except
    every fourth bone that owns only ``few``; a vertex of a non-root bone is bound to its parent
    too with a weight up to 0.5 (as skinned characters blend at joints). Returns rest vertices
    (N, 3), keypoints (K, 3), parents (K,), SparseWeights."""
    rng = np.random.default_rng(seed)
    parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, k)], np.int32)
    kp = np.zeros((k, 3))
    for j in range(1, k):
        kp[j] = kp[parents[j]] + rng.normal(size=3) * 0.3
    verts, rows = [], []
    for j in range(k):
        n = few if j % 4 == 3 else per_bone
        direction = rng.normal(size=3)
        along = rng.uniform(0, 0.2, size=(n, 1)) * direction / np.linalg.norm(direction)
        verts.append(kp[j] + along + rng.normal(size=(n, 3)) * 0.05)
        for _ in range(n):
            row = np.zeros(k)
            blend = rng.uniform(0, 0.5) if parents[j] >= 0 and rng.uniform() < 0.7 else 0.0
            row[j] = 1.0 - blend
            if blend:
                row[parents[j]] = blend
            rows.append(row)
    return np.concatenate(verts), kp, parents, SparseWeights.from_dense(np.array(rows))


def random_pose(kp, parents, rng):
    """Global rotations (K, 4) and positions (K, 3) of random local rotations, by forward kinematics,
    with the root moved."""
    local = quat_normalize(rng.normal(size=(len(parents), 4)))
    root = kp + rng.normal(size=3)
    return forward_kinematics(local, kp, parents, root)


@pytest.mark.parametrize("k, seed", [(6, 0), (64, 1), (120, 2)])
def test_the_joint_fit_recovers_the_transforms_a_blended_mesh_was_posed_with(k, seed):
    verts, kp, parents, weights = blended_rig(k, seed)
    q, t = random_pose(kp, parents, np.random.default_rng(seed + 10))
    posed = linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t))
    est, supported = estimate_transforms(verts, posed, weights, kp)
    assert supported.all()
    assert np.degrees(quat_angle(est[:, :4], q)).max() < FLOAT_DEG
    np.testing.assert_allclose(est[:, 4:], t, atol=1e-5)
    # the reference can fail: bone by bone, Kabsch misses where vertices blend two bones
    kabsch, _ = kabsch_transforms(verts, posed, weights, kp)
    assert np.degrees(quat_angle(kabsch[:, :4], q)).max() > 1.0


def test_transforms_unrelated_to_the_skeleton_are_recovered_too():
    """LBS does not tie a bone's translation to its parent: any (q_k, t_k) are read back."""
    verts, kp, parents, weights = blended_rig(16, 3)
    rng = np.random.default_rng(4)
    q, t = quat_normalize(rng.normal(size=(16, 4))), rng.normal(size=(16, 3))
    posed = linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t))
    est, _ = estimate_transforms(verts, posed, weights, kp)
    assert np.degrees(quat_angle(est[:, :4], q)).max() < FLOAT_DEG
    np.testing.assert_allclose(est[:, 4:], t, atol=1e-5)


def test_frames_batch_over_leading_dimensions():
    verts, kp, parents, weights = blended_rig(10, 5)
    rng = np.random.default_rng(6)
    poses = [random_pose(kp, parents, rng) for _ in range(3)]
    posed = np.stack([linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t)) for q, t in poses])
    est, _ = estimate_transforms(verts, posed.reshape(3, 1, -1, 3), weights, kp)
    assert est.shape == (3, 1, 10, 7)
    for f, (q, _) in enumerate(poses):
        assert np.degrees(quat_angle(est[f, 0, :, :4], q)).max() < FLOAT_DEG


def test_a_mirrored_mesh_gives_rotations_never_reflections():
    verts, kp, parents, weights = blended_rig(5, 7)
    est, _ = estimate_transforms(verts, verts * np.array([-1.0, 1.0, 1.0]), weights, kp)
    assert np.isfinite(est).all()
    np.testing.assert_allclose(np.linalg.norm(est[:, :4], axis=-1), 1.0, atol=1e-6)


def test_on_a_mesh_that_is_not_lbs_the_prior_pulls_towards_kabsch():
    """Without the prior the fit minimises the vertex residual of all bones together (its LBS
    reconstruction is closer to a noisy mesh than per-bone Kabsch's); the prior, scaled by the
    residual's variance, moves every rotation towards Kabsch's, and leaves an exact pose alone."""
    verts, kp, parents, weights = blended_rig(12, 8)
    rng = np.random.default_rng(9)
    q, t = random_pose(kp, parents, rng)
    exact = linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t))
    posed = exact + rng.normal(size=verts.shape) * 0.01
    residual = lambda tr: np.linalg.norm(linear_blend_skinning(verts, kp, weights, tr) - posed)  # noqa: E731
    free, _ = estimate_transforms(verts, posed, weights, kp, prior_deg=0.0)
    pulled, _ = estimate_transforms(verts, posed, weights, kp)
    kabsch, _ = kabsch_transforms(verts, posed, weights, kp)
    assert residual(free) < residual(kabsch)
    assert residual(free) <= residual(pulled)
    to_kabsch = lambda tr: quat_angle(tr[:, :4], kabsch[:, :4])  # noqa: E731
    assert (to_kabsch(pulled) <= to_kabsch(free) + 1e-9).all() and to_kabsch(pulled).sum() < to_kabsch(free).sum()
    np.testing.assert_array_equal(estimate_transforms(verts, exact, weights, kp)[0],
                                  estimate_transforms(verts, exact, weights, kp, prior_deg=0.0)[0])


def _chain_with_gaps():
    """root (0,0,0) -> hip (0,1,0) with no vertices -> legs at (+-0.5, 1, 0), each a tetrahedron
    of vertices bound rigidly, the root a tetrahedron, and a tip under leg 0 whose two vertices
    lie on a line (its rotation about that line is free)."""
    kp = np.array([[0.0, 0, 0], [0, 1, 0], [-0.5, 1, 0], [0.5, 1, 0], [-0.5, 0.5, 0]])
    tet = np.array([[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1], [-0.05, -0.05, -0.05]])
    verts = np.concatenate([kp[0] + tet, kp[2] + tet, kp[3] + tet, kp[4] + [[0, -0.1, 0], [0, -0.2, 0]]])
    owner = [0] * 4 + [2] * 4 + [3] * 4 + [4] * 2
    w = np.zeros((len(verts), 5))
    w[np.arange(len(verts)), owner] = 1
    return verts, kp, np.array([-1, 0, 1, 1, 2]), SparseWeights.from_dense(w)


def test_weight_support_by_hand():
    verts, kp, parents, weights = _chain_with_gaps()
    assert weight_support(verts, weights).tolist() == [True, False, True, True, False]


def test_undetermined_bones_are_completed_from_the_skeleton():
    verts, kp, parents, weights = _chain_with_gaps()
    z, x = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    local = np.stack([quat_from_axis_angle(x, 0.3), quat_from_axis_angle(x, 1.2), quat_from_axis_angle(z, 0.1),
                      quat_from_axis_angle(z, -0.1), quat_from_axis_angle(z, 0.7)])
    q, t = forward_kinematics(local, kp, parents, kp + [0.2, 0, 0])
    posed = linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t))
    pose = read_pose(verts, kp, parents, weights, posed)
    assert pose.supported.tolist() == [True, False, True, True, False]
    assert np.degrees(quat_angle(pose.rotations[[0, 2, 3]], q[[0, 2, 3]])).max() < FLOAT_DEG
    # hip: its two legs agree within 20 degrees (0.2 rad apart), so it takes their average weighted
    # by the skin weight at and below each (6 for leg 0 with the tip, 4 for leg 1): their rotations
    # are the hip's turned by +-0.1 rad about z, and the largest eigenvector of
    # 6 qa qa^T + 4 qb qb^T turns it by atan(0.2 tan 0.1) about z
    expected = quat_multiply(q[1], quat_from_axis_angle(z, np.arctan(0.2 * np.tan(0.1))))
    assert np.degrees(quat_angle(pose.rotations[1], expected)) < FLOAT_DEG
    # the tip: its parent's rotation; both follow their parents rigidly
    assert np.degrees(quat_angle(pose.rotations[4], pose.rotations[2])) < 1e-9
    for k in (1, 4):
        p = parents[k]
        np.testing.assert_allclose(pose.positions[k], pose.positions[p] + quat_apply(pose.rotations[p], kp[k] - kp[p]),
                                   atol=1e-9)
    assert pose.transforms.shape == (5, 7) and pose.transforms.dtype == np.float32


def test_bad_input_says_what_was_expected():
    verts, kp, parents, weights = _chain_with_gaps()
    with pytest.raises(ValueError, match="posed_vertices"):
        estimate_transforms(verts, verts[:-1], weights, kp)
    with pytest.raises(ValueError, match="parents"):
        read_pose(verts, kp, parents[:-1], weights, verts)


@pytest.mark.slow
def test_a_shared_asset_posed_by_its_own_clips_is_read_back(assets_dir, tmp_path):
    """CesiumMan (glTF sample, 19 bones, every one skinned) posed by linear blend skinning with its
    own clip as ingested: the read-off returns the clip's transforms on every supported bone."""
    import pyarrow.parquet as pq

    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.datagen.ingest.runner import ingest_assets

    raw = tmp_path / "raw"
    ingest_assets([assets_dir / "glb" / "CesiumMan.glb"], raw, progress=False, split="test")
    ev = EvalData.load(raw)
    (char,) = ev.characters.values()
    rig = char.rig
    table = pq.read_table(raw / "motions", columns=["num_frames", "num_joints", "transforms"]).to_pylist()
    errors, moved = [], []
    for m in table:
        clip = np.asarray(m["transforms"], np.float32).reshape(m["num_frames"], m["num_joints"], 7)
        for frame in clip[::7]:
            pose = read_pose(rig.vertices, rig.keypoints, rig.parents, rig.weights, ev.posed(char, frame))
            s = pose.supported
            errors.append(np.degrees(quat_angle(pose.rotations[s], frame[s, :4].astype(np.float64))).max())
            moved.append(np.degrees(quat_angle(np.array([1.0, 0, 0, 0]), frame[s, :4].astype(np.float64))).max())
            np.testing.assert_allclose(pose.positions[s], frame[s, 4:], atol=1e-4 * rig.height)
    assert pose.supported.sum() >= 15
    assert min(moved) > 10  # the clip moves the bones
    assert max(errors) < 1e-2, max(errors)


def test_read_only_rigs_reuse_their_fit_design_and_writable_ones_are_read_afresh():
    """A rig given as read-only arrays (as every benchmark Rig) reuses its factorised design across
    calls; writable arrays may change between calls, so they are never served from the cache."""
    verts, kp, parents, weights = blended_rig(8, 11)
    rng = np.random.default_rng(12)
    q, t = random_pose(kp, parents, rng)
    posed = linear_blend_skinning(verts, kp, weights, transforms_to_array(q, t))

    def frozen(a):
        a = np.array(a)
        a.flags.writeable = False
        return a.view()

    ro = (frozen(verts), frozen(kp), SparseWeights(frozen(weights.indices), frozen(weights.values), 8))
    first, _ = estimate_transforms(ro[0], posed, ro[2], ro[1])
    again, _ = estimate_transforms(ro[0], posed, ro[2], ro[1])
    np.testing.assert_array_equal(first, again)
    assert np.degrees(quat_angle(again[:, :4], q)).max() < FLOAT_DEG
    # writable: the same rest vertices give the same answer; moved ones the answer for the move
    writable = np.array(verts)
    estimate_transforms(writable, posed, weights, kp)
    writable += [1.0, 0.0, 0.0]  # a rest mesh 1 m to the right, posed the same: bones shift back
    moved, _ = estimate_transforms(writable, posed, weights, kp)
    # (a stale design would be off by degrees; the longer lever of the 3-vertex bones costs float
    # precision: 0.01 degrees)
    assert np.degrees(quat_angle(moved[:, :4], q)).max() < 1e-2
    np.testing.assert_allclose(moved[:, 4:], t - quat_apply(q, [1.0, 0.0, 0.0]), atol=1e-4)
