import numpy as np
import pytest
import torch

from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_normalize, quat_to_matrix
from mimicbench.geometry.skinning import linear_blend_skinning, posed_keypoints_from_vertices
from mimicbench.geometry.skinning_torch import linear_blend_skinning_torch
from mimicbench.schemas.weights import SparseWeights


def naive_lbs(verts, keypoints, dense, transforms):
    out = np.zeros_like(verts, dtype=np.float64)
    for i, v in enumerate(verts):
        for k in range(len(keypoints)):
            if dense[i, k] == 0:
                continue
            r = quat_to_matrix(transforms[k, :4])
            out[i] += dense[i, k] * (r @ (v - keypoints[k]) + transforms[k, 4:])
    return out


def posed(tube, frames=3, seed=0):
    k = len(tube["parents"])
    local = quat_normalize(np.random.default_rng(seed).normal(size=(frames, k, 4)) * [4, 1, 1, 1])
    g_rot, g_pos = forward_kinematics(local, tube["keypoints"], tube["parents"])
    return transforms_to_array(g_rot, g_pos)


def test_lbs_sparse_dense_and_naive_agree(tube):
    t = posed(tube)
    dense = tube["weights"].to_dense()
    fast_sparse = linear_blend_skinning(tube["vertices"], tube["keypoints"], tube["weights"], t)
    fast_dense = linear_blend_skinning(tube["vertices"], tube["keypoints"], dense, t)
    assert fast_sparse.shape == (3, len(tube["vertices"]), 3)
    np.testing.assert_allclose(fast_sparse, fast_dense, atol=1e-5)
    for f in range(3):
        np.testing.assert_allclose(fast_sparse[f], naive_lbs(tube["vertices"], tube["keypoints"], dense, t[f]), atol=1e-5)


def test_lbs_torch_twin_matches_numpy(tube):
    t = posed(tube, seed=1)
    ref = linear_blend_skinning(tube["vertices"], tube["keypoints"], tube["weights"], t)
    w = tube["weights"]
    dense_t = linear_blend_skinning_torch(torch.tensor(tube["vertices"]), torch.tensor(tube["keypoints"]),
                                          torch.tensor(w.to_dense()), torch.tensor(t, dtype=torch.float64))
    sparse_t = linear_blend_skinning_torch(torch.tensor(tube["vertices"]), torch.tensor(tube["keypoints"]),
                                           torch.tensor(w.values), torch.tensor(t, dtype=torch.float64),
                                           weight_indices=torch.tensor(w.indices))
    np.testing.assert_allclose(dense_t.numpy(), ref, atol=1e-5)
    np.testing.assert_allclose(sparse_t.numpy(), ref, atol=1e-5)


def test_rest_pose_is_identity_and_keypoints_are_weight_averages(tube):
    k = len(tube["parents"])
    rest = transforms_to_array(np.tile([1.0, 0, 0, 0], (k, 1)), tube["keypoints"])
    out = linear_blend_skinning(tube["vertices"], tube["keypoints"], tube["weights"], rest)
    np.testing.assert_allclose(out, tube["vertices"], atol=1e-6)
    dense = tube["weights"].to_dense()
    kp = posed_keypoints_from_vertices(out, tube["weights"])
    for j in range(k):
        expect = (dense[:, j:j + 1] * tube["vertices"]).sum(0) / dense[:, j].sum()
        np.testing.assert_allclose(kp[j], expect, atol=1e-6)


def test_sparse_weights_invariants_and_round_trip():
    rng = np.random.default_rng(0)
    dense = rng.random((50, 20)) ** 4
    sw = SparseWeights.from_dense(dense)
    assert sw.indices.shape == (50, 8)
    np.testing.assert_allclose(sw.row_sums(), 1.0, atol=1e-6)
    assert ((sw.to_dense() > 0).sum(1) <= 8).all()
    # the kept influences are the 8 largest of each row
    top = np.sort(dense, axis=1)[:, -8:]
    kept = np.sort(sw.to_dense() * dense.sum(1, keepdims=True), axis=1)[:, -8:]
    np.testing.assert_allclose(kept / kept.sum(1, keepdims=True), top / top.sum(1, keepdims=True), rtol=1e-5)


def test_sparse_weights_from_csr_equals_from_dense():
    from scipy.sparse import random as sparse_random

    rng = np.random.default_rng(1)
    m = sparse_random(200, 40, density=0.2, random_state=rng, format="coo")
    m.data = np.round(m.data, 1) + 0.05  # ties between weights, resolved by column like from_dense
    empty = np.setdiff1d(np.arange(200), m.row)
    # duplicate entries are summed, as the dense form would hold them; empty rows get one weight
    rows, cols = np.r_[m.row, m.row[:30], empty], np.r_[m.col, m.col[:30], np.zeros(len(empty), int)]
    dup = type(m)((np.r_[m.data, m.data[:30], np.ones(len(empty))], (rows, cols)), shape=m.shape)
    dense = dup.toarray()
    a, b = SparseWeights.from_csr(dup), SparseWeights.from_dense(dense)
    np.testing.assert_array_equal(a.indices, b.indices)
    np.testing.assert_array_equal(a.values, b.values)
    with pytest.raises(ValueError, match="no positive weight"):
        SparseWeights.from_csr(type(m)(np.zeros((3, 4))))
