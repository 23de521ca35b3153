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

Measurements behind these choices: README, *Measurements behind the defaults*.
"""
from __future__ import annotations

import numpy as np


class ArapRefiner:
    """Refine LBS-posed meshes of characters by ARAP.

    Args:
        rigid: a vertex whose largest skin weight is at least this is held at its LBS position.
        iterations: ARAP local-global iterations.
    """

    def __init__(self, rigid: float = 0.5, iterations: int = 10):
        if not 0 < rigid <= 1:
            raise ValueError(f"rigid: expected a weight in (0, 1], got {rigid}")
        self.rigid = rigid
        self.iterations = iterations
        self._cache: dict[str, tuple] = {}

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

    def refine(self, key: str, rest_vertices: np.ndarray, faces: np.ndarray, weight_values: np.ndarray,
               posed: np.ndarray) -> np.ndarray:
        """ARAP-refined vertices (N, 3) float32; the LBS result itself if the solve is not finite.

        Args:
            key: cache key of the character (its ID).
            rest_vertices: (N, 3) rest mesh; faces: (M, 3) triangles.
            weight_values: (N, J) skin weight values (their row maximum decides what is rigid).
            posed: (N, 3) LBS-posed vertices.
        """
        import igl

        if key not in self._cache:
            v = np.ascontiguousarray(rest_vertices, np.float64)
            f = np.ascontiguousarray(self.solvable_faces(v, faces))
            b = self.handles(f, weight_values, len(v))
            data = igl.ARAPData()
            data.max_iter = self.iterations
            igl.arap_precomputation(v, f, 3, b, data)
            self._cache[key] = (b, data)
        b, data = self._cache[key]
        u0 = np.ascontiguousarray(posed, np.float64)
        out = igl.arap_solve(np.ascontiguousarray(u0[b]), data, u0.copy())
        out = np.asarray(out, np.float64)
        if out.shape != u0.shape or not np.isfinite(out).all():
            return np.asarray(posed, np.float32)
        return out.astype(np.float32)
