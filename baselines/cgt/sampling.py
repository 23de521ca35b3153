"""Capping the points CGT attends over: farthest-point subsampling and interpolation back.

CGT's attention is dense over every pair of source and target points (N_s x N_t); on CPU we attend
over at most ``cap`` points of each mesh, chosen by farthest-point sampling, and carry the attended
features back to every target point by inverse-distance weighting of its 3 nearest chosen points.
With ``cap`` >= N every point is chosen and each interpolates from itself, so the capped model is
the dense one (up to the 1e-12 floor of the weights).
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree


def farthest_points(points: np.ndarray, count: int) -> np.ndarray:
    """(min(count, N),) int64 rows of points (N, 3) by farthest-point sampling, starting from the point
    farthest from the centroid (deterministic); all rows, in order, when ``count`` >= N or <= 0."""
    p = np.asarray(points, np.float64)
    n = len(p)
    if count <= 0 or count >= n:
        return np.arange(n)
    chosen = np.empty(count, np.int64)
    chosen[0] = int(np.argmax(((p - p.mean(0)) ** 2).sum(1)))
    dist = ((p - p[chosen[0]]) ** 2).sum(1)
    for i in range(1, count):
        chosen[i] = int(np.argmax(dist))
        dist = np.minimum(dist, ((p - p[chosen[i]]) ** 2).sum(1))
    return chosen


def interpolation(points: np.ndarray, chosen: np.ndarray, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-distance weights carrying values at ``points[chosen]`` back to all points (N, 3):
    ``(index (N, k) int64 into chosen, weight (N, k) float32)``, rows summing to 1."""
    k = min(k, len(chosen))
    d, idx = cKDTree(np.asarray(points, np.float64)[chosen]).query(points, k=k)
    d, idx = np.asarray(d).reshape(len(points), k), np.asarray(idx).reshape(len(points), k)
    w = 1.0 / np.maximum(d, 1e-12)
    return idx.astype(np.int64), (w / w.sum(1, keepdims=True)).astype(np.float32)


def interpolate(values: torch.Tensor, index: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Values (B, M, C) at the chosen points -> (B, N, C) at every point, index/weight (N, k)."""
    return (values[:, index] * weight[None, :, :, None]).sum(2)
