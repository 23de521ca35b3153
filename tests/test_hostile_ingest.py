"""Hostile inputs to ``datagen ingest`` (issue 31, round 3): GLB chunk tricks, malformed glTF JSON,
clips with one key far in the future, same-stem characters, a dataset folder that lost its
manifest, paths holding ``#``, and NaN values. Every hostile file is made here, byte by byte."""
from __future__ import annotations

import hashlib
import json
import math
import shutil
import struct

import numpy as np
import pytest

from mimicbench.datagen.ingest.clip_length import MAX_CLIP_FRAMES, ClipTooLong
from mimicbench.datagen.ingest.gltf_resample import frame_times, load_gltf
from mimicbench.datagen.ingest.runner import ingest_assets
from mimicbench.datagen.ingest.uris import external_uri_problems
from mimicbench.cli import main
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.validate import validate_dataset
from tests.mmd_fixtures import pmd_bytes, pmx_bytes, vmd_bytes


def _chunk(kind: bytes, data: bytes) -> bytes:
    """One GLB chunk (glTF 2.0 section 4.4.3): length, type ('JSON' or 'BIN\\0' as ASCII), data padded to 4."""
    pad = b" " if kind == b"JSON" else b"\0"
    data += pad * (-len(data) % 4)
    return struct.pack("<I", len(data)) + kind + data


def _glb(*chunks: bytes) -> bytes:
    body = b"".join(chunks)
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _status(out) -> dict:
    return {s.asset.rsplit("/", 1)[-1]: s for s in read_records(out, "status")}


# --- 1. a second JSON chunk cannot smuggle an outside URI past the check --------------------------

def test_a_second_json_chunk_is_refused_by_the_check_and_the_loader(tmp_path):
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "outside.bin").write_bytes(struct.pack("<3f", 7.0, 8.0, 9.0))
    folder = tmp_path / "asset"
    folder.mkdir()
    harmless = json.dumps({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 4}]}).encode()
    evil = json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "../secret/outside.bin", "byteLength": 12}]}).encode()
    two = folder / "Two.glb"
    two.write_bytes(_glb(_chunk(b"JSON", harmless), _chunk(b"BIN\0", b"\0" * 4), _chunk(b"JSON", evil)))
    bin_first = folder / "BinFirst.glb"
    bin_first.write_bytes(_glb(_chunk(b"BIN\0", b"\0" * 4), _chunk(b"JSON", evil)))
    past_end = folder / "PastEnd.glb"  # a chunk longer than the file the header declares
    past_end.write_bytes(_glb(struct.pack("<I", 4096) + b"JSON" + harmless))
    cut = folder / "Cut.glb"  # the header declares more bytes than the file has
    cut.write_bytes(_glb(_chunk(b"JSON", harmless))[:-4])
    for path, words in ((two, "second JSON chunk"), (bin_first, "first GLB chunk is not JSON"),
                        (past_end, "runs past the end"), (cut, "truncated GLB: the header says")):
        with pytest.raises(ValueError, match=words):
            external_uri_problems(path)
        with pytest.raises(ValueError, match=words):
            load_gltf(path)  # the loader reads the same chunks through the same parser
    (folder / "good.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    s = ingest_assets([folder], out, progress=False)
    st = _status(out)
    assert st["Two.glb"].status == "failed" and "second JSON chunk" in st["Two.glb"].reason
    assert st["BinFirst.glb"].status == "failed" and st["PastEnd.glb"].status == "failed"
    assert s["failed"] == 4 and [c.character_id for c in read_records(out, "characters")] == ["assets/good"]


def test_a_uri_that_is_a_list_and_a_top_level_array_are_failed_rows(tmp_path):
    (tmp_path / "ListUri.gltf").write_text(json.dumps({"asset": {"version": "2.0"},
                                                       "buffers": [{"uri": ["a.bin"], "byteLength": 4}]}))
    (tmp_path / "Array.gltf").write_text(json.dumps([{"asset": {"version": "2.0"}}]))
    (tmp_path / "NotJson.glb").write_bytes(_glb(_chunk(b"JSON", b"{not json")))
    (tmp_path / "good.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    assert main(["datagen", "ingest", str(tmp_path), "--out", str(out), "--quiet"]) == 1
    st = _status(out)
    assert "uri is a list, expected a string" in st["ListUri.gltf"].reason
    assert "JSON is a list, expected an object" in st["Array.gltf"].reason
    assert "does not parse" in st["NotJson.glb"].reason
    assert st["good.pmx"].status == "ok" and len(read_records(out, "characters")) == 1


# --- 3. clip length bound, before allocating ---------------------------------------------------

def test_a_vmd_key_at_frame_2_31_is_a_failed_row_and_the_bound_can_be_raised(tmp_path):
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    far = vmd_bytes([("センター", 2 ** 31, (0, 0, 0), (0, 0, 0, 1), {})])
    assert len(far) < 300
    (tmp_path / "a_far.vmd").write_bytes(far)
    (tmp_path / "b.pmx").write_bytes(pmx_bytes(encoding=1))
    (tmp_path / "b_walk.vmd").write_bytes(vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {}),
                                                    ("センター", 50, (0, 1, 0), (0, 0, 0, 1), {})]))
    out = tmp_path / "ds"
    assert main(["datagen", "ingest", str(tmp_path / "a.pmx"), str(tmp_path / "b.pmx"), "--out", str(out),
                 "--quiet"]) == 1  # the motion file failed; the models are ok
    st = _status(out)
    assert st["a_far.vmd"].status == "failed"
    assert f"{2 ** 31 + 1} frames exceed the clip length bound of {MAX_CLIP_FRAMES}" in st["a_far.vmd"].reason
    assert "--max-clip-frames" in st["a_far.vmd"].reason
    assert sorted(c.character_id for c in read_records(out, "characters")) == ["assets/a", "assets/b"]
    assert [m.num_frames for m in read_records(out, "motions")] == [51]
    out2 = tmp_path / "ds2"
    assert main(["datagen", "ingest", str(tmp_path / "b.pmx"), "--out", str(out2), "--max-clip-frames", "50",
                 "--quiet"]) == 1
    assert "51 frames exceed the clip length bound of 50" in _status(out2)["b_walk.vmd"].reason
    assert main(["datagen", "ingest", str(tmp_path / "b.pmx"), "--out", str(out2), "--max-clip-frames", "51",
                 "--quiet"]) == 0
    assert _status(out2)["b_walk.vmd"].status == "ok" and len(read_records(out2, "motions")) == 1


