"""Skin weights for a resampled mesh by barycentric interpolation of the original weights.

Each new vertex takes the closest point on the original surface; its weights are the
barycentric combination of the weights of that triangle's three vertices, pruned to the 8
largest and renormalised. The apparel mask is interpolated the same way (kept where >= 0.5).
"""
from __future__ import annotations

import numpy as np

from datagen.resample.closest_point import SurfacePoints
from mimicbench.weights import MAX_INFLUENCES, SparseWeights


def interpolate_weights(dense_weights: np.ndarray, faces: np.ndarray, surface: SurfacePoints) -> SparseWeights:
    """Weights (N', 8) for new vertices from original dense weights (N, K) on original faces (M, 3)."""
    corners = faces[surface.faces]  # (N', 3)
    w = np.einsum("qc,qck->qk", surface.barycentric, dense_weights[corners])
    return SparseWeights.from_dense(w, MAX_INFLUENCES)


def interpolate_mask(mask: np.ndarray, faces: np.ndarray, surface: SurfacePoints) -> np.ndarray:
    """A per-vertex 0/1 mask (N,) carried to the new vertices: interpolated, kept where >= 0.5."""
    corners = faces[surface.faces]
    return np.einsum("qc,qc->q", surface.barycentric, np.asarray(mask, np.float64)[corners]) >= 0.5


def nearest_vertex_weights(dense_weights: np.ndarray, old_vertices: np.ndarray, new_vertices: np.ndarray) -> SparseWeights:
    """The naive reskin the tests compare against: copy the nearest original vertex's weights."""
    from scipy.spatial import cKDTree

    _, idx = cKDTree(old_vertices).query(new_vertices)
    return SparseWeights.from_dense(dense_weights[idx], MAX_INFLUENCES)
