"""Kinematic collision pieces of the body: one convex piece per body bone, from the vertices it owns.

A body bone owns the vertices whose largest skin weight is its own. Its piece is the convex hull
of those vertices in the bone's rest frame (a capsule for a zoo character, whose mesh is one
capsule per bone); it follows the bone's transform exactly: a rest point p maps to
``R(q_k) (p - cbar_k) + t_k``. Bones owning fewer than 4 vertices, or a flat set, get no piece.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from mimicbench.geometry.quaternion import quat_apply, quat_conjugate

MAX_HULL_POINTS = 96  # Bullet's convex-convex tests slow down with many hull points


@dataclass(frozen=True)
class BodyPiece:
    """One body bone's convex piece.

    ``points`` (P, 3) float64 hull points relative to the bone head at rest (what Bullet gets);
    ``planes`` (H, 4) outward planes ``n . x + d <= 0`` inside of the hull of ``points`` (the
    shape Bullet collides with), in the same frame; ``centre`` (3,) and ``radius`` a sphere around
    the points (metres), to skip far points in the inside test.
    """

    bone: int
    points: np.ndarray
    planes: np.ndarray
    centre: np.ndarray
    radius: float


def hull_points(points: np.ndarray, min_extent: float = 1e-4, max_points: int = MAX_HULL_POINTS):
    """The convex hull of ``points`` (P, 3): (its points (H, 3) in input order, scipy's hull), or
    None for fewer than 4 points or a set thinner than ``min_extent`` (metres) in some direction.
    Over ``max_points`` hull points, an evenly spaced subset of them is kept (and its hull)."""
    pts = np.asarray(points, np.float64)
    if len(pts) < 4 or np.linalg.svd(pts - pts.mean(0), compute_uv=False)[-1] < min_extent:
        return None
    try:
        hull = ConvexHull(pts)
    except QhullError:
        return None
    on_hull = pts[np.sort(hull.vertices)]
    if len(on_hull) > max_points:
        on_hull = on_hull[np.linspace(0, len(on_hull) - 1, max_points).astype(int)]
        hull = ConvexHull(on_hull)
    return on_hull, hull


def body_pieces(vertices: np.ndarray, keypoints: np.ndarray, owner: np.ndarray, body_bones: np.ndarray,
                min_extent: float = 1e-4) -> list[BodyPiece]:
    """Convex pieces of the body bones.

    Args:
        vertices: (N, 3) rest vertices, metres.
        keypoints: (K, 3) rest joint heads, metres.
        owner: (N,) int, the dominant bone of each vertex.
        body_bones: (K,) bool, the bones that get a piece (not apparel).
        min_extent: a point set thinner than this (metres) in some direction gets no piece.
    """
    pieces = []
    vertices = np.asarray(vertices, np.float64)
    for k in np.nonzero(body_bones)[0]:
        found = hull_points(vertices[owner == k] - np.asarray(keypoints[k], np.float64), min_extent)
        if found is None:
            continue
        on_hull, hull = found
        centre = 0.5 * (on_hull.min(axis=0) + on_hull.max(axis=0))
        pieces.append(BodyPiece(int(k), on_hull, hull.equations.copy(), centre,
                                float(np.linalg.norm(on_hull - centre, axis=1).max())))
    return pieces


def points_inside(pieces: list[BodyPiece], transforms: np.ndarray, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """(..., P) bool: posed points inside any posed piece (deeper than ``tol`` metres; a negative
    ``tol`` also takes points within ``-tol`` outside it).

    Args:
        transforms: (..., K, 7) poses (q_w, q_x, q_y, q_z, t) of every bone.
        points: (..., P, 3) world points of the same frames.
    """
    points = np.asarray(points, np.float64)
    transforms = np.asarray(transforms, np.float64)
    inside = np.zeros(points.shape[:-1], bool)
    for piece in pieces:
        q = transforms[..., piece.bone, :4]
        t = transforms[..., piece.bone, 4:]
        centre = t + quat_apply(q, piece.centre)  # (..., 3)
        offset = points - centre[..., None, :]
        reach = piece.radius + max(-tol, 0.0)
        near = np.nonzero(np.einsum("...pc,...pc->...p", offset, offset) < reach ** 2)
        if not len(near[0]):
            continue
        qn = np.broadcast_to(q[..., None, :], points.shape[:-1] + (4,))[near]
        local = quat_apply(quat_conjugate(qn), offset[near]) + piece.centre  # (P', 3) rest frame, head at 0
        depth = local @ piece.planes[:, :3].T + piece.planes[:, 3]  # (P', H)
        hit = depth.max(axis=-1) < -tol
        inside[tuple(i[hit] for i in near)] = True
    return inside
