"""FBX ingest checked against ufbx, a second FBX reader that never touches Blender
(:mod:`tests.fbx_reference`): every animation stack becomes a clip, each stored clip posed by the
dataset's own LBS at its recorded times ``t0 + f / fps`` matches ufbx's skinning of the file at
those times, a stack that moves and scales the rig object reaches the joints, unweighted
vertices are left out as FORMAT.md says, a clip Blender does not play fails, and the reader
survives many loads. Fixtures: a multi-clip FBX exported from the shared RobotExpressive.glb and
a hand-made rig (:mod:`tests.fbx_fixtures`), written once per session."""

import numpy as np
import pytest

from mimicbench.datagen.ingest import blender_pool
from mimicbench.datagen.ingest.runner import ingest_assets
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.shards import read_records
from tests.fbx_fixtures import RIG_STACKS, RIG_UNWEIGHTED, export_glb_as_fbx, write_rig_fbx
from tests.fbx_reference import ufbx_vertices
from tests.test_ingest import load  # (character, motions, child JSON, child arrays) of an ingested asset

pytestmark = pytest.mark.blender

MEAN_PCT, MAX_PCT = 0.05, 0.5  # the bounds, percent of height


@pytest.fixture(scope="session")
def fbx_files(assets_dir, tmp_path_factory) -> dict:
    """``{stem: path}``: RobotExpressive as FBX (14 stacks) and the hand-made rig (3 stacks)."""
    folder = tmp_path_factory.mktemp("fbx")
    return {"RobotExpressiveFbx": export_glb_as_fbx(assets_dir / "glb" / "RobotExpressive.glb",
                                                    folder / "RobotExpressiveFbx.fbx"),
            "HandRig": write_rig_fbx(folder / "HandRig.fbx")}


@pytest.fixture(scope="module")
def ingested(fbx_files, tmp_path_factory):
    out = tmp_path_factory.mktemp("fbx-ingest") / "ds"
    summary = ingest_assets(list(fbx_files.values()), out, timeout=600, progress=False)
    return out, summary


def stored_index(arrays, ref) -> np.ndarray:
    """Index into ufbx's concatenated vertices of each stored vertex (mesh by mesh, the vertex's
    index in its mesh: Blender keeps FBX control points in order)."""
    counts = arrays["mesh_vertex_counts"]
    owner = np.repeat(np.arange(len(counts)), counts)
    offsets = np.concatenate([[0], np.cumsum(ref["counts"])])
    return offsets[owner] + arrays["source_vertex"]


def compare_with_ufbx(path, char, motions, meta, arrays):
    """Per clip (mean %, max %) of the stored clip posed by LBS against ufbx at t0 + f / fps, at 5
    frames a clip, and ufbx's read of the file."""
    frames = {c["name"]: sorted({0, 1, c["frames"] // 3, c["frames"] // 2, c["frames"] - 1}) for c in meta["clips"]}
    times = {c["name"]: [c["t0"] + f / c["fps"] for f in frames[c["name"]]] for c in meta["clips"]}
    ref = ufbx_vertices(path, meta["meshes"], times)
    idx = stored_index(arrays, ref)
    errors = {}
    for clip in meta["clips"]:
        m, f = motions[clip["name"]], frames[clip["name"]]
        pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, m.transforms[f],
                                     None if m.scale is None else m.scale[f])
        d = np.linalg.norm(pred - ref[clip["name"]][:, idx], axis=-1) / char.height * 100
        errors[clip["name"]] = (float(d.mean()), float(d.max()))
    return errors, ref


@pytest.mark.slow
@pytest.mark.parametrize("stem", ["RobotExpressiveFbx", "HandRig"])
def test_every_stack_is_a_clip_that_matches_ufbx_at_its_recorded_times(ingested, fbx_files, stem):
    out, summary = ingested
    assert summary["failed"] == 0 and summary["failed_clips"] == 0, summary["statuses"]
    char, motions, meta, arrays = load(out, stem)
    errors, ref = compare_with_ufbx(fbx_files[stem], char, motions, meta, arrays)
    assert sorted(errors) == sorted(ref["stacks"]) == sorted(motions)  # every stack stored, named as the stack
    assert len(errors) == (14 if stem == "RobotExpressiveFbx" else len(RIG_STACKS))
    for clip in meta["clips"]:
        mean, mx = errors[clip["name"]]
        assert mean < MEAN_PCT and mx < MAX_PCT, (stem, clip["name"], mean, mx)
        # the stacks' keys start at file time 0: frame 0 is at t0 = 0, not one frame late
        assert abs(clip["t0"]) < 1e-9 and abs(clip["first_frame"]) < 1e-9, clip
        rec = [c for c in char.meta["ingest"]["clips"] if c["name"] == clip["name"]][0]["reproduction_error"]
        assert rec["max_pct"] < MAX_PCT, (clip["name"], rec)
    if stem == "HandRig":
        assert {c["name"]: c["frames"] for c in meta["clips"]} == RIG_STACKS


def _blender_to_dataset(p):
    """(x, y, z) Blender Z up -> (x, z, -y) dataset Y up."""
    p = np.asarray(p, float)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], -1)


