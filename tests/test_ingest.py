"""Ingest of the shared real assets through Blender, in child processes."""
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from datagen.ingest import ingest_assets
from mimicbench.cli import main
from mimicbench.skinning import linear_blend_skinning
from schemas.shards import read_records
from schemas.validate import validate_dataset

pytestmark = pytest.mark.blender

# joints and clips per asset (../shared/assets/LICENSES.md); frames for a few clips:
# clip seconds x frame rate + 1 (glTF clips sampled at Blender's 24 fps; BVH at its own rate)
EXPECTED = {"Fox": (24, 3), "CesiumMan": (19, 1), "RobotExpressive": (43, 14), "Quaternius_Horse": (50, 13),
            "Quaternius_Dolphin": (13, 1), "CMU_02_01": (31, 1)}
FRAMES = {"assets/Fox/Survey": 83, "assets/Fox/Walk": 18, "assets/CesiumMan/Anim_0": 48,
          "assets/CMU_02_01/CMU_02_01": 343}


@pytest.fixture(scope="module")
def ingested(assets_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("ingest") / "assets"
    paths = sorted((assets_dir / "glb").glob("*.glb")) + [assets_dir / "bvh" / "CMU_02_01.bvh"]
    summary = ingest_assets(paths, out, jobs=2, timeout=600, category_map={"Fox*": "quadruped", "Quaternius_Horse": "quadruped",
                                                                          "*Dolphin*": "fish"}, progress=False)
    return out, summary


@pytest.mark.slow
def test_joint_clip_and_frame_counts_match_the_files(ingested):
    out, summary = ingested
    assert summary["failed"] == 0 and validate_dataset(out) == []
    chars = {c.character_id.split("/")[1]: c for c in read_records(out, "characters")}
    motions = read_records(out, "motions")
    for stem, (joints, clips) in EXPECTED.items():
        assert chars[stem].num_joints == joints, stem
        assert sum(m.character_id == f"assets/{stem}" for m in motions) == clips, stem
        assert (np.asarray(chars[stem].parents) < np.arange(joints)).all()
    by_id = {m.motion_id: m for m in motions}
    for mid, frames in FRAMES.items():
        assert by_id[mid].num_frames == frames, mid
    assert abs(by_id["assets/CMU_02_01/CMU_02_01"].fps - 120) < 0.01
    assert len(chars["RobotExpressive"].vertices) == 7214 and len(chars["CMU_02_01"].vertices) == 0
    assert chars["Fox"].category == "quadruped" and chars["CesiumMan"].category == "unknown"


@pytest.mark.slow
def test_core_lbs_reproduces_blenders_evaluated_mesh(ingested):
    out, _ = ingested
    for stem in ("Fox", "CesiumMan", "RobotExpressive", "Quaternius_Horse", "Quaternius_Dolphin"):
        meta = json.loads((out / ".ingest" / f"{stem}.json").read_text())
        d = np.load(out / ".ingest" / f"{stem}.npz")
        char = [c for c in read_records(out, "characters") if c.character_id == f"assets/{stem}"][0]
        motions = {m.name: m for m in read_records(out, "motions") if m.character_id == char.character_id}
        height = float(np.ptp(char.vertices[:, 1]))
        for ci, clip in enumerate(meta["clips"]):
            frames = d[f"clip{ci}_eval_frames"]
            pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, motions[clip["name"]].transforms[frames])
            err = np.linalg.norm(pred - d[f"clip{ci}_eval_vertices"], axis=-1).max() / height * 100
            assert err < 0.1, (stem, clip["name"], err)


