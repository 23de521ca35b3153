"""Closest points of resampled vertices on their own piece of the original mesh.

A piece is a connected component along faces (:func:`mimicbench.geometry.mesh.mesh_pieces`). Re-skinning
takes a new vertex's weights at its closest point on the original surface. Taken on any piece, that
point would give vertices of the zoo's thin hair strands, which decimation leaves a few millimetres
off their own surface (a strand's link collapsed to a handful of vertices), the weights of the cape
or of the next link lying nearer. :func:`mimicbench.datagen.resample.simplify.resample_to`
says which piece each new vertex came from, and the closest point is taken on that piece alone.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.resample.closest_point import SurfacePoints, closest_points
from mimicbench.geometry.mesh import mesh_pieces


def own_piece_points(old_vertices: np.ndarray, old_faces: np.ndarray, new_vertices: np.ndarray,
                     new_pieces: np.ndarray, anywhere: SurfacePoints | None = None) -> SurfacePoints:
    """Closest points of the new vertices on the original pieces they came from.

    Args:
        old_vertices: (N, 3) float64 and old_faces: (M, 3) int64, the original mesh.
        new_vertices: (Q, 3) float64, the resampled vertices.
        new_pieces: (Q,) int, the piece of the original mesh (its :func:`mimicbench.geometry.mesh.mesh_pieces`
            label) each new vertex came from, as :func:`mimicbench.datagen.resample.simplify.resample_to` gives it.
        anywhere: closest points of the new vertices on the whole original mesh; computed when not
            given.

    Returns:
        :class:`SurfacePoints` (Q,): ``anywhere``'s where that point lies on the vertex's own piece,
        else the closest point on its own piece (face indices into ``old_faces``).
    """
    old_v, old_f = np.asarray(old_vertices, np.float64), np.asarray(old_faces, np.int64)
    new_v, new_pieces = np.asarray(new_vertices, np.float64), np.asarray(new_pieces, np.int64)
    if new_pieces.shape != (len(new_v),):
        raise ValueError(f"new_pieces: expected shape ({len(new_v)},), got {new_pieces.shape}")
    if anywhere is None:
        anywhere = closest_points(old_v, old_f, new_v)
    face_piece = mesh_pieces(old_f, len(old_v))[old_f[:, 0]]  # (M,)
    move = face_piece[anywhere.faces] != new_pieces
    if not move.any():
        return anywhere
    points, distances = anywhere.points.copy(), anywhere.distances.copy()
    faces, barycentric = anywhere.faces.copy(), anywhere.barycentric.copy()
    for piece in np.unique(new_pieces[move]):
        query = np.flatnonzero(move & (new_pieces == piece))
        own = np.flatnonzero(face_piece == piece)
        if len(own) == 0:
            raise ValueError(f"new_pieces: piece {piece} is not a piece of the original mesh")
        found = closest_points(old_v, old_f[own], new_v[query])
        points[query], distances[query] = found.points, found.distances
        faces[query], barycentric[query] = own[found.faces], found.barycentric
    return SurfacePoints(points, distances, faces, barycentric)