def _rig_object_motion(points_blender, location, angle_z, scale):
    """Points (N, 3) at rest (Blender frame, relative to the rig object's origin) moved by the rig
    object's transform: scale, then a turn of ``angle_z`` about Blender Z, then ``location``; in
    the dataset frame."""
    c, s = np.cos(angle_z), np.sin(angle_z)
    rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return _blender_to_dataset(points_blender * np.asarray(scale) @ rz.T + np.asarray(location))


@pytest.mark.slow
def test_a_stack_that_moves_and_scales_the_rig_object_reaches_the_joints(ingested):
    """Travel ends with the rig object at (0.8, 0.3, 0.2), turned 1.2 rad about Blender Z and
    scaled 1.5 (tests/fbx_fixtures.py); Stretch ends scaled 1.4 along Blender x; Bend leaves it."""
    out, _ = ingested
    char, motions, _, _ = load(out, "HandRig")
    rest_blender = np.array([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]])  # Root, Mid, Tip heads as built
    np.testing.assert_allclose(char.keypoints, _blender_to_dataset(rest_blender), atol=1e-5)
    travel = motions["Rig|Travel"]
    want = _rig_object_motion(rest_blender[:1], (0.8, 0.3, 0.2), 1.2, 1.5)  # the root joint rides the object
    np.testing.assert_allclose(travel.transforms[-1, 0, 4:], want[0], atol=1e-4)
    assert travel.scale is not None
    np.testing.assert_allclose(travel.scale[-1, :, :3], 1.5, atol=1e-4)  # uniform: s_xx = s_yy = s_zz = 1.5
    np.testing.assert_allclose(travel.scale[-1, :, 3:], 0.0, atol=1e-4)
    stretch = motions["Rig|Stretch"]
    assert stretch.scale is not None  # Blender x is dataset x: 1.4 on the root, which Stretch does not turn
    np.testing.assert_allclose(stretch.scale[-1, 0], [1.4, 1, 1, 0, 0, 0], atol=1e-4)
    assert motions["Rig|Bend"].scale is None
    np.testing.assert_allclose(motions["Rig|Bend"].transforms[:, 0, 4:], 0.0, atol=1e-5)


@pytest.mark.slow
def test_unweighted_vertices_follow_their_mesh_node_and_are_left_out(ingested, fbx_files):
    """The rig's top ring and cap have no weight. In the file (ufbx) they follow the tube's node,
    which hangs from the scene root (Blender's exporter unparents skinned meshes), so they stay
    where they are while every joint moves with the rig object: no joint carries them. The
    dataset leaves them out (and the faces using them) and counts them, instead of binding them
    to the nearest bone."""
    out, _ = ingested
    char, motions, meta, arrays = load(out, "HandRig")
    ref = ufbx_vertices(fbx_files["HandRig"], meta["meshes"], {"Rig|Travel": [16 / 24], "Rig|Bend": [20 / 24]})
    total = sum(ref["counts"])
    assert len(char.vertices) == total - RIG_UNWEIGHTED
    info = char.meta["ingest"]
    assert info["left_out_vertices"] == RIG_UNWEIGHTED and info["unweighted_vertices"] == RIG_UNWEIGHTED
    np.testing.assert_allclose(char.weights.to_dense().sum(axis=1), 1.0, atol=1e-5)
    assert char.faces.max() < len(char.vertices) and len(char.faces) == 12 * 12 * 2 - 12 * 2  # ring faces gone
    kept = stored_index(arrays, ref)
    left = np.setdiff1d(np.arange(total), kept)
    assert len(left) == RIG_UNWEIGHTED
    rest = np.concatenate(ref["rest"])
    assert (rest[left, 1] > 1.55).all() and (rest[kept, 1] <= 1.55).all()  # exactly the top ring and the cap
    for stack in ("Rig|Travel", "Rig|Bend"):
        np.testing.assert_allclose(ref[stack][0, left], rest[left], atol=1e-5)  # they stay with the tube's node
        frame = RIG_STACKS[stack] - 1
        moved = np.linalg.norm(motions[stack].transforms[frame, :, 4:] - char.keypoints, axis=1)
        turned = 1 - np.abs(motions[stack].transforms[frame, :, 0])
        assert ((moved > 1e-3) | (turned > 1e-3)).all() or stack == "Rig|Bend"  # Travel moves every joint
    assert np.abs(ref["Rig|Bend"][0, kept] - char.vertices).max() > 0.1  # the skinned part bends