@pytest.mark.slow
def test_broken_files_and_timeouts_become_status_rows(assets_dir, tmp_path, monkeypatch):
    truncated = tmp_path / "Truncated.glb"
    truncated.write_bytes((assets_dir / "glb" / "Fox.glb").read_bytes()[:5000])
    fake = tmp_path / "NotAnFbx.fbx"
    fake.write_text("this is a text file, not an FBX\n")
    hang = tmp_path / "HangingDolphin.glb"
    shutil.copy(assets_dir / "glb" / "Quaternius_Dolphin.glb", hang)
    obj = tmp_path / "Plain.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    monkeypatch.setenv("MIMICBENCH_TEST_HANG", "HangingDolphin")
    good = assets_dir / "glb" / "CesiumMan.glb"
    summary = ingest_assets([truncated, fake, hang, obj, good], tmp_path / "out", jobs=2, timeout=20, progress=False)
    reasons = {s.asset.split("/")[-1]: s for s in summary["statuses"]}
    assert reasons["CesiumMan.glb"].status == "ok"
    assert reasons["Truncated.glb"].status == "failed" and reasons["Truncated.glb"].reason
    assert reasons["NotAnFbx.fbx"].status == "failed" and reasons["NotAnFbx.fbx"].reason
    assert "timed out after 20 s" in reasons["HangingDolphin.glb"].reason
    assert "no armature" in reasons["Plain.obj"].reason
    assert [c.character_id for c in read_records(tmp_path / "out", "characters")] == ["assets/CesiumMan"]
    # a re-run skips what is done and retries the failures
    monkeypatch.delenv("MIMICBENCH_TEST_HANG")
    again = ingest_assets([good, hang], tmp_path / "out", timeout=120, progress=False)
    assert again["skipped"] == 1 and again["ingested"] == 1


@pytest.mark.slow
@pytest.mark.parametrize("stem,clip", [("CesiumMan", "Anim_0"), ("Quaternius_Dolphin", "Armature_Swim")])
def test_export_obj_and_bvh_reimport_in_blender(assets_dir, tmp_path, stem, clip):
    out = tmp_path / "out"
    assert main(["datagen", "ingest", str(assets_dir / "glb" / f"{stem}.glb"), "--out", str(out), "--export", "obj,bvh",
                 "--quiet"]) == 0
    char = read_records(out, "characters")[0]
    walk = read_records(out, "motions")[0]
    script = (
        "import bpy, json, sys\n"
        "bpy.ops.wm.read_factory_settings(use_empty=True)\n"
        "bpy.ops.wm.obj_import(filepath=sys.argv[-2])\n"
        "n = len(bpy.context.scene.objects[0].data.vertices)\n"
        "bpy.ops.import_anim.bvh(filepath=sys.argv[-1])\n"
        "arm = [o for o in bpy.context.scene.objects if o.type == 'ARMATURE'][0]\n"
        "rest = [list(arm.matrix_world @ b.head_local) for b in arm.data.bones]\n"
        "bpy.context.scene.frame_set(5)\n"
        "posed = [list(arm.matrix_world @ p.head) for p in arm.pose.bones]\n"
        "print(json.dumps({'n': n, 'names': [b.name for b in arm.data.bones], 'rest': rest, 'posed': posed}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", script, str(out / "export" / f"{stem}.obj"),
                           str(out / "export" / stem / f"{clip}.bvh")], capture_output=True, text=True, timeout=300)
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["n"] > 0
    order = [char.bone_names.index(n) for n in res["names"]]
    to_y_up = lambda p: np.array(p)[:, [0, 2, 1]] * [1, 1, -1]  # noqa: E731  Blender (x, y, z) -> (x, z, -y)
    np.testing.assert_allclose(to_y_up(res["rest"]), char.keypoints[order], atol=1e-3 * float(np.ptp(char.vertices[:, 1])))
    posed = walk.transforms[4, :, 4:]  # Blender frame 5 is the clip's fifth frame
    # posed joints within 0.5% of height (BVH stores Euler angles; CesiumMan differs by up to 0.27%)
    np.testing.assert_allclose(to_y_up(res["posed"]), posed[order], atol=5e-3 * float(np.ptp(char.vertices[:, 1])))


@pytest.mark.slow
def test_fbx_exported_by_blender_ingests_like_its_glb(assets_dir, tmp_path):
    fbx = tmp_path / "CesiumManFbx.fbx"
    script = ("import bpy, sys\nbpy.ops.wm.read_factory_settings(use_empty=True)\n"
              "bpy.ops.import_scene.gltf(filepath=sys.argv[-2])\n"
              "bpy.ops.export_scene.fbx(filepath=sys.argv[-1], bake_anim=True, add_leaf_bones=False)\n")
    subprocess.run([sys.executable, "-c", script, str(assets_dir / "glb" / "CesiumMan.glb"), str(fbx)], check=True,
                   capture_output=True, timeout=300)
    summary = ingest_assets([fbx], tmp_path / "out", progress=False)
    assert summary["failed"] == 0
    char = read_records(tmp_path / "out", "characters")[0]
    assert char.num_joints == 19 and len(char.vertices) > 3000
    meta = json.loads((tmp_path / "out" / ".ingest" / "CesiumManFbx.json").read_text())
    d = np.load(tmp_path / "out" / ".ingest" / "CesiumManFbx.npz")
    motion = read_records(tmp_path / "out", "motions")[0]
    frames = d["clip0_eval_frames"]
    pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, motion.transforms[frames])
    err = np.linalg.norm(pred - d["clip0_eval_vertices"], axis=-1).max() / np.ptp(char.vertices[:, 1]) * 100
    assert err < 0.1 and meta["clips"]


