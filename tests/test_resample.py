"""Resampling to 5,000 faces with barycentric re-skinning."""
import dataclasses

import numpy as np
import pytest
import trimesh

from mimicbench.datagen.resample.character import resample_character
from mimicbench.datagen.resample.stage import resample_dataset
from mimicbench.datagen.resample.clean import clean_mesh
from mimicbench.datagen.resample.closest_point import closest_points, closest_points_brute_force
from mimicbench.datagen.resample.quality import transfer_error_percent
from mimicbench.datagen.resample.reskin import nearest_vertex_weights
from mimicbench.cli import main
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.validate import validate_dataset
from mimicbench.schemas.weights import SparseWeights
from tests.test_schemas import make_character


def tube_record(tube, rings=24, cid="toy/tube"):
    rec = make_character(tube, cid)
    return dataclasses.replace(rec, apparel_vertex_mask=tube["vertices"][:, 1] > 0.7, meta=None)


def bend_motion(record, frames=6):
    from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
    from mimicbench.geometry.quaternion import quat_from_axis_angle

    k = record.num_joints
    angles = np.linspace(0, 0.8, frames)
    local = np.tile([1.0, 0, 0, 0], (frames, k, 1))
    local[:, 1:4] = quat_from_axis_angle(np.array([0, 0, 1.0]), angles)[:, None, :]
    g, p = forward_kinematics(local, record.keypoints, record.parents)
    return MotionRecord(f"{record.character_id}/bend", record.character_id, "bend", record.split, 30.0, frames, k,
                        transforms_to_array(g, p))


@pytest.mark.parametrize("backend", ["pymeshlab", "fast"])
def test_coarse_tube_is_refined_to_target_with_valid_weights(tube, backend):
    rec = tube_record(tube)
    assert len(rec.faces) < 5000
    out = resample_character(rec, [bend_motion(rec)], 5000, backend)
    q = out.meta["resample"]
    assert abs(q["faces_out"] - 5000) <= 50 and q["subdivisions"] >= 1
    np.testing.assert_allclose(out.weight_values.sum(1), 1.0, atol=1e-5)
    assert (out.weight_values > 0).sum(1).max() <= 8
    assert q["hausdorff_pct"] < 1.0 and q["transfer_error_pct"] < 0.5
    assert out.keypoints is rec.keypoints and out.bone_names == rec.bone_names
    # the apparel mask follows the surface: new vertices above 0.7 m are apparel
    assert out.apparel_vertex_mask[out.vertices[:, 1] > 0.75].all() and not out.apparel_vertex_mask[out.vertices[:, 1] < 0.65].any()


def stretch_motion(record, frames=4):
    """Bones pulled apart along their chain with a small twist: skin between rings must blend."""
    from mimicbench.geometry.kinematics import transforms_to_array
    from mimicbench.geometry.quaternion import quat_from_axis_angle

    k = record.num_joints
    q = quat_from_axis_angle(np.array([0, 1.0, 0]), np.linspace(0, 0.15, frames)[:, None] * np.arange(k)[None, :])
    t = record.keypoints[None].astype(np.float64) + np.linspace(0, 0.06, frames)[:, None, None] * np.arange(k)[None, :, None] * [0, 1, 0]
    return MotionRecord(f"{record.character_id}/stretch", record.character_id, "stretch", record.split, 30.0, frames,
                        k, transforms_to_array(q, t))


def test_barycentric_reskin_beats_nearest_vertex_on_a_refined_coarse_mesh():
    from tests.toys import make_tube

    coarse = tube_record(make_tube(rings=6, segments=8), cid="toy/coarse")
    motion = stretch_motion(coarse)
    out = resample_character(coarse, [motion], 2000, "pymeshlab")
    assert out.meta["resample"]["subdivisions"] >= 2
    clean = clean_mesh(coarse.vertices, coarse.faces, coarse.weights, coarse.apparel_vertex_mask)
    new_v = out.vertices.astype(np.float64)
    surface = closest_points(clean.vertices, clean.faces, new_v)
    naive = nearest_vertex_weights(clean.weights, clean.vertices, new_v)
    height = float(np.ptp(clean.vertices[:, 1]))
    args = (coarse.keypoints, surface, motion.transforms, height)
    ours = transfer_error_percent(clean.vertices, clean.faces, clean.weights, new_v, out.weights, *args)
    theirs = transfer_error_percent(clean.vertices, clean.faces, clean.weights, new_v, naive, *args)
    assert ours < 0.5 * theirs, (ours, theirs)


