"""Weighted rotation averaging (MimiCAT Eq. 4).

For each target keypoint j, the average of source rotations q_i weighted by a soft
correspondence M_ij is the eigenvector of the largest eigenvalue of
``A_j = sum_i M_ij q_i q_i^T`` (Markley et al., "Averaging Quaternions", 2007). Because
``q q^T = (-q)(-q)^T`` the result does not depend on the signs of the inputs.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import quat_canonical, quat_identity
from mimicbench.geometry.validation import check_last_dim


def weighted_quaternion_average(quaternions: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Average quaternions with a soft correspondence matrix.

    Args:
        quaternions: (..., K1, 4) unit quaternions q_i (w, x, y, z).
        weights: (..., K1, K2) non-negative weights M_ij.

    Returns:
        (..., K2, 4) unit quaternions with w >= 0. A column of ``weights`` that is all zero
        gives the identity.
    """
    q = check_last_dim(quaternions, 4, "quaternions").astype(np.float64)
    m = np.asarray(weights, dtype=np.float64)
    if m.shape[-2] != q.shape[-2]:
        raise ValueError(f"weights: expected shape (..., {q.shape[-2]}, K2), got {m.shape}")
    a = np.einsum("...ij,...ia,...ib->...jab", m, q, q)  # (..., K2, 4, 4)
    _, vecs = np.linalg.eigh(a)
    avg = quat_canonical(vecs[..., :, -1])
    empty = m.sum(axis=-2) <= 0
    return np.where(empty[..., None], quat_identity(avg.shape[:-1]), avg)
