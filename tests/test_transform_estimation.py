import numpy as np

from mimicbench.geometry.kinematics import transforms_to_array
from mimicbench.geometry.quaternion import quat_angle, quat_normalize
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.geometry.transform_estimation import estimate_transforms
from mimicbench.schemas.weights import SparseWeights


def rigid_character(k=6, per_bone=10, seed=0):
    """Each keypoint rigidly owns ``per_bone`` random (non-collinear) vertices."""
    rng = np.random.default_rng(seed)
    keypoints = rng.normal(size=(k, 3))
    verts = np.concatenate([keypoints[j] + 0.2 * rng.normal(size=(per_bone, 3)) for j in range(k)])
    owner = np.repeat(np.arange(k), per_bone)
    dense = np.zeros((len(verts), k))
    dense[np.arange(len(verts)), owner] = 1.0
    return verts, keypoints, SparseWeights.from_dense(dense)


def test_kabsch_recovers_random_rigid_transforms():
    verts, keypoints, weights = rigid_character()
    rng = np.random.default_rng(1)
    q = quat_normalize(rng.normal(size=(4, 6, 4)))
    t = rng.normal(size=(4, 6, 3))
    truth = transforms_to_array(q, t)
    posed_v = linear_blend_skinning(verts, keypoints, weights, truth).astype(np.float64)
    est, owned = estimate_transforms(verts, posed_v, weights, keypoints)
    assert owned.all()
    assert quat_angle(est[..., :4], q).max() < 1e-5
    np.testing.assert_allclose(est[..., 4:], t, atol=1e-5)


def test_reflection_is_never_returned():
    verts, keypoints, weights = rigid_character(k=2, seed=3)
    mirrored = verts * np.array([-1.0, 1.0, 1.0])  # a reflection, not a rotation
    est, _ = estimate_transforms(verts, mirrored, weights, keypoints)
    assert np.isfinite(est).all()
    np.testing.assert_allclose(np.linalg.norm(est[:, :4], axis=-1), 1.0, atol=1e-6)


def test_keypoint_without_vertices_gets_identity():
    verts, keypoints, weights = rigid_character(k=3)
    keypoints = np.concatenate([keypoints, [[5.0, 5.0, 5.0]]])
    weights = SparseWeights(weights.indices, weights.values, 4)
    est, owned = estimate_transforms(verts, verts, weights, keypoints)
    assert owned.tolist() == [True, True, True, False]
    np.testing.assert_allclose(est[3], [1, 0, 0, 0, 5, 5, 5])
