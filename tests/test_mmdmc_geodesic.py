"""G, the vertex-joint geodesic distances of the MMDMC reference (baselines/mmdmc/geodesic.py)."""
from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from mimicbench.baselines.mmdmc.geodesic import anchor_vertices, geodesic_distances, surface_graph
from tests.toys import make_tube


def strip(n: int = 6, width: float = 0.1, step: float = 0.25):
    """A strip of 2n vertices along +Y (two columns x = 0 and x = width), 2(n-1) triangles."""
    v = np.array([[x, step * i, 0.0] for i in range(n) for x in (0.0, width)], np.float32)
    f = []
    for i in range(n - 1):
        a, b, c, d = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
        f += [[a, b, c], [b, d, c]]
    return v, np.array(f, np.int32)


def networkx_reference(v, f, sources):
    """Shortest path lengths along mesh edges by networkx (a second implementation)."""
    g = nx.Graph()
    for tri in f:
        for a, b in ((0, 1), (1, 2), (2, 0)):
            i, j = int(tri[a]), int(tri[b])
            g.add_edge(i, j, weight=float(np.linalg.norm(v[i] - v[j])))
    out = np.zeros((len(v), len(sources)))
    for k, s in enumerate(sources):
        d = nx.single_source_dijkstra_path_length(g, int(s))
        out[:, k] = [d[i] for i in range(len(v))]
    return out


def test_strip_by_hand():
    v, f = strip()
    joints = np.array([[0.0, -0.05, 0.0], [0.1, 1.3, 0.0]], np.float32)  # below vertex 0, above vertex 11
    assert anchor_vertices(v, joints).tolist() == [0, 11]
    g = geodesic_distances(v, f, joints)
    assert g.shape == (12, 2)
    assert g[0, 0] == 0 and g[11, 1] == 0
    # left column from vertex 0: straight up the column edges, 0.25 per row
    np.testing.assert_allclose(g[0::2, 0], 0.25 * np.arange(6), atol=1e-6)
    # vertex 1 is the one edge of length 0.1 away
    assert g[1, 0] == pytest.approx(0.1, abs=1e-6)
    # distances grow along the chain away from each anchor
    assert np.all(np.diff(g[0::2, 0]) > 0) and np.all(np.diff(g[1::2, 1]) < 0)


def test_matches_networkx_on_a_tube():
    tube = make_tube(num_bones=4, rings=10, segments=8)
    v, f, k = np.asarray(tube["vertices"]), np.asarray(tube["faces"]), np.asarray(tube["keypoints"])
    g = geodesic_distances(v, f, k)
    ref = networkx_reference(v, f, anchor_vertices(v, k))
    np.testing.assert_allclose(g, ref, rtol=1e-5, atol=1e-6)
    # each joint's anchor is at distance 0, and a vertex's distance to a joint is never below the straight line
    assert np.all(g[anchor_vertices(v, k), np.arange(len(k))] == 0)
    straight = np.linalg.norm(v[:, None] - v[anchor_vertices(v, k)][None], axis=-1)
    assert np.all(g >= straight - 1e-5)


def test_pieces_are_bridged_at_their_closest_vertices():
    v, f = strip(n=2)
    far = v + np.array([0.0, 0.0, 0.3], np.float32)  # a second strip 0.3 m behind the first
    verts = np.concatenate([v, far])
    faces = np.concatenate([f, f + len(v)])
    g = surface_graph(verts, faces, bridge_neighbours=0)  # spanning-tree bridges only
    from scipy.sparse import csgraph

    assert csgraph.connected_components(g, directed=False)[0] == 1
    d = geodesic_distances(verts, faces, np.array([[0.0, 0.0, 0.0]], np.float32), bridge_neighbours=0)
    assert np.isfinite(d).all()
    # the bridge joins two vertices 0.3 apart: every vertex of the far strip is exactly 0.3 beyond its twin
    # or further, and the twin of the anchor is at 0.3 or more by the shortest path through some bridge
    assert d[len(v):].min() == pytest.approx(0.3, abs=1e-6)


def test_bad_input_says_what_was_expected():
    v, f = strip()
    with pytest.raises(ValueError, match=r"keypoints: expected shape \(\?, 3\)"):
        geodesic_distances(v, f, np.zeros((2, 2)))
