import numpy as np

from mimicbench.mesh import edge_lengths, normalize_unit_height, unique_edges, unit_height_frame


def test_unique_edges_of_a_tetrahedron_and_a_quad():
    tet = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    assert unique_edges(tet).tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    assert len(unique_edges(quad)) == 5


def test_edge_lengths_by_hand():
    v = np.array([[0, 0, 0], [3, 4, 0], [0, 0, 2.0]])
    np.testing.assert_allclose(edge_lengths(v, np.array([[0, 1], [0, 2], [1, 2]])), [5, 2, np.sqrt(29)])


def test_unit_height_normalisation():
    v = np.array([[0, 1, 0], [2, 5, 4], [1, 3, -2.0]])
    centre, height = unit_height_frame(v)
    np.testing.assert_allclose(centre, [1, 3, 1])
    assert height == 4
    n = normalize_unit_height(v)
    np.testing.assert_allclose(n.max(0)[1] - n.min(0)[1], 1.0)
    np.testing.assert_allclose((n.max(0) + n.min(0)) / 2, 0, atol=1e-12)
    other = normalize_unit_height(v + 1, reference_rest_vertices=v)
    np.testing.assert_allclose(other, n + 0.25)