def test_fast_closest_points_match_brute_force():
    rng = np.random.default_rng(0)
    mesh = trimesh.creation.icosphere(subdivisions=2)
    # a decimated-style mesh with a few huge triangles next to small ones
    v = np.concatenate([mesh.vertices, [[3.0, 0, 0], [0, 3.0, 0], [0, 0, 3.0]]])
    f = np.concatenate([mesh.faces, [[len(mesh.vertices), len(mesh.vertices) + 1, len(mesh.vertices) + 2]]])
    q = rng.normal(size=(400, 3)) * 1.5
    fast, slow = closest_points(v, f, q), closest_points_brute_force(v, f, q)
    np.testing.assert_allclose(fast.distances, slow.distances, atol=1e-12)
    np.testing.assert_allclose(fast.points, slow.points, atol=1e-9)
    np.testing.assert_allclose(fast.barycentric.sum(1), 1.0)
    assert (fast.barycentric >= 0).all()
    # the barycentric coordinates rebuild the point inside its face
    np.testing.assert_allclose(np.einsum("qc,qcd->qd", fast.barycentric, v[f[fast.faces]]), fast.points, atol=1e-9)


def test_hausdorff_matches_meshlabs_filter_sampling_every_vertex():
    import pymeshlab

    from mimicbench.datagen.resample.quality import hausdorff_percent
    from mimicbench.datagen.resample.simplify import decimate

    mesh = trimesh.creation.capsule(height=1.0, radius=0.2, count=[24, 24])
    v, f, _ = decimate(mesh.vertices, mesh.faces, 300, "fast")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces.astype(np.int32)))
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
    there = ms.get_hausdorff_distance(sampledmesh=0, targetmesh=1, samplevert=True, samplenum=len(mesh.vertices))["max"]
    back = ms.get_hausdorff_distance(sampledmesh=1, targetmesh=0, samplevert=True, samplenum=len(v))["max"]
    ours = hausdorff_percent(mesh.vertices, mesh.faces, v, f, 1.4)
    assert ours > 0
    np.testing.assert_allclose(ours, max(there, back) / 1.4 * 100, rtol=1e-4)


def test_cleaning_merges_duplicates_drops_degenerates_and_keeps_pieces():
    a = trimesh.creation.icosphere(subdivisions=2)
    b = trimesh.creation.icosphere(subdivisions=1)
    v = np.concatenate([a.vertices, b.vertices + [3, 0, 0], a.vertices[:5]])  # 5 duplicate vertices
    f = np.concatenate([a.faces, b.faces + len(a.vertices), [[0, 0, 1]], a.faces[:3]])
    w = SparseWeights.from_dense(np.ones((len(v), 1)))
    c = clean_mesh(v, f, w, np.zeros(len(v)))
    assert c.report["degenerate_faces"] == 1 and c.report["duplicate_faces"] == 3
    assert c.report["kept_pieces"] == 2 and len(c.faces) == len(a.faces) + len(b.faces)


def _two_touching_strands():
    """Two closed tubes (cylinders) stacked end to end so that the end ring of the first lies on the
    start ring of the second, vertex on vertex: (V, F, owner (V,) bone of each vertex)."""
    a = trimesh.creation.cylinder(radius=0.1, height=1.0, sections=8)
    top = a.vertices[:, 2] > 0.49
    b = a.vertices + [0.0, 0.0, 1.0]
    b[b[:, 2] < 0.51] = a.vertices[top][np.argmin(np.abs(b[b[:, 2] < 0.51][:, None, :2]
                                                        - a.vertices[top][None, :, :2]).sum(-1), axis=1)]
    v = np.concatenate([a.vertices, b])
    f = np.concatenate([a.faces, a.faces + len(a.vertices)])
    owner = np.r_[np.zeros(len(a.vertices), int), np.ones(len(a.vertices), int)]
    return v, f, owner


