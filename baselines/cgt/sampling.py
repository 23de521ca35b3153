"""Capping the points CGT attends over: farthest-point subsampling of the posed source.

CGT's attention is dense over every pair of source and target points (N_s x N_t); on CPU every
target point attends over at most ``cap`` points of the posed source, chosen by farthest-point
sampling (:mod:`mimicbench.baselines.cgt.model` says why the queries are not capped). With ``cap`` >= N_s every
point is chosen and the capped model is the dense one.
"""
from __future__ import annotations

import numpy as np


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
