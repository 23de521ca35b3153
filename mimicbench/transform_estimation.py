"""Per-keypoint rigid transforms from rest and posed vertices (weighted Kabsch).

For each keypoint k, find the rotation R_k and translation t_k (the posed keypoint position)
minimising ``sum_i W_ik || R_k (vbar_i - cbar_k) + t_k - v_i ||^2``. Exact when keypoint k owns
at least three non-collinear vertices that moved rigidly with it.
"""
from __future__ import annotations

import numpy as np

from mimicbench.kinematics import transforms_to_array
from mimicbench.quaternion import matrix_to_quat
from mimicbench.validation import check_shape
from schemas.weights import as_dense


def estimate_transforms(
    rest_vertices: np.ndarray,
    posed_vertices: np.ndarray,
    weights,
    rest_keypoints: np.ndarray,
    min_weight: float = 1e-8,
) -> tuple[np.ndarray, np.ndarray]:
    """Estimate per-keypoint transforms by weighted Kabsch.

    Args:
        rest_vertices: (N, 3) rest vertices.
        posed_vertices: (..., N, 3) posed vertices (frames batch over leading dimensions).
        weights: dense (N, K) or :class:`~schemas.weights.SparseWeights`.
        rest_keypoints: (K, 3) rest keypoints cbar_k.
        min_weight: keypoints whose total weight is below this own no vertices.

    Returns:
        transforms (..., K, 7) float32 and ``owned`` (K,) bool. Keypoints that own no vertices get
        the identity rotation and the translation that keeps them rigid with their rest position
        (``t_k = cbar_k``); callers usually replace them by forward kinematics from the parent.
    """
    rest = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    posed = np.asarray(posed_vertices, dtype=np.float64)
    if posed.shape[-2:] != rest.shape:
        raise ValueError(f"posed_vertices: expected shape (..., {rest.shape[0]}, 3), got {posed.shape}")
    keypoints = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
    w = as_dense(weights, keypoints.shape[0])  # (N, K)
    total = w.sum(axis=0)  # (K,)
    owned = total > min_weight
    safe_total = np.where(owned, total, 1.0)
    mu_rest = (w.T @ rest) / safe_total[:, None]  # (K, 3)
    mu_posed = np.einsum("nk,...nc->...kc", w, posed) / safe_total[:, None]  # (..., K, 3)
    # Cross-covariance H_k = sum_i W_ik (vbar_i - mu_rest_k)(v_i - mu_posed_k)^T
    #                      = sum_i W_ik vbar_i v_i^T - total_k mu_rest_k mu_posed_k^T
    h = np.einsum("nk,na,...nb->...kab", w, rest, posed)
    h = h - total[:, None, None] * np.einsum("ka,...kb->...kab", mu_rest, mu_posed)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("...ab,...bc->...ac", vt.swapaxes(-1, -2), u.swapaxes(-1, -2))))
    d = np.where(d == 0, 1.0, d)
    fix = np.ones(h.shape[:-1])
    fix[..., 2] = d
    r = np.einsum("...ba,...b,...cb->...ac", vt, fix, u)  # V diag(1,1,d) U^T
    t = mu_posed - np.einsum("...kab,...kb->...ka", r, mu_rest - keypoints)
    q = matrix_to_quat(r)
    q[..., ~owned, :] = np.array([1.0, 0.0, 0.0, 0.0])
    t[..., ~owned, :] = keypoints[~owned]
    return transforms_to_array(q, t), owned