def _weights_of(owner, bones=2):
    dense = np.zeros((len(owner), bones))
    dense[np.arange(len(owner)), owner] = 1.0
    return SparseWeights.from_dense(dense)


def test_touching_apparel_pieces_of_other_bones_are_not_welded_but_body_ones_and_seams_are():
    v, f, owner = _two_touching_strands()
    touching = int(len(v) - len(np.unique(np.round(v, 9), axis=0)))  # vertices on another's place
    assert touching > 0
    apparel = clean_mesh(v, f, _weights_of(owner), np.ones(len(v)))  # two hair links: kept apart
    assert apparel.report["merged_vertices"] == 0 and apparel.report["kept_pieces"] == 2
    body = clean_mesh(v, f, _weights_of(owner), np.zeros(len(v)))  # body capsules: welded, as before
    assert body.report["merged_vertices"] == touching and body.report["kept_pieces"] == 1
    same = clean_mesh(v, f, _weights_of(np.zeros(len(v), int)), np.ones(len(v)))  # one bone: a seam
    assert same.report["merged_vertices"] == touching and same.report["kept_pieces"] == 1


def _two_tubes(lift: float):
    """Two closed tubes of radius 8 cm and 1 m along +Y, the lower one (piece A) skinned 100% to bone
    A, the other (piece B) 100% to bone B and lifted by ``lift`` (1.01: its end sits 1 cm above A's;
    0.99: the two ends overlap by 1 cm, side on side, as the zoo's chain links do at their joints),
    as an apparel character: (record, (V,) bool, True on piece B)."""
    from tests.toys import make_tube

    t = make_tube(num_bones=1, branch=False)
    v = np.concatenate([t["vertices"], t["vertices"] + np.float32([0.0, lift, 0.0])])
    on_b = np.arange(len(v)) >= len(t["vertices"])
    tubes = {"vertices": v, "faces": np.concatenate([t["faces"], t["faces"] + len(t["vertices"])]),
             "keypoints": np.float32([[0, 0, 0], [0, lift, 0]]), "parents": np.int32([-1, 0]),
             "weights": _weights_of(on_b.astype(int)), "bone_names": ["A", "B"]}
    rec = dataclasses.replace(make_character(tubes, "toy/two-tubes"), apparel_vertex_mask=np.ones(len(v), bool),
                              apparel_bone_mask=np.ones(2, bool), bone_roles=["a", "b"], meta=None)
    return rec, on_b


def _assert_each_piece_keeps_its_bone(out):
    """Every vertex of the resampled piece holding the top vertex has weight 1 on bone B, every other
    vertex weight 1 on bone A (pieces found by trimesh, not by the code under test)."""
    dense = out.weights.to_dense(np.float64)
    np.testing.assert_allclose(dense.sum(1), 1.0, atol=1e-6)
    label = trimesh.graph.connected_component_labels(trimesh.geometry.faces_to_edges(out.faces), len(out.vertices))
    assert len(np.unique(label)) == 2
    on_b = label == label[np.argmax(out.vertices[:, 1])]
    np.testing.assert_allclose(dense[on_b], np.broadcast_to([0.0, 1.0], (on_b.sum(), 2)), atol=1e-6)
    np.testing.assert_allclose(dense[~on_b], np.broadcast_to([1.0, 0.0], ((~on_b).sum(), 2)), atol=1e-6)