@pytest.mark.slow
def test_ingested_assets_flow_through_resample_correspond_and_benchmark(ingested, assets_dir, tmp_path):
    from benchmark.aggregate import aggregate
    from benchmark.cases import build_cases, write_cases
    from benchmark.evaluator import run_benchmark
    from datagen.correspond import correspond_dataset
    from datagen.resample import resample_dataset

    src, _ = ingested
    data = tmp_path / "assets5k"
    for backend in ("pymeshlab", "fast"):  # the default backend's output feeds the rest
        out = data.with_name(f"assets5k-{backend}") if backend != "fast" else data
        summary = resample_dataset(src, out, backend=backend, progress=False)
        assert summary["failed"] == 0
        resampled = [c for c in read_records(out, "characters") if len(c.faces)]
        # every glTF asset has a mesh (the BVH has none)
        assert len(resampled) == len(list((assets_dir / "glb").glob("*.glb")))
        for c in resampled:
            q = c.meta["resample"]
            assert abs(q["faces_out"] - 5000) <= 50, c.character_id
            if q["faces_in"] < 4950:  # most assets are smaller than 5k faces and are refined first
                assert q["subdivisions"] >= 1, (c.character_id, q)
            assert q["hausdorff_pct"] < 1.0, (backend, c.character_id, q["hausdorff_pct"])
            np.testing.assert_allclose(c.weight_values.sum(1), 1.0, atol=1e-5)
            assert (c.weight_values > 0).sum(1).max() <= 8
    # the assets as humanoid (CesiumMan, Robot) vs animals, every split (before correspond: pairs
    # record the characters table's fingerprint and categories)
    import dataclasses
    from schemas.shards import write_records

    chars = read_records(data, "characters")
    humanoid = {"assets/CesiumMan", "assets/RobotExpressive"}
    chars = [dataclasses.replace(c, category="humanoid" if c.character_id in humanoid else c.category) for c in chars]
    for split in {c.split for c in chars}:
        write_records(data, "characters", [c for c in chars if c.split == split], split)
    correspond_dataset(data, all_pairs=True, progress=False)
    cases = build_cases(data, "all", cct_pairs=6, cct_poses=2)
    assert cases["cct"]
    write_cases(data, {"cct": cases["cct"]}, {})
    run_benchmark(data, ["identity", "nearest_joint", "text_soft"], ("cct",), tmp_path / "res", progress=False)
    entries = aggregate(tmp_path / "res")["protocols"]["cct"]
    assert all(e["complete"] for e in entries), [e["first_error"] for e in entries]


@pytest.mark.slow
def test_non_armature_modifiers_are_applied(assets_dir, tmp_path):
    blend = tmp_path / "CesiumSubsurf.blend"
    script = ("import bpy, sys\nbpy.ops.wm.read_factory_settings(use_empty=True)\n"
              "bpy.ops.import_scene.gltf(filepath=sys.argv[-2])\n"
              "mesh = [o for o in bpy.context.scene.objects if o.type == 'MESH'][0]\n"
              "mesh.modifiers.new('smooth', 'SUBSURF').levels = 1\n"
              "bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])\n")
    subprocess.run([sys.executable, "-c", script, str(assets_dir / "glb" / "CesiumMan.glb"), str(blend)], check=True,
                   capture_output=True, timeout=300)
    assert ingest_assets([blend], tmp_path / "out", progress=False)["failed"] == 0
    char = read_records(tmp_path / "out", "characters")[0]
    assert len(char.vertices) > 3273 and any("smooth" in m for m in char.meta["ingest"]["applied_modifiers"])
    d = np.load(tmp_path / "out" / ".ingest" / "CesiumSubsurf.npz")
    motion = read_records(tmp_path / "out", "motions")[0]
    pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, motion.transforms[d["clip0_eval_frames"]])
    err = np.linalg.norm(pred - d["clip0_eval_vertices"], axis=-1).max() / np.ptp(char.vertices[:, 1]) * 100
    assert err < 0.1
