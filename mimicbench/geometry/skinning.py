"""Linear blend skinning (MimiCAT Eq. 1), NumPy.

``v_i = sum_k W_ik (R(q_k) (vbar_i - cbar_k) + t_k)``: each keypoint's transform maps rest to
posed; ``t_k`` is the posed position of keypoint k. Frames batch over leading dimensions.
An optional per-keypoint ``scale`` (..., K, 6), the symmetric stretch U_k of a bone that
scales (``s_xx, s_yy, s_zz, s_xy, s_xz, s_yz`` in the rest frame), makes the map
``R(q_k) U_k (vbar_i - cbar_k) + t_k``; without it U_k is the identity.
The torch twin is :mod:`mimicbench.geometry.skinning_torch`.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.kinematics import array_to_transforms
from mimicbench.geometry.quaternion import quat_to_matrix
from mimicbench.geometry.validation import check_shape
from mimicbench.schemas.weights import SparseWeights, as_dense


def stretch_matrices(scale: np.ndarray) -> np.ndarray:
    """Symmetric 3x3 matrices (..., 3, 3) from (..., 6) ``s_xx, s_yy, s_zz, s_xy, s_xz, s_yz``."""
    s = np.asarray(scale, np.float64)
    if s.shape[-1] != 6:
        raise ValueError(f"scale: expected shape (..., K, 6), got {s.shape}")
    xx, yy, zz, xy, xz, yz = np.moveaxis(s, -1, 0)
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)


def keypoint_affines(transforms: np.ndarray, rest_keypoints: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """Per-keypoint affine maps (..., K, 3, 4) ``[R_k U_k | t_k - R_k U_k cbar_k]`` from transforms
    (..., K, 7) and the optional stretch ``scale`` (..., K, 6) (U_k = identity when None)."""
    q, t = array_to_transforms(transforms)
    rest = check_shape(rest_keypoints, (q.shape[-2], 3), "rest_keypoints").astype(np.float64)
    r = quat_to_matrix(q)
    if scale is not None:
        u = stretch_matrices(scale)
        if u.shape[:-2] != r.shape[:-2]:
            raise ValueError(f"scale: expected shape {r.shape[:-2] + (6,)}, got {np.shape(scale)}")
        r = r @ u
    offset = t - np.einsum("...kij,kj->...ki", r, rest)
    return np.concatenate([r, offset[..., None]], axis=-1)


def linear_blend_skinning(
    rest_vertices: np.ndarray,
    rest_keypoints: np.ndarray,
    weights: np.ndarray | SparseWeights,
    transforms: np.ndarray,
    scale: np.ndarray | None = None,
) -> np.ndarray:
    """Pose a mesh by linear blend skinning.

    Args:
        rest_vertices: (N, 3) rest vertices, metres.
        rest_keypoints: (K, 3) joint head positions at rest, metres.
        weights: dense (N, K) or :class:`SparseWeights`; rows sum to 1.
        transforms: (..., K, 7) per-keypoint (q_w, q_x, q_y, q_z, t_x, t_y, t_z).
        scale: optional (..., K, 6) per-keypoint symmetric stretch (a motion's ``scale`` column).

    Returns:
        (..., N, 3) float32 posed vertices.
    """
    verts = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    a = keypoint_affines(transforms, rest_keypoints, scale)  # (..., K, 3, 4)
    if isinstance(weights, SparseWeights):
        if weights.num_vertices != verts.shape[0]:
            raise ValueError(f"weights: expected {verts.shape[0]} rows, got {weights.num_vertices}")
        w = weights.to_csr()
    else:
        w = as_dense(weights, a.shape[-3])
        if w.shape[0] != verts.shape[0]:
            raise ValueError(f"weights: expected {verts.shape[0]} rows, got {w.shape[0]}")
    lead, k = a.shape[:-3], a.shape[-3]
    # Blend the affine maps: (N, K) @ (K, lead*12), one sparse or dense matrix product.
    flat = np.moveaxis(a.reshape(lead + (k, 12)), -2, 0).reshape(k, -1)
    blended = np.moveaxis(np.asarray(w @ flat).reshape((verts.shape[0],) + lead + (3, 4)), 0, -3)
    out = np.einsum("...nab,nb->...na", blended[..., :3], verts) + blended[..., 3]
    return out.astype(np.float32)


def posed_keypoints_from_vertices(posed_vertices: np.ndarray, weights) -> np.ndarray:
    """Posed keypoints (..., K, 3) as the weight-averaged posed vertices (..., N, 3).

    Keypoint k is ``sum_i W_ik v_i / sum_i W_ik``; a keypoint that owns no weight gets NaN.
    """
    w = as_dense(weights)
    v = np.asarray(posed_vertices, dtype=np.float64)
    total = w.sum(axis=0)  # (K,)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("nk,...nc->...kc", w, v) / total[:, None]
