"""Mesh helpers: unique edges, edge lengths, pieces (connected components), unit-height normalisation."""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.validation import check_shape


def unique_edges(faces: np.ndarray) -> np.ndarray:
    """Unique undirected edges (E, 2) int64 of triangles (M, 3), each as (low, high), sorted."""
    f = check_shape(faces, (None, 3), "faces").astype(np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=0)
    e = np.sort(e, axis=1)
    return np.unique(e, axis=0)


def mesh_pieces(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """(N,) int64 label, 0 to P - 1, of the piece of each of N vertices: connected along the edges of
    faces (M, 3) (a vertex in no face is a piece of its own). Vertices are not welded: pieces that
    only touch (the zoo's capsules at its joints, its hair strands and cape links) stay apart.

    >>> mesh_pieces(np.array([[0, 1, 2], [3, 4, 5], [2, 1, 6]]), 8).tolist()
    [0, 0, 0, 1, 1, 1, 0, 2]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, np.int64).reshape(-1, 3)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])  # two edges join a face's corners; repeats are harmless
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(num_vertices, num_vertices))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def edge_lengths(vertices: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Lengths (..., E) of edges (E, 2) of vertices (..., N, 3)."""
    v = np.asarray(vertices)
    return np.linalg.norm(v[..., edges[:, 0], :] - v[..., edges[:, 1], :], axis=-1)


def unit_height_frame(rest_vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) of the bounding box of rest vertices (N, 3) and their height (Y extent, metres)."""
    v = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    height = float(hi[1] - lo[1])
    if not height > 0:
        raise ValueError(f"rest_vertices: expected a positive Y extent, got {height}")
    return (lo + hi) / 2.0, height


def normalize_unit_height(vertices: np.ndarray, reference_rest_vertices: np.ndarray | None = None) -> np.ndarray:
    """Map vertices (..., N, 3) into the unit-height frame of a reference rest mesh.

    Centre at the reference's bounding-box centre and divide by its height (Y extent). The
    reference defaults to ``vertices`` itself (which must then be (N, 3)).
    """
    ref = vertices if reference_rest_vertices is None else reference_rest_vertices
    centre, height = unit_height_frame(ref)
    return (np.asarray(vertices, dtype=np.float64) - centre) / height
