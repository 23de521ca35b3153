"""The mesh inputs SFPT's networks read: directed mesh edges (EdgeConv's graph) and per-vertex normals."""
from __future__ import annotations

import numpy as np
import torch


def mesh_edges(faces: np.ndarray, count: int) -> np.ndarray:
    """(E, 2) int64 directed edges (i, j) of triangles (M, 3), both directions of each unique edge, plus a
    self loop (i, i) for every one of the ``count`` vertices (so an isolated vertex keeps its own feature)."""
    f = np.asarray(faces, np.int64)
    if f.size and (f.min() < 0 or f.max() >= count):
        raise ValueError(f"faces: expected vertex indices in [0, {count}), got [{f.min()}, {f.max()}]")
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]) if f.size else np.zeros((0, 2), np.int64)
    e = e[e[:, 0] != e[:, 1]]
    e = np.unique(np.sort(e, axis=1), axis=0)
    loops = np.repeat(np.arange(count, dtype=np.int64)[:, None], 2, axis=1)
    return np.concatenate([e, e[:, ::-1], loops]).astype(np.int64)


def vertex_normals(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """(N, 3) unit vertex normals: the normalised sum of the unit normals of the triangles (M, 3) at each vertex
    of ``vertices`` (N, 3) (zero where a vertex has no triangle of non-zero area)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    fn = torch.nn.functional.normalize(torch.linalg.cross(b - a, c - a), dim=-1, eps=1e-12)
    out = torch.zeros_like(vertices).index_add_(0, faces.reshape(-1), fn.repeat_interleave(3, dim=0))
    return torch.nn.functional.normalize(out, dim=-1, eps=1e-12)
