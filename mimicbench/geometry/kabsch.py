"""Per-keypoint rigid transforms by weighted Kabsch, each bone on its own.

For each keypoint k, find the rotation R_k and translation t_k (the posed keypoint position)
minimising ``sum_i W_ik || R_k (vbar_i - cbar_k) + t_k - v_i ||^2``. Exact when keypoint k owns
at least three non-collinear vertices that moved rigidly with it; biased where vertices blend
several bones. The joint fit of all bones (:func:`mimicbench.geometry.transform_estimation.estimate_transforms`)
starts from it and is regularised towards it.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.kinematics import transforms_to_array
from mimicbench.geometry.quaternion import matrix_to_quat
from mimicbench.geometry.validation import check_shape
from mimicbench.schemas.weights import SparseWeights, as_dense


def kabsch_transforms(
    rest_vertices: np.ndarray,
    posed_vertices: np.ndarray,
    weights,
    rest_keypoints: np.ndarray,
    min_weight: float = 1e-8,
) -> tuple[np.ndarray, np.ndarray]:
    """Estimate per-keypoint transforms by weighted Kabsch, bone by bone.

    Args:
        rest_vertices: (N, 3) rest vertices, metres.
        posed_vertices: (..., N, 3) posed vertices (frames batch over leading dimensions).
        weights: dense (N, K) or :class:`~mimicbench.schemas.weights.SparseWeights`.
        rest_keypoints: (K, 3) rest keypoints cbar_k.
        min_weight: keypoints whose total weight is below this own no vertices.

    Returns:
        transforms (..., K, 7) float32 and ``owned`` (K,) bool. Keypoints that own no vertices get
        the identity rotation and the translation that keeps them at their rest position
        (``t_k = cbar_k``).
    """
    rest = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    posed = np.asarray(posed_vertices, dtype=np.float64)
    if posed.shape[-2:] != rest.shape:
        raise ValueError(f"posed_vertices: expected shape (..., {rest.shape[0]}, 3), got {posed.shape}")
    keypoints = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
    q, t, owned = kabsch_rotations(rest, posed, weight_matrix(weights, keypoints.shape[0]), keypoints, min_weight)
    return transforms_to_array(q, t), owned


def weight_matrix(weights, num_keypoints: int):
    """Skin weights as a scipy sparse (N, K) float64 CSR matrix, from dense (N, K) weights or a
    :class:`~mimicbench.schemas.weights.SparseWeights`."""
    from scipy.sparse import csr_matrix

    if isinstance(weights, SparseWeights):
        if weights.num_keypoints != num_keypoints:
            raise ValueError(f"weights: expected {num_keypoints} keypoints, got {weights.num_keypoints}")
        return weights.to_csr()
    return csr_matrix(as_dense(weights, num_keypoints))


def kabsch_rotations(rest: np.ndarray, posed: np.ndarray, w, keypoints: np.ndarray,
                     min_weight: float = 1e-8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`kabsch_transforms` on checked float64 arrays: rest (N, 3), posed (..., N, 3), weights
    w (N, K) (:func:`weight_matrix`), keypoints (K, 3); returns quaternions (..., K, 4), positions
    (..., K, 3) (float64) and ``owned`` (K,) bool."""
    wt = w.T.tocsr()  # (K, N)
    total = np.asarray(wt.sum(axis=1)).ravel()  # (K,)
    owned = total > min_weight
    safe_total = np.where(owned, total, 1.0)
    lead, n = posed.shape[:-2], rest.shape[0]
    frames = np.moveaxis(posed.reshape((-1, n, 3)), 0, 1).reshape(n, -1)  # (N, F*3)
    mu_rest = np.asarray(wt @ rest) / safe_total[:, None]  # (K, 3)
    mu_posed = np.moveaxis(np.asarray(wt @ frames).reshape(-1, frames.shape[1] // 3, 3), 1, 0)
    mu_posed = (mu_posed / safe_total[:, None]).reshape(lead + (len(total), 3))  # (..., K, 3)
    # Cross-covariance H_k = sum_i W_ik (vbar_i - mu_rest_k)(v_i - mu_posed_k)^T
    #                      = sum_i W_ik vbar_i v_i^T - total_k mu_rest_k mu_posed_k^T
    outer = (rest[:, None, :, None] * frames.reshape(n, -1, 1, 3)).reshape(n, -1)  # (N, F*3*3): [n, f, a, b]
    h = np.asarray(wt @ outer).reshape(len(total), -1, 3, 3)  # (K, F, 3, 3): [k, f, a, b]
    h = np.moveaxis(h, 0, 1).reshape(lead + (len(total), 3, 3))
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
    return q, t, owned
