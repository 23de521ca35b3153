"""Rectangular Hungarian assignment (scipy's ``linear_sum_assignment``)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment


def hungarian_match(scores: np.ndarray, maximize: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one matching of the rows and columns of a K1 x K2 score matrix.

    Args:
        scores: (K1, K2) float; finite.
        maximize: maximise the total score (True, for similarities) or minimise it (costs).

    Returns:
        pairs (min(K1, K2), 2) int64 of (row, column) sorted by row, and the one-hot matrix
        (K1, K2) float32 with a 1 at each pair.
    """
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 2:
        raise ValueError(f"scores: expected shape (K1, K2), got {s.shape}")
    if not np.isfinite(s).all():
        raise ValueError("scores: expected finite values, got NaN or inf")
    rows, cols = linear_sum_assignment(s, maximize=maximize)
    pairs = np.stack([rows, cols], axis=1).astype(np.int64)
    onehot = np.zeros(s.shape, dtype=np.float32)
    onehot[rows, cols] = 1.0
    return pairs, onehot