def test_resampled_vertices_take_weights_from_their_own_piece_only(monkeypatch):
    """Piece B's end sits 1 cm above piece A's; the decimator (here by hand) leaves B's end 6 mm
    lower, as fast-simplification leaves the zoo's thin hair strands a few mm off their surface.
    The end's 16 ring vertices and its centre are then 4 mm from A's end cap and 6 mm from their own
    piece: they keep bone B's weight, and their closest points are on B, 6 mm away."""
    import fast_simplification

    rec, on_b = _two_tubes(1.01)
    v, f = rec.vertices.astype(np.float64), rec.faces.astype(np.int64)
    end = on_b & (v[:, 1] < 1.02)  # B's lowest ring and its end cap's centre
    assert end.sum() == 17
    moved = v.copy()
    moved[end, 1] -= 0.006

    def by_hand(points, triangles, *args, return_collapses=False, **kwargs):
        out = (moved.astype(np.float32), np.asarray(triangles))
        return out + (np.zeros((0, 2), np.int64),) if return_collapses else out  # no collapse

    monkeypatch.setattr(fast_simplification, "simplify", by_hand)
    out = resample_character(rec, [], 1000, "fast")
    np.testing.assert_array_equal(out.faces, f)
    _assert_each_piece_keeps_its_bone(out)
    assert out.meta["resample"]["own_piece_vertices"] == 17
    anywhere = closest_points(v, f, moved[end])
    np.testing.assert_allclose(anywhere.distances, 0.004, atol=1e-6)  # on A's end cap
    from mimicbench.datagen.resample.pieces import own_piece_points

    own = own_piece_points(v, f, moved, on_b.astype(int))  # pieces numbered by first vertex: A 0, B 1
    np.testing.assert_allclose(own.distances[end], 0.006, atol=1e-6)  # on B's end
    assert on_b[f[own.faces[end]]].all()
    np.testing.assert_array_equal(own.faces[~end], closest_points(v, f, moved[~end]).faces)


@pytest.mark.parametrize("backend", ["fast", "pymeshlab"])
def test_decimated_overlapping_pieces_keep_their_own_bones(backend):
    """B's end overlaps A's by 1 cm, side on side: where the surfaces coincide the closest point on
    any piece may be the other's; decimated by either backend, each vertex keeps its own piece's bone."""
    rec, _ = _two_tubes(0.99)
    out = resample_character(rec, [], 400, backend)
    _assert_each_piece_keeps_its_bone(out)
    assert out.meta["resample"]["own_piece_vertices"] > 0


@pytest.mark.parametrize("breakage,reason", [
    ("nan", "NaN"), ("index", "faces index"), ("flat", "zero area"), ("unweighted", "no skin weight"), ("tiny", "at least 4"),
])
def test_bad_input_gets_a_status_row_and_others_are_written(tube, tmp_path, breakage, reason):
    good = tube_record(tube, cid="toy/good")
    bad = tube_record(tube, cid="toy/bad")
    v, f, wv = bad.vertices.copy(), bad.faces.copy(), bad.weight_values.copy()
    if breakage == "nan":
        v[3] = np.nan
    elif breakage == "index":
        f[0, 0] = len(v) + 10
    elif breakage == "flat":
        v[:] = 0.0
    elif breakage == "unweighted":
        wv[7] = 0.0
    elif breakage == "tiny":
        f = f[:3]
    bad = dataclasses.replace(bad, vertices=v, faces=f, weight_values=wv)
    src = tmp_path / "in"
    write_records(src, "characters", [good, bad], "train")
    write_records(src, "motions", [bend_motion(good)], "train")
    summary = resample_dataset(src, tmp_path / "out", backend="fast", progress=False)
    assert summary["failed"] == 1
    status = {s.asset: s for s in read_records(tmp_path / "out", "status", "resample")}
    assert status["toy/bad"].status == "failed" and reason in status["toy/bad"].reason
    assert [r.character_id for r in read_records(tmp_path / "out", "characters")] == ["toy/good"]
    assert validate_dataset(tmp_path / "out") == []


def hausdorff_ok(record, limit: float) -> bool:
    """Hausdorff below ``limit`` % of height, except for zoo snakes: their 12-60 overlapping
    capsules hide a cap pair inside the body at every joint, which takes most of a 5,000-face
    budget (Blender's Decimate keeps 2.4% on zoo/reptile-0000 too; see benchmarks/resample.py and
    datagen/resample/__init__.py)."""
    snake = (record.meta.get("params") or {}).get("snake", False)
    return record.meta["resample"]["hausdorff_pct"] < (4.0 if snake else limit)


