"""Vertex-joint geodesic distances G (MMDMC Sec. 4.2): shortest paths along mesh edges from each
joint's anchor, the surface vertex closest to the joint (joints sit inside the mesh).

Meshes made of separate pieces (the zoo's characters are one capsule per bone; MMD models have
loose hair and accessories) are bridged first: every vertex is joined to its nearest vertices in
other pieces (``bridge_neighbours``, by Euclidean length), and pieces still apart are joined at
their closest vertex pair along a minimum spanning tree of the pieces, so every distance is
finite. Shortest paths come from :func:`scipy.sparse.csgraph.dijkstra`.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from mimicbench.geometry.mesh import unique_edges
from mimicbench.geometry.validation import check_shape


def anchor_vertices(vertices: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """(K,) int64 index of the vertex (N, 3) closest to each joint (K, 3)."""
    v = check_shape(vertices, (None, 3), "vertices")
    k = check_shape(keypoints, (None, 3), "keypoints")
    return cKDTree(np.asarray(v, np.float64)).query(np.asarray(k, np.float64))[1].astype(np.int64)


def _graph(n: int, edges: np.ndarray, vertices: np.ndarray) -> sp.csr_matrix:
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    length = np.maximum(length, 1e-9)  # csgraph reads an explicit 0 as "no edge"
    g = sp.coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    return g.maximum(g.T)


def surface_graph(vertices: np.ndarray, faces: np.ndarray, bridge_neighbours: int = 4) -> sp.csr_matrix:
    """Symmetric (N, N) CSR graph of edge lengths: mesh edges plus bridges between pieces.

    Args:
        vertices: (N, 3) rest vertices, metres.
        faces: (M, 3) triangles.
        bridge_neighbours: nearest vertices (of the whole mesh) each vertex looks at for a bridge to
            another piece; 0 keeps only the minimum-spanning-tree bridges.
    """
    v = np.asarray(check_shape(vertices, (None, 3), "vertices"), np.float64)
    n = len(v)
    edges = unique_edges(faces) if len(faces) else np.zeros((0, 2), np.int64)
    g = _graph(n, edges, v)
    count, label = csgraph.connected_components(g, directed=False)
    if count == 1:
        return g
    tree = cKDTree(v)
    extra = []
    if bridge_neighbours > 0:
        _, nn = tree.query(v, k=min(bridge_neighbours + 1, n))
        i = np.repeat(np.arange(n), nn.shape[1])
        j = nn.reshape(-1)
        keep = label[i] != label[j]
        extra.append(np.stack([i[keep], j[keep]], 1))
    g = _graph(n, np.concatenate([edges] + extra), v)
    count, label = csgraph.connected_components(g, directed=False)
    if count > 1:  # join what is still apart at the closest vertex pairs, along a spanning tree
        pieces = [np.flatnonzero(label == c) for c in range(count)]
        gap = np.full((count, count), np.inf)
        pair = {}
        for a in range(count):
            ta = cKDTree(v[pieces[a]])
            for b in range(a + 1, count):
                d, idx = ta.query(v[pieces[b]])
                m = int(np.argmin(d))
                gap[a, b] = max(d[m], 1e-9)
                pair[a, b] = (pieces[a][idx[m]], pieces[b][m])
        mst = csgraph.minimum_spanning_tree(sp.csr_matrix(np.where(np.isfinite(gap), gap, 0))).tocoo()
        joins = np.array([pair[min(a, b), max(a, b)] for a, b in zip(mst.row, mst.col)], np.int64).reshape(-1, 2)
        g = _graph(n, np.concatenate([edges] + extra + [joins]), v)
    return g


def geodesic_distances(vertices: np.ndarray, faces: np.ndarray, keypoints: np.ndarray,
                       bridge_neighbours: int = 4) -> np.ndarray:
    """G: (N, K) float32 geodesic distance, metres, from every vertex to every joint's anchor.

    ``G[anchor_vertices(...)[k], k] == 0`` for every joint k.
    """
    anchors = anchor_vertices(vertices, keypoints)
    g = surface_graph(vertices, faces, bridge_neighbours)
    d = csgraph.dijkstra(g, directed=False, indices=np.unique(anchors))
    row = {a: i for i, a in enumerate(np.unique(anchors))}
    out = d[[row[a] for a in anchors]].T
    if not np.isfinite(out).all():  # cannot happen after bridging; say so rather than feed inf on
        raise ValueError("geodesic_distances: some vertices are unreachable from a joint's anchor")
    return out.astype(np.float32)
