"""Ingest of the shared real assets through Blender, checked against the glTF 2.0 specification
(:mod:`tests.gltf_reference`, a numpy evaluator that never touches Blender), against BVH offsets
read by hand, and for resume, collisions, failures and options."""
import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from mimicbench.datagen.ingest import blender_pool
from mimicbench.datagen.ingest.runner import ingest_assets
from mimicbench.cli import main
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.manifest import load_manifest
from mimicbench.schemas.shards import read_records
from mimicbench.schemas.validate import validate_dataset
from tests.gltf_edit import make_variant
from tests.gltf_reference import GltfReference

pytestmark = pytest.mark.blender

# joints and clips per asset (../shared/assets/LICENSES.md); frames for a few clips:
# clip seconds x 24 fps + 1 (glTF clips sampled at Blender's 24 fps; BVH at its own rate)
EXPECTED = {"Fox": (24, 3), "CesiumMan": (19, 1), "RobotExpressive": (43, 14), "Quaternius_Horse": (50, 13),
            "Quaternius_Dolphin": (13, 1), "Quaternius_Farmer": (49, 0), "Quaternius_Punk": (49, 0),
            "Quaternius_Stegosaurus": (29, 6), "Quaternius_Triceratops": (29, 6), "Quaternius_MantaRay": (13, 1),
            "Quaternius_Rat": (31, 6), "Quaternius_Husky": (49, 12), "CMU_02_01": (31, 1)}
FRAMES = {"assets/Fox/Survey": 83, "assets/Fox/Walk": 18, "assets/CesiumMan/Anim_0": 48,
          "assets/CMU_02_01/CMU_02_01": 343}
# Body plans (datagen/ingest/category.py): the four-legged dinosaurs stand on straight legs -> quadruped
CATEGORY = {"Fox": "quadruped", "Quaternius_Horse": "quadruped", "Quaternius_Husky": "quadruped",
            "Quaternius_Rat": "quadruped", "CesiumMan": "humanoid", "RobotExpressive": "humanoid",
            "Quaternius_Farmer": "humanoid", "Quaternius_Punk": "humanoid", "Quaternius_Dolphin": "fish",
            "Quaternius_MantaRay": "fish", "Quaternius_Stegosaurus": "quadruped",
            "Quaternius_Triceratops": "quadruped", "CMU_02_01": "humanoid"}
MEAN_PCT, MAX_PCT = 0.05, 0.5  # the bounds, percent of height


@pytest.fixture(scope="module")
def ingested(assets_dir, tmp_path_factory):
    """Every shared glTF asset and the BVH, ingested once for this module (two Blender processes)."""
    out = tmp_path_factory.mktemp("ingest") / "assets"
    paths = sorted((assets_dir / "glb").glob("*.glb")) + [assets_dir / "bvh" / "CMU_02_01.bvh"]
    summary = ingest_assets(paths, out, jobs=2, timeout=600, category_map={"*MantaRay*": "fish"}, progress=False)
    return out, summary


def load(out, stem):
    """(character, {clip name: motion}, child result JSON, child arrays) of ``assets/<stem>``."""
    char = [c for c in read_records(out, "characters") if c.character_id == f"assets/{stem}"][0]
    motions = {m.name: m for m in read_records(out, "motions") if m.character_id == char.character_id}
    key = char.meta["ingest"]["cache_key"]
    meta = json.loads((out / ".ingest" / f"{key}.json").read_text())
    return char, motions, meta, dict(np.load(out / ".ingest" / f"{key}.npz"))


def vertex_map(ref: GltfReference, meshes: list[str], counts) -> np.ndarray:
    """Index into ``ref.vertices()`` of each stored vertex: Blender keeps each glTF mesh node's
    vertices in order as one object named after the node (``.001``-style or numeric suffixes when
    names collide); an object whose name matches no node takes the unmatched node with its count."""
    offsets, per_node, off = {}, {}, 0
    for p in ref.primitives():
        name = ref.nodes[p.node].get("name") or f"node{p.node}"
        per_node.setdefault(name, []).append(np.arange(off, off + len(p.positions)))
        off += len(p.positions)
    nodes = {n: np.concatenate(v) for n, v in per_node.items()}
    used, out = set(), []
    for name, count in zip(meshes, counts):
        match = name if name in nodes else re.sub(r"(\.\d{3}|\d+)$", "", name)
        if match not in nodes or match in used or len(nodes[match]) != count:
            match = [n for n in nodes if n not in used and len(nodes[n]) == count][0]
        used.add(match)
        offsets[name] = match
        out.append(nodes[match])
    return np.concatenate(out)