# MeshLab's collapse keeps 1.18% on zoo/quadruped-0001 (fast: 0.23%), the backend's one miss
@pytest.mark.parametrize("backend,limit", [("fast", 1.0), ("pymeshlab", 1.25)])
def test_zoo_dataset_resamples_resumes_and_validates(small_zoo, tmp_path, backend, limit):
    out = tmp_path / "zoo5k"
    assert main(["datagen", "resample", str(small_zoo), str(out), "--backend", backend, "--quiet"]) == 0
    chars = read_records(out, "characters")
    assert len(chars) == len(read_records(small_zoo, "characters"))
    for c in chars:
        q = c.meta["resample"]
        assert abs(q["faces_out"] - 5000) <= 50 and q["faces_in"] > 5000
        assert q["transfer_error_pct"] < 0.5
        np.testing.assert_allclose(c.weight_values.sum(1), 1.0, atol=1e-5)
        assert (c.weight_values > 0).sum(1).max() <= 8
        assert hausdorff_ok(c, limit), (c.character_id, q["hausdorff_pct"])
    assert sum(not (c.meta.get("params") or {}).get("snake", False) for c in chars) >= 12
    assert len(read_records(out, "motions")) == len(read_records(small_zoo, "motions"))
    again = resample_dataset(small_zoo, out, backend=backend, progress=False)
    assert again["resampled"] == 0 and again["already_done"] == len(chars)
    assert validate_dataset(out) == []


def test_pymeshlab_decimation_ignores_parameters_left_by_an_earlier_call():
    """pymeshlab keeps a filter's last parameters in the process; ours are all spelled out."""
    import pymeshlab

    from mimicbench.datagen.resample.simplify import decimate

    mesh = trimesh.creation.icosphere(subdivisions=4)
    before = decimate(mesh.vertices, mesh.faces, 800, "pymeshlab")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces.astype(np.int32)))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=400, optimalplacement=False, planarquadric=True)
    after = decimate(mesh.vertices, mesh.faces, 800, "pymeshlab")
    np.testing.assert_array_equal(before[1], after[1])
    np.testing.assert_allclose(before[0], after[0])
    # with optimal placement the new vertices leave the original ones
    assert not np.isin(np.round(after[0], 9), np.round(mesh.vertices, 9)).all(axis=1).all()


def test_closest_points_on_degenerate_triangles_give_valid_barycentric_coordinates():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0.0]])
    f = np.array([[0, 1, 2], [1, 3, 4], [4, 4, 4]])  # a triangle, a segment (collinear) and a point
    q = np.array([[2.5, 0.5, 0], [3.2, 0, 0.1], [0.2, 0.2, 1.0]])
    fast, slow = closest_points(v, f, q), closest_points_brute_force(v, f, q)
    np.testing.assert_allclose(fast.distances, slow.distances, atol=1e-12)
    assert np.isfinite(fast.barycentric).all() and (fast.barycentric >= 0).all()
    np.testing.assert_allclose(fast.barycentric.sum(1), 1.0)


def test_streamed_in_batches_gives_the_same_shards(small_zoo, tmp_path, monkeypatch):
    """Characters read a row group at a time and resampled BATCH at a time, frames spilled to disk:
    batches of 3 write the bytes one batch writes, and a re-run over finished output (rows read
    back by row group) rewrites them identically."""
    import hashlib

    import mimicbench.datagen.resample.stage as stage

    def shards(root):
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((root / "characters").glob("*.parquet"))}

    resample_dataset(small_zoo, tmp_path / "one", faces=300, progress=False)
    monkeypatch.setattr(stage, "BATCH", 3)
    resample_dataset(small_zoo, tmp_path / "many", faces=300, progress=False, flush_every=2)
    assert shards(tmp_path / "one") == shards(tmp_path / "many") and len(shards(tmp_path / "one")) >= 2
    again = resample_dataset(small_zoo, tmp_path / "many", faces=300, progress=False)
    assert again["already_done"] == again["characters"] and shards(tmp_path / "many") == shards(tmp_path / "one")
    assert validate_dataset(tmp_path / "many") == []
