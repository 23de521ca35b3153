"""Test-time as-rigid-as-possible refinement of an LBS-posed mesh (libigl's ARAP).

LBS blends rigid bone transforms and so thins joints and shears skin between bones. The
refinement keeps the vertices that one bone owns outright (largest skin weight >= ``rigid``) where
LBS put them and solves ARAP (Sorkine and Alexa 2007; libigl ``arap_precomputation`` /
``arap_solve``) from the rest mesh for the others, starting from the LBS result. Each connected
component of the mesh keeps at least three fixed vertices (its most rigidly bound ones) so no
rotation is left free; a vertex that no triangle uses is held too, and degenerate (zero-area)
triangles, whose cotangent weights are infinite, are left out of the solve. The precomputation
depends only on the rest mesh and its weights and is cached per character.

The default ``rigid=0.5`` holds the vertices a majority of whose weight one bone carries (every
vertex that only two bones share among them) and lets ARAP re-solve the ones blended between
three or more bones.

The solve runs on the mesh welded at ``weld`` (1e-3) of its size: vertices closer than that (or
joined by an edge that short) form one cluster, solved as one vertex at their mean, and each
vertex then takes its cluster's solution plus its own LBS offset from the cluster's LBS mean, so
what is shorter than the tolerance deforms exactly as LBS deformed it (resampled real meshes keep
zero-area triangles whose two sides an unwelded solve pulled apart).

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np


WELD = 1e-3
"""Default weld tolerance, a fraction of the mesh's largest bounding-box side (see the module docstring)."""