def compare_with_reference(path, char, motions, meta, arrays, skip=(), unit=1.0):
    """Per clip (mean %, max %) of stored LBS vs the glTF evaluator at 5 frames per clip (the
    evaluator's metres times ``unit``, the ingest's ``mesh_unit``)."""
    ref = GltfReference(path)
    idx = vertex_map(ref, meta["meshes"], arrays["mesh_vertex_counts"])
    height = float(np.ptp(ref.vertices(None)[:, 1])) * unit
    names = [a.get("name") for a in ref.animations]
    errors = {}
    for ci, clip in enumerate(meta["clips"]):
        ai = names.index(clip["name"]) if clip["name"] in names else ci
        t0, _ = ref.clip_range(ai)
        assert abs(clip["t0"] - t0) < 1e-4, (path, clip["name"], clip["t0"], t0)  # frame 0 is the first key
        m = motions[clip["name"]]
        frames = sorted({0, 1, m.num_frames // 3, m.num_frames // 2, m.num_frames - 1})
        pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, m.transforms[frames],
                                     None if m.scale is None else m.scale[frames])
        want = np.stack([ref.vertices(ai, t0 + f / m.fps)[idx] for f in frames]) * unit  # frame f is t0 + f / fps
        d = np.linalg.norm(pred - want, axis=-1) / height * 100
        errors[clip["name"]] = (float(d.mean()), float(d.max()))
    return errors


@pytest.mark.slow
def test_joint_clip_and_frame_counts_match_the_files(ingested):
    out, summary = ingested
    assert summary["failed"] == 0 and summary["failed_clips"] == 0 and validate_dataset(out) == []
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
    # no bone of the Horse scales (its nodes' 0.99998-style export scales stay below the tolerance)
    assert all(m.scale is None for m in motions if m.character_id == "assets/Quaternius_Horse")
    assert (out / "CARD.md").read_text().count("skel-") >= 3


@pytest.mark.slow
def test_every_clip_of_every_gltf_asset_matches_the_specification(ingested, assets_dir):
    """Each clip on its own, bones it does not animate at their node's TRS, whatever came before."""
    out, _ = ingested
    worst = {}
    for path in sorted((assets_dir / "glb").glob("*.glb")):
        char, motions, meta, arrays = load(out, path.stem)
        errors = compare_with_reference(path, char, motions, meta, arrays)
        assert len(errors) == EXPECTED[path.stem][1]
        for clip, (mean, mx) in errors.items():
            assert mean < MEAN_PCT and mx < MAX_PCT, (path.stem, clip, mean, mx)
            worst[f"{path.stem}/{clip}"] = mx
            # the error recorded in meta (vs Blender's own evaluation) is as small
            rec = [c for c in char.meta["ingest"]["clips"] if c["name"] == clip][0]["reproduction_error"]
            assert rec["max_pct"] < MAX_PCT
    assert len(worst) == sum(c for _, c in EXPECTED.values()) - 1  # every clip but the BVH's


@pytest.mark.slow
def test_step_cubic_retimed_and_scaled_clips_match_the_specification(assets_dir, tmp_path):
    """Variants: keys between the 24 fps samples (t0 = 0.01 s), STEP and CUBICSPLINE samplers, a
    bone scaled non-uniformly (stored in the scale column), a clip that moves no bone (a status row)."""
    fox = make_variant(assets_dir / "glb" / "Fox.glb", tmp_path / "FoxVariant.glb", scale_node="b_Head_05",
                       boneless_node="fox")
    rat = make_variant(assets_dir / "glb" / "Quaternius_Rat.glb", tmp_path / "RatVariant.glb", scale_node="Body",
                       scale_to=(0.88, 0.88, 0.88))
    out = tmp_path / "out"
    summary = ingest_assets([fox, rat], out, progress=False)
    assert summary["failed"] == 0
    clip_rows = [s for s in summary["statuses"] if "#" in s.asset]
    assert [s.asset.split("#")[1] for s in clip_rows] == ["NoBones"] and "animates no bone" in clip_rows[0].reason
    for path in (fox, rat):
        char, motions, meta, arrays = load(out, path.stem)
        errors = compare_with_reference(path, char, motions, meta, arrays)
        assert len(errors) == {"FoxVariant": 3, "RatVariant": 6}[path.stem]
        for clip, (mean, mx) in errors.items():
            assert mean < MEAN_PCT and mx < MAX_PCT, (path.stem, clip, mean, mx)
        assert all(m.scale is not None for m in motions.values())  # every clip scales a bone
        # without the scale column the scaled bone's vertices are off: the column carries real information
        m = next(iter(motions.values()))
        f = m.num_frames // 2
        rigid = linear_blend_skinning(char.vertices, char.keypoints, char.weights, m.transforms[f])
        scaled = linear_blend_skinning(char.vertices, char.keypoints, char.weights, m.transforms[f], m.scale[f])
        assert np.abs(rigid - scaled).max() / char.height > 0.005


@pytest.mark.slow
def test_mesh_unit_rescales_a_file_in_another_unit_and_its_size_is_warned(ingested, assets_dir, tmp_path):
    """The Fox is authored in centimetres but glTF declares metres: as read it is 79 m tall and
    the run warns; with --mesh-unit 0.01 every length (mesh, joints, clip translations) is a
    hundredth, the clips still match the specification's evaluator (scaled), and no warning."""
    out, summary = ingested
    assert [w for w in summary["warnings"] if w.startswith("assets/Fox:") and "--mesh-unit" in w]
    assert not [w for w in summary["warnings"] if "CesiumMan" in w or "Quaternius" in w]
    fox = assets_dir / "glb" / "Fox.glb"
    small = ingest_assets([fox], tmp_path / "small", mesh_unit=0.01, progress=False)
    assert small["warnings"] == []
    char, motions, meta, arrays = load(tmp_path / "small", "Fox")
    big, big_motions, _, _ = load(out, "Fox")
    assert char.meta["ingest"]["metres_per_unit"] == pytest.approx(0.01) and big.meta["ingest"]["metres_per_unit"] == pytest.approx(1.0)
    assert 0.7 < char.height < 0.9
    np.testing.assert_allclose(char.vertices, big.vertices * 0.01, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(char.keypoints, big.keypoints * 0.01, rtol=1e-5, atol=1e-6)
    for name, m in motions.items():
        np.testing.assert_array_equal(m.transforms[..., :4], big_motions[name].transforms[..., :4])
        np.testing.assert_allclose(m.transforms[..., 4:], big_motions[name].transforms[..., 4:] * 0.01, rtol=1e-5, atol=1e-6)
    for name, (mean, worst) in compare_with_reference(fox, char, motions, meta, arrays, unit=0.01).items():
        assert mean < MEAN_PCT and worst < MAX_PCT, (name, mean, worst)
    with pytest.raises(ValueError, match="--mesh-unit"):
        ingest_assets([fox], tmp_path / "bad", mesh_unit=0.0, progress=False)


# the rule that decides each (datagen/ingest/category.py): the Fox's forelegs come down to the ground, so it is
# a quadruped, not the ambiguous biped with small arms off the ground (a T-rex: unknown)
RULE = {"Fox": "forelegs named as arms, body horizontal", "Quaternius_Horse": "four legs under the body",
        "Quaternius_Husky": "four legs under the body", "Quaternius_Rat": "four legs under the body",
        "Quaternius_Stegosaurus": "four legs under the body", "Quaternius_Triceratops": "four legs under the body",
        "CesiumMan": "two arms and two legs, upright", "RobotExpressive": "two arms and two legs, upright",
        "Quaternius_Farmer": "two arms and two legs, upright", "Quaternius_Punk": "two arms and two legs, upright",
        "CMU_02_01": "two arms and two legs, upright", "Quaternius_Dolphin": "fins and no legs",
        "Quaternius_MantaRay": "fins and no legs"}


@pytest.mark.slow
def test_skeleton_families_and_inferred_categories(ingested):
    out, _ = ingested
    chars = {c.character_id.split("/")[1]: c for c in read_records(out, "characters")}
    for stem, cat in CATEGORY.items():
        assert chars[stem].category == cat, (stem, chars[stem].meta["category"])
        assert chars[stem].meta["category"]["evidence"]["rule"] == RULE[stem], (stem, chars[stem].meta["category"])
        source = chars[stem].meta["category"]["source"]
        assert source == ("map" if stem == "Quaternius_MantaRay" else "inferred")
        assert chars[stem].meta["category"]["evidence"]["rule"]
    families = {}
    for stem, c in chars.items():
        families.setdefault(c.skeleton_id, set()).add(stem)
    shared = sorted(sorted(f) for f in families.values() if len(f) > 1)
    assert shared == [["Quaternius_Dolphin", "Quaternius_MantaRay"], ["Quaternius_Farmer", "Quaternius_Punk"],
                      ["Quaternius_Stegosaurus", "Quaternius_Triceratops"]]
    for stem, c in chars.items():  # equal skeleton_id exactly when names and parents are equal
        for other, d in chars.items():
            same = c.bone_names == d.bone_names and np.array_equal(c.parents, d.parents)
            assert (c.skeleton_id == d.skeleton_id) == same, (stem, other)


@pytest.mark.slow
def test_categories_survive_renamed_bones(ingested):
    """The same skeletons under other naming conventions infer the same category; with names that
    say nothing, the skeleton's geometry decides where it can (feet on the ground)."""
    from mimicbench.datagen.ingest.category import infer_category

    out, _ = ingested
    styles = [lambda n: "mixamorig:" + n, lambda n: "DEF-" + n.replace(".", "_"),
              lambda n: re.sub(r"\.L$", "_l", re.sub(r"\.R$", "_r", n))]
    for c in read_records(out, "characters"):
        stem = c.character_id.split("/")[1]
        _, _, _, arrays = load(out, stem)
        pose = arrays["default_keypoints"]
        for style in styles:
            cat, ev = infer_category([style(n) for n in c.bone_names], c.parents, pose)
            assert cat == CATEGORY[stem], (stem, ev)
        opaque = [f"j{i:03d}" for i in range(c.num_joints)]
        cat, ev = infer_category(opaque, c.parents, pose)
        if stem in ("Quaternius_Farmer", "Quaternius_Punk", "CesiumMan", "CMU_02_01", "Quaternius_Horse",
                    "Quaternius_Husky"):
            assert cat == CATEGORY[stem], (stem, ev)
        assert cat in (CATEGORY[stem], "unknown"), (stem, ev)  # never a confident wrong body plan


def bvh_rest_joints(path) -> tuple[list[str], np.ndarray]:
    """Joint names and rest positions (file units) of a BVH, from its OFFSETs alone."""
    names, pos, stack = [], [], []
    for line in open(path).read().split("MOTION")[0].splitlines():
        tok = line.split()
        if tok and tok[0] in ("ROOT", "JOINT"):
            names.append(tok[1])
            stack.append(len(names) - 1)
            pos.append(None)
        elif tok and tok[0] == "End":
            stack.append(None)
        elif tok and tok[0] == "OFFSET" and stack[-1] is not None:
            parent = stack[-2] if len(stack) > 1 and stack[-2] is not None else None
            pos[stack[-1]] = np.array([float(x) for x in tok[1:4]]) + (pos[parent] if parent is not None else 0)
        elif tok and tok[0] == "}":
            stack.pop()
    return names, np.array(pos)


@pytest.mark.slow
def test_bvh_becomes_a_skeleton_in_metres(ingested, assets_dir):
    out, _ = ingested
    char, motions, _, _ = load(out, "CMU_02_01")
    names, rest = bvh_rest_joints(assets_dir / "bvh" / "CMU_02_01.bvh")
    order = [names.index(n) for n in char.bone_names]
    # default --bvh-scale auto: this file's skeleton is about 24 units tall, which is 0.24 m in centimetres
    # and 24 m in metres, so CMU's own unit (inches / 0.45 = 0.056444 m) is taken (BVH is Y up like the dataset)
    want = rest[order] * 0.056444
    np.testing.assert_allclose(char.keypoints - char.keypoints[0], want - want[0], atol=1e-4)
    assert char.meta["ingest"]["bvh_scale"] == pytest.approx(0.056444) and char.meta["ingest"]["bvh_unit"].startswith("CMU")
    assert load_manifest(out)["configs"]["characters"]["bvh_scale"] == "auto"
    assert 1.2 < np.ptp(char.keypoints[:, 1]) < 1.9  # a person, in metres
    assert char.height is None and len(char.faces) == 0
    assert max(np.ptp(m.transforms[..., 4:].reshape(-1, 3), axis=0).max() for m in motions.values()) < 10
    # frame f is the file's frame f, at f / fps: t0 = 0 (Blender's importer puts it at frame 1, which is not time 1/fps)
    clip = char.meta["ingest"]["clips"][0]
    assert clip["t0"] == 0 and clip["first_frame"] == 0
    rows = np.array([[float(x) for x in line.split()] for line in
                     (assets_dir / "bvh" / "CMU_02_01.bvh").read_text().split("Frame Time:")[1].splitlines()[1:]
                     if line.strip()])
    (m,) = motions.values()
    root = char.bone_names.index(names[0])  # root OFFSET 0; channels Xposition Yposition Zposition first
    assert m.num_frames == len(rows)
    for f in (0, 1, 100, len(rows) - 1):
        np.testing.assert_allclose(m.transforms[f, root, 4:], rows[f, :3] * 0.056444, atol=1e-5)


@pytest.mark.slow
def test_ingest_is_additive_and_collision_free(assets_dir, tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    fox_a = shutil.copy(assets_dir / "glb" / "Fox.glb", tmp_path / "a" / "Beast.glb")
    fox_b = shutil.copy(assets_dir / "glb" / "Quaternius_Dolphin.glb", tmp_path / "b" / "Beast.glb")
    out = tmp_path / "out"
    first = ingest_assets([fox_a, fox_b], out, progress=False, split="test")
    ids = first["character_ids"]
    assert len(set(ids.values())) == 2 and ids[str(fox_a)] == "assets/Beast"
    assert re.fullmatch(r"assets/Beast-[0-9a-f]{8}", ids[str(fox_b)])
    chars = {c.character_id: c for c in read_records(out, "characters")}
    assert chars[ids[str(fox_a)]].num_joints == 24 and chars[ids[str(fox_b)]].num_joints == 13
    assert len(list((out / ".ingest").glob("Beast-*.npz"))) == 2 and {c.split for c in chars.values()} == {"test"}
    # a second run adds a character and keeps the others
    second = ingest_assets([assets_dir / "glb" / "CesiumMan.glb", fox_a], out, progress=False)
    assert second["skipped"] == 1 and second["ingested"] == 1
    assert {c.character_id for c in read_records(out, "characters")} == set(ids.values()) | {"assets/CesiumMan"}
    assert "Beast" in (out / "CARD.md").read_text() or (out / "CARD.md").exists()
    # a changed file under the same path is ingested again (the cache key holds its content hash)
    shutil.copy(assets_dir / "glb" / "Quaternius_MantaRay.glb", fox_a)
    third = ingest_assets([fox_a], out, progress=False)
    assert third["ingested"] == 1 and third["skipped"] == 0
    chars = {c.character_id: c for c in read_records(out, "characters")}
    assert len(chars) == 3 and len(chars["assets/Beast"].vertices) == 1432
    assert validate_dataset(out) == []


@pytest.mark.slow
def test_broken_files_timeouts_and_crashes_become_status_rows(assets_dir, tmp_path, monkeypatch):
    truncated = tmp_path / "Truncated.glb"
    truncated.write_bytes((assets_dir / "glb" / "Fox.glb").read_bytes()[:5000])
    fake = tmp_path / "NotAnFbx.fbx"
    fake.write_text("this is a text file, not an FBX\n")
    hang = shutil.copy(assets_dir / "glb" / "Quaternius_Dolphin.glb", tmp_path / "HangingDolphin.glb")
    crash = shutil.copy(assets_dir / "glb" / "Quaternius_Dolphin.glb", tmp_path / "CrashingDolphin.glb")
    obj = tmp_path / "Plain.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    good = assets_dir / "glb" / "CesiumMan.glb"
    monkeypatch.setattr(blender_pool, "CHILD_MODULE", "tests.ingest_hang_child")  # injects the hang and crash
    summary = ingest_assets([truncated, fake, hang, crash, obj, good], tmp_path / "out", jobs=1, timeout=30,
                            progress=False)
    reasons = {s.asset.split("/")[-1]: s for s in summary["statuses"]}
    assert reasons["CesiumMan.glb"].status == "ok"  # after a hang and a crash, in a fresh process
    assert reasons["Truncated.glb"].status == "failed" and reasons["Truncated.glb"].reason
    assert reasons["NotAnFbx.fbx"].status == "failed" and reasons["NotAnFbx.fbx"].reason
    assert "timed out after 30 s" in reasons["HangingDolphin.glb"].reason
    assert "ended with code 3" in reasons["CrashingDolphin.glb"].reason
    assert "no armature" in reasons["Plain.obj"].reason
    assert [c.character_id for c in read_records(tmp_path / "out", "characters")] == ["assets/CesiumMan"]
    assert not list((tmp_path / "out" / ".ingest").glob("HangingDolphin*"))  # its partial result was dropped
    # a re-run with the real child skips what is done and retries the failures
    monkeypatch.setattr(blender_pool, "CHILD_MODULE", "mimicbench.datagen.ingest.blender_child")
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


def _child_error(out, stem):
    """Reproduction error of clip 0 of ``assets/<stem>`` against Blender's evaluation of the file."""
    char, motions, meta, arrays = load(out, stem)
    return char.meta["ingest"]["clips"][0]["reproduction_error"]["max_pct"], meta


@pytest.mark.slow
def test_fbx_exported_by_blender_ingests_like_its_glb(assets_dir, tmp_path):
    from tests.fbx_fixtures import export_glb_as_fbx

    fbx = export_glb_as_fbx(assets_dir / "glb" / "CesiumMan.glb", tmp_path / "CesiumManFbx.fbx")
    summary = ingest_assets([fbx], tmp_path / "out", progress=False)
    assert summary["failed"] == 0
    char = read_records(tmp_path / "out", "characters")[0]
    assert char.num_joints == 19 and len(char.vertices) > 3000 and char.category == "humanoid"
    err, meta = _child_error(tmp_path / "out", "CesiumManFbx")
    assert err < 0.1 and meta["clips"]


@pytest.mark.slow
def test_non_armature_modifiers_are_applied(assets_dir, tmp_path):
    blend = tmp_path / "CesiumSubsurf.blend"
    script = ("import bpy, sys\nbpy.ops.wm.read_factory_settings(use_empty=True)\n"
              "bpy.ops.import_scene.gltf(filepath=sys.argv[-2])\n"
              "mesh = [o for o in bpy.context.scene.objects if o.type == 'MESH' and o.parent][0]\n"
              "mesh.modifiers.new('smooth', 'SUBSURF').levels = 1\n"
              "bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])\n")
    subprocess.run([sys.executable, "-c", script, str(assets_dir / "glb" / "CesiumMan.glb"), str(blend)], check=True,
                   capture_output=True, timeout=300)
    assert ingest_assets([blend], tmp_path / "out", progress=False)["failed"] == 0
    char = read_records(tmp_path / "out", "characters")[0]
    assert len(char.vertices) > 3273 and any("smooth" in m for m in char.meta["ingest"]["applied_modifiers"])
    err, meta = _child_error(tmp_path / "out", "CesiumSubsurf")
    assert err < 0.1
    # a .blend keeps Blender's clock (frame F at F / fps): the clip the glTF importer keyed at t * 24 starts at the glTF's first key
    t0, _ = GltfReference(assets_dir / "glb" / "CesiumMan.glb").clip_range(0)
    assert abs(meta["clips"][0]["t0"] - t0) < 1e-4 and abs(meta["clips"][0]["first_frame"] - t0 * 24) < 1e-3


@pytest.mark.slow
def test_ingested_assets_flow_through_resample_correspond_and_benchmark(ingested, assets_dir, tmp_path):
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.benchmark.cases import build_cases, write_cases
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.datagen.correspond.stage import correspond_dataset
    from mimicbench.datagen.resample.stage import resample_dataset

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
    correspond_dataset(data, all_pairs=True, progress=False)
    cases = build_cases(data, "all", cct_pairs=6, cct_poses=2)  # categories inferred at ingest
    assert cases["cct"]
    write_cases(data, {"cct": cases["cct"]}, {})
    run_benchmark(data, ["identity", "nearest_joint", "text_soft"], ("cct",), tmp_path / "res", progress=False)
    entries = aggregate(tmp_path / "res")["protocols"]["cct"]
    assert all(e["complete"] for e in entries), [e["first_error"] for e in entries]