@pytest.mark.slow
def test_an_fbx_at_29_97_fps_keeps_its_own_clock(tmp_path):
    """Blender's importer keys FBX times at 30 frames a second while the scene runs at 29.97: the
    clips are sampled at the file's 29.97 fps and still match ufbx at t0 + f / fps."""
    fbx = write_rig_fbx(tmp_path / "HandRig2997.fbx", fps=30, fps_base=1.001)
    out = tmp_path / "ds"
    assert ingest_assets([fbx], out, timeout=600, progress=False)["failed_clips"] == 0
    char, motions, meta, arrays = load(out, "HandRig2997")
    errors, ref = compare_with_ufbx(fbx, char, motions, meta, arrays)
    assert abs(ref["fps"] - 29.97) < 0.01 and all(abs(c["fps"] - ref["fps"]) < 1e-3 for c in meta["clips"])
    assert {c["name"]: c["frames"] for c in meta["clips"]} == RIG_STACKS
    for name, (mean, mx) in errors.items():
        assert mean < MEAN_PCT and mx < MAX_PCT, (name, mean, mx)


@pytest.mark.slow
def test_a_clip_blender_does_not_play_fails_instead_of_storing_the_rest_pose(fbx_files, tmp_path, monkeypatch):
    """With every action bound without its slot (the old FBX bug), only the stack the importer
    assigned itself plays: the other clips fail with a status row, found in a fresh import."""
    monkeypatch.setattr(blender_pool, "CHILD_MODULE", "tests.ingest_unslotted_child")
    summary = ingest_assets([fbx_files["HandRig"]], tmp_path / "ds", timeout=600, progress=False)
    failed = {s.asset.split("#")[1]: s.reason for s in summary["statuses"] if "#" in s.asset}
    assert sorted(failed) == ["Rig|Stretch", "Rig|Travel"], failed
    assert all("does not play" in r for r in failed.values())
    assert [m.name for m in read_records(tmp_path / "ds", "motions")] == ["Rig|Bend"]


def test_ufbx_reads_the_same_file_the_same_across_many_loads(fbx_files):
    """The bindings drop references (tests/fbx_reference.py): 25 loads and evaluations in one
    process neither crash nor read differently; and the read is the rig as built by hand: the
    rest tube, and its bottom ring (weighted to the root bone alone, which Travel does not turn)
    carried by the rig object's transform at Travel's last key."""
    ref = ufbx_vertices(fbx_files["HandRig"], ["Tube"], {"Rig|Travel": [0.0, 0.3, 16 / 24], "Rig|Bend": [0.5]},
                        loads=25)
    assert ref["counts"] == [12 * 13 + 1] and sorted(ref["stacks"]) == sorted(RIG_STACKS) and ref["fps"] == 24
    rest = ref["rest"][0]
    assert abs(np.ptp(rest[:, 1]) - 1.75) < 1e-5 and abs(rest[:, 0].max() - 0.15) < 1e-5  # tube 1.75 m, radius 0.15
    ring = np.arange(12)
    rest_blender = np.stack([rest[ring, 0], -rest[ring, 2], rest[ring, 1]], -1)
    want = _rig_object_motion(rest_blender, (0.8, 0.3, 0.2), 1.2, 1.5)
    np.testing.assert_allclose(ref["Rig|Travel"][2, ring], want, atol=1e-4)
    assert np.isfinite(ref["Rig|Travel"]).all() and np.isfinite(ref["Rig|Bend"]).all()