class ArapRefiner:
    """Refine LBS-posed meshes of characters by ARAP.

    Args:
        rigid: a vertex whose largest skin weight is at least this is held at its LBS position.
        iterations: ARAP local-global iterations.
        weld: vertices closer than this fraction of the mesh's size are solved as one (0: only
            coincident ones).
    """

    def __init__(self, rigid: float = 0.5, iterations: int = 10, weld: float = WELD):
        if not 0 < rigid <= 1:
            raise ValueError(f"rigid: expected a weight in (0, 1], got {rigid}")
        if not 0 <= weld < 1:
            raise ValueError(f"weld: expected a fraction of the mesh's size in [0, 1), got {weld}")
        self.rigid = rigid
        self.iterations = iterations
        self.weld = weld
        self._cache: dict[str, tuple] = {}

    def clusters(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(N,) int64 cluster label of each vertex: vertices joined by a mesh edge shorter than
        ``weld`` times the mesh's size (largest bounding-box side), or closer than that without an
        edge, share a label (transitively); labels are 0..C-1 in order of first vertex."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        v = np.asarray(vertices, np.float64)
        f = np.asarray(faces, np.int64)
        size = float((v.max(axis=0) - v.min(axis=0)).max()) if len(v) else 1.0
        tol = self.weld * size
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        short = edges[np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1) <= tol]
        near = cKDTree(v).query_pairs(tol, output_type="ndarray") if len(v) else np.zeros((0, 2), np.int64)
        pairs = np.concatenate([short, near.astype(np.int64).reshape(-1, 2)])
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(v), len(v)))
        _, label = connected_components(graph, directed=False)
        _, first = np.unique(label, return_index=True)
        order = np.empty(len(first), np.int64)
        order[np.argsort(first)] = np.arange(len(first))  # relabel by first vertex
        return order[label]

    @staticmethod
    def solvable_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(M', 3) int64 the triangles of non-zero area (relative to the mesh's size)."""
        v = np.asarray(vertices, np.float64)
        f = np.asarray(faces, np.int64)
        area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
        size = float((v.max(axis=0) - v.min(axis=0)).max()) if len(v) else 1.0
        return f[area > 1e-10 * size * size]

    def handles(self, faces: np.ndarray, weight_values: np.ndarray, num_vertices: int) -> np.ndarray:
        """(H,) int32 fixed vertices: rigidly bound ones, those no triangle of ``faces`` uses, and
        the three most rigidly bound
        vertices of each connected component that has fewer than three."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        top = np.asarray(weight_values).max(axis=1)
        fixed = top >= self.rigid
        f = np.asarray(faces, np.int64)
        used = np.zeros(num_vertices, bool)
        used[f.ravel()] = True
        fixed |= ~used
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(num_vertices, num_vertices))
        n_comp, label = connected_components(graph, directed=False)
        for c in range(n_comp):
            members = np.flatnonzero(label == c)
            if fixed[members].sum() < 3:  # fewer than three leave a rotation free: fix the most rigid three
                fixed[members[np.argsort(-top[members], kind="stable")[:3]]] = True
        return np.flatnonzero(fixed).astype(np.int32)

    def _prepared(self, key: str, rest_vertices: np.ndarray, faces: np.ndarray, weight_values: np.ndarray) -> tuple:
        """Cached per ``key``: cluster labels (N,), cluster sizes (C,), held clusters (H,) and
        libigl's ARAP data of the welded mesh."""
        import igl

        if key not in self._cache:
            rest = np.asarray(rest_vertices, np.float64)
            label = self.clusters(rest, faces)
            count = np.bincount(label).astype(np.float64)
            v = np.ascontiguousarray(_cluster_mean(rest, label, count))
            f = label[np.asarray(faces, np.int64)]
            f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
            f = np.ascontiguousarray(self.solvable_faces(v, f))
            top = np.zeros(len(v))
            np.maximum.at(top, label, np.asarray(weight_values, np.float64).max(axis=1))
            b = self.handles(f, top[:, None], len(v))
            data = igl.ARAPData()
            data.max_iter = self.iterations
            igl.arap_precomputation(v, f, 3, b, data)
            self._cache[key] = (label, count, b, data)
        return self._cache[key]

    def held(self, key: str, rest_vertices: np.ndarray, faces: np.ndarray, weight_values: np.ndarray) -> np.ndarray:
        """(H,) int64 the vertices :meth:`refine` keeps at their LBS position: those of a held
        cluster (one whose members include a rigidly bound vertex, or a cluster :meth:`handles`
        fixes otherwise)."""
        label, _, b, _ = self._prepared(key, rest_vertices, faces, weight_values)
        return np.flatnonzero(np.isin(label, b))

    def refine(self, key: str, rest_vertices: np.ndarray, faces: np.ndarray, weight_values: np.ndarray,
               posed: np.ndarray) -> np.ndarray:
        """ARAP-refined vertices (N, 3) float32; the LBS result itself if the solve is not finite.

        ARAP is solved on the welded mesh (:meth:`clusters`: one vertex a cluster at its members'
        mean, faces that collapse left out); each vertex then takes its cluster's solution plus
        its own LBS offset from the cluster's LBS mean, so what is shorter than the weld
        tolerance deforms as LBS deformed it.

        Args:
            key: cache key of the character (its ID).
            rest_vertices: (N, 3) rest mesh; faces: (M, 3) triangles.
            weight_values: (N, J) skin weight values (their row maximum decides what is rigid).
            posed: (N, 3) LBS-posed vertices.
        """
        import igl

        label, count, b, data = self._prepared(key, rest_vertices, faces, weight_values)
        lbs = np.asarray(posed, np.float64)
        u0 = np.ascontiguousarray(_cluster_mean(lbs, label, count))
        out = igl.arap_solve(np.ascontiguousarray(u0[b]), data, u0.copy())
        out = np.asarray(out, np.float64)
        if out.shape != u0.shape or not np.isfinite(out).all():
            return np.asarray(posed, np.float32)
        return (out[label] + lbs - u0[label]).astype(np.float32)


def _cluster_mean(points: np.ndarray, label: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(C, 3) mean of ``points`` (N, 3) per cluster ``label`` (N,) of sizes ``count`` (C,)."""
    out = np.zeros((len(count), 3))
    np.add.at(out, label, points)
    return out / count[:, None]