def test_gltf_frame_times_are_bounded_before_allocating():
    # one key at t = 1e7 s at 24 fps is 240 million frames
    with pytest.raises(ClipTooLong, match="240000001 frames exceed"):
        frame_times(0.0, 1e7, 24.0)
    with pytest.raises(ClipTooLong, match="exceed"):
        frame_times(0.0, float("inf"), 24.0)
    assert len(frame_times(0.0, 1.0, 24.0)) == 25
    with pytest.raises(ClipTooLong, match="26 frames exceed the clip length bound of 25"):
        frame_times(0.0, 25 / 24, 24.0, max_frames=25)


def test_a_bvh_declaring_a_billion_frames_fails_before_blender(tmp_path):
    bvh = tmp_path / "huge.bvh"
    bvh.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n"
                   "  End Site\n  {\n    OFFSET 0 100 0\n  }\n}\nMOTION\nFrames: 1000000000\nFrame Time: 0.0333\n0 0 0\n")
    (tmp_path / "good.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    s = ingest_assets([bvh, tmp_path / "good.pmx"], out, progress=False)
    st = _status(out)
    assert st["huge.bvh"].status == "failed" and "1000000000 frames exceed" in st["huge.bvh"].reason
    assert s["failed"] == 1 and st["good.pmx"].status == "ok"


# --- 4. character IDs unique across formats and runs -------------------------------------------

def _hashed(stem: str, path) -> str:
    return f"assets/{stem}-{hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:8]}"


def test_same_stem_mmd_models_get_distinct_ids_in_one_run_and_across_runs(tmp_path):
    for sub in ("x", "y", "z"):
        (tmp_path / sub).mkdir()
    a, b, c = tmp_path / "x" / "Gene.pmx", tmp_path / "y" / "Gene.pmx", tmp_path / "z" / "Gene.pmx"
    a.write_bytes(pmx_bytes())
    b.write_bytes(pmx_bytes(encoding=1))
    c.write_bytes(pmx_bytes(version=2.1))
    pmd = tmp_path / "x" / "Gene.pmd"
    pmd.write_bytes(pmd_bytes())
    out = tmp_path / "ds"
    ingest_assets([a, b], out, progress=False)
    first = {ch.character_id: ch.source for ch in read_records(out, "characters")}
    assert first == {"assets/Gene": str(a.resolve()), _hashed("Gene", b): str(b.resolve())}
    assert validate_dataset(out) == []
    ingest_assets([c, pmd], out, progress=False)  # a later run: the same stem from another folder and format
    chars = {ch.character_id: ch.source for ch in read_records(out, "characters")}
    assert chars == {**first, _hashed("Gene", c): str(c.resolve()), _hashed("Gene", pmd): str(pmd.resolve())}
    bodies = sorted(r.character_id for r in read_records(out, "rigid_bodies"))
    assert bodies == sorted([cid for cid in chars for _ in range(2)])  # every model's 2 bodies kept
    ingest_assets([a], out, progress=False)  # the same file again keeps its ID and replaces only itself
    assert {ch.character_id: ch.source for ch in read_records(out, "characters")} == chars


# --- 5. a dataset folder whose manifest is missing ----------------------------------------------

def test_ingest_into_a_folder_that_lost_its_manifest_is_refused_and_loses_nothing(tmp_path, capsys):
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    (tmp_path / "b.pmx").write_bytes(pmx_bytes(encoding=1))
    out = tmp_path / "ds"
    assert main(["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(out), "--quiet"]) == 0
    (out / "manifest.json").unlink()
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main(["datagen", "ingest", str(tmp_path / "b.pmx"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "mimicbench: error:" in err and "no manifest.json" in err and "Traceback" not in err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


# --- 6. a path holding '#' ------------------------------------------------------------------------

def test_counts_and_status_rows_add_up_for_a_folder_with_a_hash(tmp_path, capsys):
    src = tmp_path / "take#2"
    src.mkdir()
    (src / "good.pmx").write_bytes(pmx_bytes())
    (src / "good_hop.vmd").write_bytes(vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {})]))
    (src / "cut.pmx").write_bytes(pmx_bytes()[:300])
    out = tmp_path / "ds"
    for _ in range(3):
        capsys.readouterr()
        assert main(["datagen", "ingest", str(src), "--out", str(out), "--quiet"]) == 1
        text = capsys.readouterr().out
        assert "2 ok, 1 failed" in text and "1 failed, 0 clips unreadable" in text
        rows = read_records(out, "status")
        assert sorted(r.asset.rsplit("/", 1)[-1] for r in rows) == ["cut.pmx", "good.pmx", "good_hop.vmd"]


# --- 7. NaN in stored values ----------------------------------------------------------------------

def test_nonfinite_arrays_names_each_field_and_count():
    from mimicbench.schemas.finite import nonfinite_arrays

    rec = MotionRecord("a/b", "a", "b", "train", 30.0, 2, 1, np.array([[[1, 0, 0, 0, 0, np.inf, 0]], [[np.nan] * 7]]))
    assert nonfinite_arrays(rec, ("transforms", "scale")) == ["transforms (8 values)"]
    rec.transforms = np.zeros((2, 1, 7))
    assert nonfinite_arrays(rec, ("transforms", "scale")) == []


def test_validate_reports_nan_in_a_stored_motion(tmp_path):
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    ingest_assets([tmp_path / "a.pmx"], out, progress=False)
    (char,) = read_records(out, "characters")
    t = np.zeros((4, 3, 7), np.float32)
    t[..., 0] = 1.0
    t[2, 1, 1:4] = np.nan
    t[3, 0, 4] = np.inf
    write_records(out, "motions", [MotionRecord(f"{char.character_id}/bad", char.character_id, "bad", char.split, 30.0,
                                                4, 3, t)], char.split)
    problems = validate_dataset(out, values=True)
    assert any("'transforms' holds 4 NaN or infinite values" in p for p in problems), problems
    assert main(["validate", str(out)]) == 1


# --- end to end through Blender: a NaN rotation, a key at t = 1e7 s, ok.pmx beside ok.glb ----------

def _small_glb(path, times, rotations):
    """A 2-joint skinned glTF (joint 1 at y = 1) with one clip rotating joint 1."""
    from tests.gltf_edit import add_accessor, write_glb

    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 2]}],
           "nodes": [{"name": "j0", "children": [1]}, {"name": "j1", "translation": [0, 1, 0]},
                     {"name": "skinned", "mesh": 0, "skin": 0}],
           "meshes": [], "accessors": [], "bufferViews": [], "skins": [], "animations": []}
    blob = bytearray()
    pos = add_accessor(doc, blob, np.array([[0, 2, 0], [0, 1, 0], [1, 1, 0]]))
    joints = add_accessor(doc, blob, np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]]), dtype=np.uint8)
    weights = add_accessor(doc, blob, np.array([[1, 0, 0, 0], [0.5, 0.5, 0, 0], [1, 0, 0, 0]]))
    ibm = np.stack([np.eye(4), np.linalg.inv(np.array([[1, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 0], [0, 0, 0, 1.0]]))])
    ibm_acc = add_accessor(doc, blob, ibm.transpose(0, 2, 1).reshape(2, 16), kind="MAT4")
    doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": joints, "WEIGHTS_0": weights},
                                      "indices": None}]}]
    doc["meshes"][0]["primitives"][0].pop("indices")
    doc["skins"] = [{"joints": [0, 1], "inverseBindMatrices": ibm_acc}]
    t = add_accessor(doc, blob, np.array(times, float)[:, None])
    r = add_accessor(doc, blob, np.array(rotations, float))
    doc["animations"] = [{"name": "bend", "samplers": [{"input": t, "output": r}],
                          "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]
    return write_glb(path, doc, blob)


@pytest.mark.slow
def test_blender_assets_nan_rotation_far_key_and_a_pmx_beside_a_glb(tmp_path):
    q90 = [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    _small_glb(tmp_path / "ok.glb", [0.0, 1.0], [[0, 0, 0, 1], q90])
    _small_glb(tmp_path / "nan.glb", [0.0, 1.0], [[0, 0, 0, 1], [np.nan, 0, 0, 1]])
    _small_glb(tmp_path / "far.glb", [0.0, 1e7], [[0, 0, 0, 1], q90])
    out = tmp_path / "ds"
    s = ingest_assets([tmp_path / "ok.glb", tmp_path / "nan.glb", tmp_path / "far.glb"], out, progress=False)
    st = {r.asset.rsplit("/", 1)[-1]: r for r in read_records(out, "status")}
    assert st["ok.glb"].status == "ok"
    assert st["nan.glb"].status == "failed" and "1 NaN or infinite values in the rotation of node 1" in st["nan.glb"].reason
    assert st["far.glb"].status == "failed" and "frames exceed the clip length bound" in st["far.glb"].reason
    motions = read_records(out, "motions")
    assert [m.motion_id for m in motions] == ["assets/ok/bend"]
    assert all(np.isfinite(m.transforms).all() for m in motions)
    assert s["failed"] == 2 and validate_dataset(out) == []
    # a later run: ok.pmx from another folder next to the glTF ok.glb gets its own ID
    (tmp_path / "mmd").mkdir()
    pmx = tmp_path / "mmd" / "ok.pmx"
    pmx.write_bytes(pmx_bytes())
    ingest_assets([pmx], out, progress=False)
    chars = {c.character_id: c.source for c in read_records(out, "characters")}
    assert chars["assets/ok"] == str((tmp_path / "ok.glb").resolve())
    assert chars[_hashed("ok", pmx)] == str(pmx.resolve())
    assert [m.motion_id for m in read_records(out, "motions")] == ["assets/ok/bend"]
    shutil.rmtree(out)


@pytest.mark.slow
def test_an_fbx_clip_longer_than_the_bound_is_a_failed_clip_row(assets_dir, tmp_path):
    from tests.fbx_fixtures import export_glb_as_fbx

    fbx = export_glb_as_fbx(assets_dir / "glb" / "CesiumMan.glb", tmp_path / "ManFbx.fbx")
    out = tmp_path / "ds"
    s = ingest_assets([fbx], out, progress=False, max_clip_frames=10)
    rows = read_records(out, "status")
    clip_rows = [r for r in rows if r.asset.startswith(f"{fbx.resolve()}#")]
    assert clip_rows and all(r.status == "failed" and "exceed the clip length bound of 10 frames" in r.reason
                             for r in clip_rows)
    assert s["failed"] == 0 and s["failed_clips"] == len(clip_rows)
    assert len(read_records(out, "characters")) == 1 and read_records(out, "motions") == []
    s = ingest_assets([fbx], tmp_path / "ds2", progress=False)  # the default bound takes the clip
    assert s["failed_clips"] == 0 and len(read_records(tmp_path / "ds2", "motions")) >= 1


def test_validate_reports_a_character_id_held_by_two_rows(tmp_path):
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    ingest_assets([tmp_path / "a.pmx"], out, progress=False)
    (char,) = read_records(out, "characters")
    other = "val" if char.split != "val" else "test"
    twin = read_records(out, "characters")[0]
    twin.split, twin.source = other, "/elsewhere/a.pmx"
    write_records(out, "characters", [twin], other)  # the same ID in another split
    problems = validate_dataset(out)
    assert any("1 character_id values held by more than one row (assets/a)" in p for p in problems), problems
