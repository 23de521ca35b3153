"""Skin weights for a resampled mesh by barycentric interpolation of the original weights.

Each new vertex takes the closest point on the original surface, on the piece it came from
(:func:`mimicbench.datagen.resample.pieces.own_piece_points`); its weights are the barycentric combination of
the weights of that triangle's three vertices, pruned to the 8 largest and renormalised. The
apparel mask is interpolated the same way (kept where >= 0.5).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix

from mimicbench.datagen.resample.closest_point import SurfacePoints
from mimicbench.schemas.weights import MAX_INFLUENCES, SparseWeights


def barycentric_matrix(faces: np.ndarray, surface: SurfacePoints, num_vertices: int) -> csr_matrix:
    """(Q, N) sparse matrix whose row q holds query q's barycentric coordinates at the three
    corners of its closest face: ``B @ x`` interpolates per-vertex data x (N, ...) at the points."""
    corners = faces[surface.faces]  # (Q, 3)
    rows = np.repeat(np.arange(len(corners)), 3)
    return csr_matrix((surface.barycentric.ravel(), (rows, corners.ravel())), shape=(len(corners), num_vertices))


def interpolate_weights(weights: SparseWeights, faces: np.ndarray, surface: SurfacePoints) -> SparseWeights:
    """Weights of the new vertices (Q, 8) from the original weights (N, K) on original faces (M, 3)."""
    b = barycentric_matrix(faces, surface, weights.num_vertices)
    return SparseWeights.from_csr(b @ weights.to_csr(), MAX_INFLUENCES)


def interpolate_mask(mask: np.ndarray, faces: np.ndarray, surface: SurfacePoints) -> np.ndarray:
    """A per-vertex 0/1 mask (N,) carried to the new vertices: interpolated, kept where >= 0.5."""
    mask = np.asarray(mask, np.float64)
    return barycentric_matrix(faces, surface, len(mask)) @ mask >= 0.5


def nearest_vertex_weights(weights: SparseWeights, old_vertices: np.ndarray, new_vertices: np.ndarray) -> SparseWeights:
    """The naive reskin the tests compare against: copy the nearest original vertex's weights."""
    from scipy.spatial import cKDTree

    _, idx = cKDTree(old_vertices).query(new_vertices)
    return weights.take(idx)
