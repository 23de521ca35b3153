"""Check and clean a skinned mesh before resampling.

Bad input (NaN coordinates, faces indexing missing vertices, fewer than 4 faces, zero area
everywhere, unweighted vertices) raises :class:`BadMesh` with the reason. Cleaning merges
duplicate vertices, drops degenerate and duplicate faces, and drops isolated pieces smaller than
a share of the total area, while separate components that are large enough (apparel pieces,
per-bone capsules) are kept. What was removed is reported.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh


class BadMesh(ValueError):
    """A mesh that cannot be resampled; the message says why."""


@dataclass
class CleanMesh:
    """A cleaned mesh with per-vertex data carried through the vertex merge.

    Attributes:
        vertices: (N, 3) float64. faces: (M, 3) int64.
        weights: (N, K) float64 dense skin weights, rows sum to 1.
        apparel: (N,) float64 apparel mask (0 or 1).
        report: counts of what was removed.
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    apparel: np.ndarray
    report: dict = field(default_factory=dict)


def check_mesh(vertices: np.ndarray, faces: np.ndarray, weights: np.ndarray) -> None:
    """Raise :class:`BadMesh` naming the first problem of the input."""
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise BadMesh(f"vertices: expected shape (N, 3), got {vertices.shape}")
    if not np.isfinite(vertices).all():
        raise BadMesh(f"{int((~np.isfinite(vertices)).any(axis=1).sum())} vertices have NaN or inf coordinates")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) < 4:
        raise BadMesh(f"expected at least 4 triangles, got faces of shape {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise BadMesh(f"faces index vertices in [{faces.min()}, {faces.max()}], but there are {len(vertices)} vertices")
    area = trimesh.triangles.area(vertices[faces])
    if not (area > 0).any():
        raise BadMesh("every face has zero area")
    unweighted = weights.sum(axis=1) <= 1e-8
    if unweighted.any():
        raise BadMesh(f"{int(unweighted.sum())} vertices have no skin weight")


def clean_mesh(vertices, faces, weights, apparel, min_piece_area: float = 1e-6) -> CleanMesh:
    """Clean a mesh; ``min_piece_area`` is the smallest piece kept, as a share of the total area."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    w = np.asarray(weights, np.float64)
    check_mesh(v, f, w)
    report = {"vertices_in": int(len(v)), "faces_in": int(len(f))}
    # merge duplicate vertices (exact positions up to 1e-9 of the size); keep the first's data
    scale = float(np.ptp(v, axis=0).max()) or 1.0
    key = np.round(v / (scale * 1e-9)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    report["merged_vertices"] = int(len(v) - len(first))
    v, w, app = v[first], w[first], np.asarray(apparel, np.float64)[first]
    f = inverse[f]
    degenerate = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    degenerate |= trimesh.triangles.area(v[f]) <= 1e-14 * scale * scale
    report["degenerate_faces"] = int(degenerate.sum())
    f = f[~degenerate]
    _, unique_idx = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    report["duplicate_faces"] = int(len(f) - len(unique_idx))
    f = f[np.sort(unique_idx)]
    mesh = trimesh.Trimesh(v, f, process=False)
    labels = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(f))
    area = mesh.area_faces
    piece_area = np.bincount(labels, weights=area)
    small = piece_area < min_piece_area * area.sum()
    report["removed_pieces"] = int(small.sum())
    report["kept_pieces"] = int((~small).sum())
    f = f[~small[labels]]
    if len(f) < 4:
        raise BadMesh(f"only {len(f)} faces are left after cleaning")
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    report["unused_vertices"] = int(len(v) - len(used))
    return CleanMesh(v[used], remap[f], w[used], app[used], report)
