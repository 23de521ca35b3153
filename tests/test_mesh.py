import numpy as np

from mimicbench.geometry.mesh import edge_lengths, mesh_pieces, normalize_unit_height, unique_edges, unit_height_frame


def test_unique_edges_of_a_tetrahedron_and_a_quad():
    tet = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    assert unique_edges(tet).tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    assert len(unique_edges(quad)) == 5


def test_mesh_pieces_by_hand_and_as_trimesh_finds_them():
    # two triangles sharing an edge are one piece; a triangle apart is another; vertex 7 is in no face
    f = np.array([[0, 1, 2], [3, 4, 5], [2, 6, 1]])
    assert mesh_pieces(f, 8).tolist() == [0, 0, 0, 1, 1, 1, 0, 2]
    import trimesh

    a, b = trimesh.creation.icosphere(1), trimesh.creation.box()
    faces = np.concatenate([b.faces + len(a.vertices), a.faces])  # the second piece's faces first
    label = mesh_pieces(faces, len(a.vertices) + len(b.vertices))
    expected = trimesh.graph.connected_component_labels(trimesh.geometry.faces_to_edges(faces), len(label))
    assert len(np.unique(label)) == 2 and (label[:len(a.vertices)] == label[0]).all()
    assert len(np.unique(np.stack([label, expected], 1), axis=0)) == 2  # the same partition


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
