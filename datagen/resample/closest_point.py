"""Closest points on a triangle mesh, with the triangle and barycentric coordinates.

Candidates come from a scipy cKDTree over triangle centroids (the ``candidates`` nearest
centroids per query), then ``trimesh.triangles.closest_point`` gives the exact closest point on
each candidate triangle and the nearest one wins. That alone can miss a large triangle whose
centroid is far; so the result is certified: the few largest triangles are checked for every
query, and with r the largest centroid-to-corner distance of the others, no other triangle whose
centroid lies beyond ``best + r`` can be closer; queries whose candidate ring does not reach that
far get four times more candidates until it does. The answer is
exact; :func:`closest_points_brute_force` is the reference the tests compare with.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree


@dataclass
class SurfacePoints:
    """Per query: the closest point (Q, 3), its distance (Q,), face index (Q,) and barycentric
    coordinates (Q, 3) in that face."""

    points: np.ndarray
    distances: np.ndarray
    faces: np.ndarray
    barycentric: np.ndarray


def _finish(triangles, queries, best_face, best_point):
    bary = trimesh.triangles.points_to_barycentric(triangles[best_face], best_point)
    bary = np.clip(bary, 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    return SurfacePoints(best_point, np.linalg.norm(best_point - queries, axis=1), best_face, bary)


def _nearest_on_candidates(triangles, queries, cand):
    q, k = cand.shape
    pts = trimesh.triangles.closest_point(triangles[cand.ravel()], np.repeat(queries, k, axis=0)).reshape(q, k, 3)
    d = np.linalg.norm(pts - queries[:, None, :], axis=2)
    j = np.argmin(d, axis=1)
    rows = np.arange(q)
    return cand[rows, j], pts[rows, j], d[rows, j]


def closest_points(vertices: np.ndarray, faces: np.ndarray, queries: np.ndarray, candidates: int = 16,
                   always_checked: int = 32) -> SurfacePoints:
    """Exact closest surface points of queries (Q, 3) on the mesh (N, 3), (M, 3).

    The ``always_checked`` triangles with the largest centroid-to-corner radius are tested for
    every query; the others through the centroid tree, certified with the largest radius among
    them (so a few huge triangles do not loosen the bound for all).
    """
    triangles = np.asarray(vertices, np.float64)[faces]
    queries = np.asarray(queries, np.float64)
    centroids = triangles.mean(axis=1)
    radii = np.linalg.norm(triangles - centroids[:, None, :], axis=2).max(axis=1)
    order = np.argsort(-radii)
    big, rest = order[: min(always_checked, len(faces) - 1)], np.sort(order[min(always_checked, len(faces) - 1):])
    radius = radii[rest].max()
    tree = cKDTree(centroids[rest])
    best_face = np.zeros(len(queries), np.int64)
    best_point = np.zeros((len(queries), 3))
    best_d = np.full(len(queries), np.inf)
    if len(big):
        best_face, best_point, best_d = _nearest_on_candidates(triangles, queries, np.tile(big, (len(queries), 1)))
    todo = np.arange(len(queries))
    k = min(candidates, len(rest))
    while len(todo):
        cdist, cand = tree.query(queries[todo], k=k)
        cdist, cand = cdist.reshape(len(todo), k), rest[cand.reshape(len(todo), k)]
        f, p, d = _nearest_on_candidates(triangles, queries[todo], cand)
        better = d < best_d[todo]
        best_face[todo[better]], best_point[todo[better]], best_d[todo[better]] = f[better], p[better], d[better]
        if k == len(rest):
            break
        # certified when every unseen triangle's centroid is beyond best + radius
        todo = todo[cdist[:, -1] < best_d[todo] + radius]
        k = min(k * 4, len(rest))
    return _finish(triangles, queries, best_face, best_point)


def closest_points_brute_force(vertices, faces, queries) -> SurfacePoints:
    """Exact closest points by testing every triangle for every query (slow; for tests)."""
    triangles = np.asarray(vertices, np.float64)[faces]
    best_d = np.full(len(queries), np.inf)
    best_f = np.zeros(len(queries), np.int64)
    best_p = np.zeros((len(queries), 3))
    for fi in range(len(faces)):
        p = trimesh.triangles.closest_point(np.repeat(triangles[fi:fi + 1], len(queries), 0), queries)
        d = np.linalg.norm(p - queries, axis=1)
        better = d < best_d
        best_d[better], best_f[better], best_p[better] = d[better], fi, p[better]
    return _finish(triangles, queries, best_f, best_p)
