"""Check and clean a skinned mesh before resampling.

Bad input (NaN coordinates, faces indexing missing vertices, fewer than 4 faces, zero area
everywhere, unweighted vertices) raises :class:`BadMesh` with the reason. Cleaning merges
duplicate vertices, drops degenerate and duplicate faces, and drops isolated pieces smaller than
a share of the total area, while separate components that are large enough (apparel pieces,
per-bone capsules) are kept. What was removed is reported.

:func:`weld_short_edges` cleans the resampled mesh the same way before it is re-skinned: quadric
edge collapse (fast-simplification above all, on a subdivided mesh) leaves clusters of vertices
a few 1e-7 of the size apart, joined by near-zero edges in zero-area triangles, which no pose
transfer can keep at their rest length (ELS divides by it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from mimicbench.geometry.mesh import mesh_pieces
from mimicbench.schemas.weights import SparseWeights


class BadMesh(ValueError):
    """A mesh that cannot be resampled; the message says why."""


@dataclass
class CleanMesh:
    """A cleaned mesh with per-vertex data carried through the vertex merge.

    Attributes:
        vertices: (N, 3) float64. faces: (M, 3) int64.
        weights: skin weights of the N vertices, rows sum to 1.
        apparel: (N,) float64 apparel mask (0 or 1).
        report: counts of what was removed.
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: SparseWeights
    apparel: np.ndarray
    report: dict = field(default_factory=dict)


