"""Distances from points to line segments (bones as head-to-tail segments)."""
from __future__ import annotations

import numpy as np


def point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (N, C) from points (N, 3) to segments a (C, 3) -> b (C, 3)."""
    ab = b - a  # (C, 3)
    ap = points[:, None, :] - a[None]  # (N, C, 3)
    t = np.clip(np.einsum("ncj,cj->nc", ap, ab) / np.maximum(np.einsum("cj,cj->c", ab, ab), 1e-12), 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=-1)
