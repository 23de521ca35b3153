"""Closest points on a triangle mesh, with the triangle and barycentric coordinates.

The search is libigl's AABB tree (``igl.point_mesh_squared_distance``), exact up to floating
point; :func:`closest_points_brute_force` tests every triangle for every query and is the
reference the tests compare with.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass
class SurfacePoints:
    """Per query: the closest point (Q, 3), its distance (Q,), face index (Q,) and barycentric
    coordinates (Q, 3) in that face (non-negative, rows sum to 1)."""

    points: np.ndarray
    distances: np.ndarray
    faces: np.ndarray
    barycentric: np.ndarray


def _finish(corners: np.ndarray, queries: np.ndarray, face: np.ndarray, point: np.ndarray) -> SurfacePoints:
    """SurfacePoints from each query's closest face (Q,), its corners (Q, 3, 3) and closest point (Q, 3)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        bary = trimesh.triangles.points_to_barycentric(corners, point)
    # a degenerate triangle (a segment or a point) has no barycentric frame: take its nearest corner
    bad = ~np.isfinite(bary).all(axis=1)
    if bad.any():
        nearest = np.argmin(np.linalg.norm(corners[bad] - point[bad, None, :], axis=2), axis=1)
        bary[bad] = np.eye(3)[nearest]
    bary = np.clip(bary, 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    return SurfacePoints(point, np.linalg.norm(point - queries, axis=1), face, bary)


def closest_points(vertices: np.ndarray, faces: np.ndarray, queries: np.ndarray) -> SurfacePoints:
    """Closest surface points of queries (Q, 3) on the mesh (N, 3) float, (M, 3) int.

    Degenerate triangles count as segments or points (libigl's rule), so every query gets an
    answer on a mesh with at least one face.
    """
    import igl

    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    q = np.ascontiguousarray(queries, np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise ValueError(f"closest_points: expected vertices (N, 3) and faces (M>0, 3), got {v.shape} and {f.shape}")
    if q.ndim != 2 or q.shape[1] != 3:
        raise ValueError(f"closest_points: expected queries of shape (Q, 3), got {q.shape}")
    if len(q) == 0:
        return SurfacePoints(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3)))
    _, face, point = igl.point_mesh_squared_distance(q, v, f)
    return _finish(v[f[face]], q, face, point)


def closest_points_brute_force(vertices, faces, queries) -> SurfacePoints:
    """Exact closest points by testing every triangle for every query (slow; for tests)."""
    triangles = np.asarray(vertices, np.float64)[faces]
    queries = np.asarray(queries, np.float64)
    best_d = np.full(len(queries), np.inf)
    best_f = np.zeros(len(queries), np.int64)
    best_p = np.zeros((len(queries), 3))
    for fi in range(len(faces)):
        p = trimesh.triangles.closest_point(np.repeat(triangles[fi:fi + 1], len(queries), 0), queries)
        d = np.linalg.norm(p - queries, axis=1)
        better = d < best_d
        best_d[better], best_f[better], best_p[better] = d[better], fi, p[better]
    return _finish(triangles[best_f], queries, best_f, best_p)