def check_mesh(vertices: np.ndarray, faces: np.ndarray, weights: SparseWeights) -> None:
    """Raise :class:`BadMesh` naming the first problem of the input."""
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise BadMesh(f"vertices: expected shape (N, 3), got {vertices.shape}")
    if not np.isfinite(vertices).all():
        raise BadMesh(f"{int((~np.isfinite(vertices)).any(axis=1).sum())} vertices have NaN or inf coordinates")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) < 4:
        raise BadMesh(f"expected at least 4 triangles, got faces of shape {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise BadMesh(f"faces index vertices in [{faces.min()}, {faces.max()}], but there are {len(vertices)} vertices")
    if weights.num_vertices != len(vertices):
        raise BadMesh(f"weights: expected {len(vertices)} rows, got {weights.num_vertices}")
    area = trimesh.triangles.area(vertices[faces])
    if not (area > 0).any():
        raise BadMesh("every face has zero area")
    unweighted = weights.row_sums() <= 1e-8
    if unweighted.any():
        raise BadMesh(f"{int(unweighted.sum())} vertices have no skin weight")


def _merge_duplicates(v: np.ndarray, scale: float, apart: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(first, inverse): the first vertex of each group of equal positions (up to 1e-9 of
    ``scale``), in their original order, and each vertex's group. ``apart`` (N,) int: vertices
    with different values are never grouped, wherever they are."""
    key = np.round(v / (scale * 1e-9)).astype(np.int64)
    if apart is not None:
        key = np.concatenate([key, np.asarray(apart, np.int64)[:, None]], axis=1)
    key = np.ascontiguousarray(key)
    _, first, inverse = np.unique(key.view(np.dtype((np.void, 8 * key.shape[1]))).ravel(), return_index=True,
                                  return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[inverse.reshape(-1)]


def apparel_owners(weights: SparseWeights, apparel) -> np.ndarray:
    """(N,) int: each apparel vertex's dominant bone (:meth:`SparseWeights.dominant`),
    -1 for the body's. :func:`clean_mesh` never welds vertices with different owners: a zoo's hair
    strands, skirt strips and cape links are separate pieces whose ends touch (same positions,
    other bones), and welded they would be decimated into one piece whose edges stretch up to 7x
    between strands once the physics moves them apart. Seams of one surface (the same weights on both
    sides) still weld."""
    return np.where(np.asarray(apparel, np.float64) > 0.5, weights.dominant(), -1)


WELD_TOLERANCE = 1e-5
"""Edges shorter than this share of the mesh's largest bounding-box side are collapsed after
resampling. On the shared assets at 5,000 faces fast-simplification leaves 48-315 edges per mesh
between 1e-10 and 1e-6 of the size, and a few dozen between 1e-6 and 1e-3; a typical edge is
about 1.5e-2. 1e-5 is far above float32's resolution (6e-8 of the size)."""


def _zero_area(v: np.ndarray, f: np.ndarray, scale: float) -> np.ndarray:
    """(M,) bool: faces (M, 3) of ``v`` (N, 3) whose area is below 1e-12 * ``scale``^2."""
    return trimesh.triangles.area(v[f]) < 1e-12 * scale * scale


def weld_short_edges(vertices: np.ndarray, faces: np.ndarray, tolerance: float = WELD_TOLERANCE
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Collapse every edge shorter than ``tolerance`` times the mesh's size (its largest
    bounding-box side) into one vertex, then drop the faces that lost a corner, faces of zero area
    (below 1e-12 * size^2), duplicate faces (the same three corners) and unused vertices.

    A mesh with no short edge and no zero-area face is returned as given (the same arrays), its
    duplicate faces included: decimating the zoo's capes to 2,000 faces folds some strips into
    pairs of faces on the same three corners, which have area and leave every edge's length as it
    is (ELS counts unique edges), and the zoo's resampled bytes stay the same.

    Only mesh edges are collapsed, never vertices of separate pieces that merely lie close. A
    group of vertices joined by short edges (transitively) becomes its lowest-index vertex, so no
    new coordinates are made; collapsing repeats until no short edge is left. Vertices keep their
    order.

    Args:
        vertices: (N, 3) float64. faces: (M, 3) int64.

    Returns:
        (vertices (N', 3), faces (M', 3), kept (N',) int64, report): ``kept`` holds the index in
        ``vertices`` of each vertex kept; the report counts ``welded_vertices``, ``collapsed_faces``
        (lost a corner), ``zero_area_faces``, ``duplicate_faces`` and ``unused_vertices``.
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    scale = float(np.ptp(v, axis=0).max()) if len(v) else 1.0
    scale = scale or 1.0
    report = {"welded_vertices": 0, "collapsed_faces": 0, "zero_area_faces": 0, "duplicate_faces": 0,
              "unused_vertices": 0}
    while True:
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        short = edges[np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1) < tolerance * scale]
        zero = _zero_area(v, f, scale)
        if not len(short) and not zero.any():
            break
        if len(short):
            graph = coo_matrix((np.ones(len(short), np.int8), (short[:, 0], short[:, 1])), shape=(len(v), len(v)))
            _, label = connected_components(graph, directed=False)
            lowest = np.full(label.max() + 1, len(v), np.int64)
            np.minimum.at(lowest, label, np.arange(len(v)))
            report["welded_vertices"] += int((lowest[label] != np.arange(len(v))).sum())
            f = lowest[label][f]
            lost = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
            report["collapsed_faces"] += int(lost.sum())
            f = f[~lost]
            continue  # welding can leave new short edges and removes most zero-area faces
        report["zero_area_faces"] += int(zero.sum())
        f = f[~zero]
    if report["welded_vertices"] == 0 and report["zero_area_faces"] == 0:
        return vertices, faces, np.arange(len(v)), report
    corners = np.ascontiguousarray(np.sort(f, axis=1))
    _, unique_idx = np.unique(corners.view(np.dtype((np.void, 24))).ravel(), return_index=True)
    report["duplicate_faces"] = int(len(f) - len(unique_idx))
    f = f[np.sort(unique_idx)]
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    report["unused_vertices"] = int(len(v) - len(used) - report["welded_vertices"])
    return v[used], remap[f], used, report


def clean_mesh(vertices, faces, weights: SparseWeights, apparel, min_piece_area: float = 1e-6) -> CleanMesh:
    """Clean a mesh; ``min_piece_area`` is the smallest piece kept, as a share of the total area."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    check_mesh(v, f, weights)
    report = {"vertices_in": int(len(v)), "faces_in": int(len(f))}
    scale = float(np.ptp(v, axis=0).max()) or 1.0
    first, inverse = _merge_duplicates(v, scale, apparel_owners(weights, apparel))
    report["merged_vertices"] = int(len(v) - len(first))
    v, app = v[first], np.asarray(apparel, np.float64)[first]
    f = inverse[f]
    degenerate = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    area = trimesh.triangles.area(v[f])
    degenerate |= area <= 1e-14 * scale * scale
    report["degenerate_faces"] = int(degenerate.sum())
    f, area = f[~degenerate], area[~degenerate]
    corners = np.ascontiguousarray(np.sort(f, axis=1))
    _, unique_idx = np.unique(corners.view(np.dtype((np.void, 24))).ravel(), return_index=True)
    report["duplicate_faces"] = int(len(f) - len(unique_idx))
    keep = np.sort(unique_idx)
    f, area = f[keep], area[keep]
    labels = mesh_pieces(f, len(v))[f[:, 0]]  # each face's piece
    piece_area = np.bincount(labels, weights=area)
    used_pieces = np.unique(labels)
    small = np.zeros(len(piece_area), bool)
    small[used_pieces] = piece_area[used_pieces] < min_piece_area * area.sum()
    report["removed_pieces"] = int(small.sum())
    report["kept_pieces"] = int(len(used_pieces) - small.sum())
    f = f[~small[labels]]
    if len(f) < 4:
        raise BadMesh(f"only {len(f)} faces are left after cleaning")
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    report["unused_vertices"] = int(len(v) - len(used))
    return CleanMesh(v[used], remap[f], weights.take(first[used]), app[used], report)
