"""Resampled meshes have no degenerate faces: :func:`mimicbench.datagen.resample.clean.weld_short_edges`
against a hand edge collapse, and resampling (a low-poly sphere; every shared real asset) checked
with areas and lengths computed here."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimicbench.datagen.resample.clean import weld_short_edges
from mimicbench.datagen.resample.simplify import decimate, resample_to


def face_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(M,) triangle areas by the cross product, in float64."""
    v = np.asarray(v, np.float64)
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)


def edge_lengths_of(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(3M,) length of every face side, in float64."""
    v = np.asarray(v, np.float64)
    return np.concatenate([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)])


def size_of(v: np.ndarray) -> float:
    return float(np.ptp(np.asarray(v, np.float64), axis=0).max())


def test_a_short_edge_collapses_as_a_hand_edge_collapse():
    sphere = trimesh.creation.icosphere(2)
    v, f = sphere.vertices.copy(), sphere.faces.astype(np.int64)
    a, b = sorted(f[0, :2])
    v[b] = v[a] + 1e-8 * np.array([1.0, 0.0, 0.0])  # the edge a-b is now 1e-8 of the size (2)
    out_v, out_f, kept, report = weld_short_edges(v, f)
    assert kept.tolist() == [i for i in range(len(v)) if i != b]
    # the hand collapse: b becomes a, the two faces on the edge go, the vertices after b move down one
    expected_faces = []
    for face in f.tolist():
        face = [a if i == b else i for i in face]
        if len(set(face)) == 3:
            expected_faces.append([i - (i > b) for i in face])
    np.testing.assert_allclose(out_v, np.delete(v, b, axis=0), rtol=0, atol=0)
    assert out_f.tolist() == expected_faces
    assert len(expected_faces) == len(f) - 2
    assert report["welded_vertices"] == 1 and report["collapsed_faces"] == 2 and report["zero_area_faces"] == 0


def test_a_cluster_of_three_vertices_becomes_its_lowest_vertex():
    sphere = trimesh.creation.icosphere(2)
    v, f = sphere.vertices.copy(), sphere.faces.astype(np.int64)
    i, j, k = sorted(f[5])
    v[j] = v[i] + [0.0, 2e-7, 0.0]
    v[k] = v[i] + [0.0, 0.0, 3e-7]  # a tiny triangle, as fast-simplification leaves at sharp corners
    out_v, out_f, _, report = weld_short_edges(v, f)
    assert report["welded_vertices"] == 2 and len(out_v) == len(v) - 2
    np.testing.assert_allclose(out_v[i], v[i], rtol=0, atol=0)
    assert face_areas(out_v, out_f).min() > 1e-12 * size_of(out_v) ** 2
    assert edge_lengths_of(out_v, out_f).min() > 1e-5 * size_of(out_v)
    assert len(np.unique(out_f)) == len(out_v)  # every vertex is used


def test_a_zero_area_sliver_with_long_sides_is_dropped():
    # a unit square split at the midpoint m of its bottom side, plus a sliver (0, m, 1) on that side
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0, 0]], np.float64)
    f = np.array([[0, 4, 3], [4, 1, 2], [4, 2, 3], [0, 1, 4]], np.int64)
    out_v, out_f, _, report = weld_short_edges(v, f)
    assert out_f.tolist() == [[0, 4, 3], [4, 1, 2], [4, 2, 3]]
    np.testing.assert_allclose(out_v, v, rtol=0, atol=0)
    assert report["zero_area_faces"] == 1 and report["welded_vertices"] == 0


def test_a_clean_mesh_comes_back_as_given_duplicate_faces_included():
    sphere = trimesh.creation.icosphere(2)
    v = sphere.vertices.astype(np.float64)
    f = np.concatenate([sphere.faces, sphere.faces[:1, ::-1]]).astype(np.int64)  # one face twice
    out_v, out_f, _, report = weld_short_edges(v, f)
    assert out_v is v and out_f is f
    assert not any(report.values())


def test_resampling_a_subdivided_low_poly_sphere_leaves_no_degenerate_faces():
    sphere = trimesh.creation.icosphere(1)  # 80 faces, subdivided to 5120, then decimated to 2000
    v, f = sphere.vertices, sphere.faces
    for _ in range(3):  # as resample_to refines it: 80 -> 320 -> 1280 -> 5120 faces
        v, f = trimesh.remesh.subdivide(v, f)
    raw_v, raw_f, _ = decimate(v, f, 2000, "fast")
    size = size_of(raw_v)
    assert (edge_lengths_of(raw_v, raw_f) < 1e-6 * size).sum() > 20  # the decimator's corner clusters
    report: dict = {}
    out_v, out_f, refined, pieces = resample_to(sphere.vertices, sphere.faces, 2000, "fast", report=report)
    assert refined == 3 and abs(len(out_f) - 2000) <= 20 and pieces.tolist() == [0] * len(out_v)
    stored = out_v.astype(np.float32)  # as the characters table keeps them
    assert face_areas(stored, out_f).min() > 1e-12 * size ** 2
    assert edge_lengths_of(stored, out_f).min() > 1e-5 * size
    assert len(np.unique(out_f)) == len(out_v)
    assert report["welded_vertices"] > 0 and report["decimation_target"] > 2000
    # still the sphere: every vertex on the unit sphere (the icosphere's flat faces are within 0.1)
    np.testing.assert_allclose(np.linalg.norm(out_v, axis=1), 1.0, atol=0.1)


@pytest.mark.slow
def test_every_shared_asset_resamples_without_degenerate_faces(assets_dir, tmp_path):
    from mimicbench.datagen.ingest.runner import ingest_assets
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.schemas.shards import read_records

    raw, data = tmp_path / "raw", tmp_path / "r5k"
    ingest_assets([assets_dir], raw, jobs=2, timeout=600, progress=False)
    summary = resample_dataset(raw, data, faces=5000, backend="fast", progress=False)
    assert summary["failed"] == 0
    meshed = [r for r in read_records(data, "characters") if len(r.faces)]
    assert len(meshed) == 13  # 12 glTF characters and Gene.pmx (the BVH has no mesh)
    welded = 0
    for r in meshed:
        v, f = np.asarray(r.vertices, np.float64), np.asarray(r.faces, np.int64)
        size = size_of(v)
        assert face_areas(v, f).min() > 1e-12 * size ** 2, r.character_id
        assert edge_lengths_of(v, f).min() > 1e-6 * size, r.character_id
        assert abs(len(f) - 5000) <= 50, (r.character_id, len(f))
        assert len(np.unique(f)) == len(v) == len(r.weight_values), r.character_id  # a weight row each
        np.testing.assert_allclose(r.weight_values.sum(axis=1), 1.0, atol=1e-5, err_msg=r.character_id)
        welded += "weld" in r.meta["resample"]
    assert welded >= 10  # the low-poly characters (subdivided, then decimated) needed it
