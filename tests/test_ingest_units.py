"""Ingest pieces that need no Blender: the glTF reference evaluator against hand-computed values,
IDs and cache keys, skeleton IDs, external URIs, option checks, scaled LBS, and category inference
on the zoo (whose categories are known)."""
import json
import math

import numpy as np
import pytest
import torch

from mimicbench.datagen.ingest.category import infer_category
from mimicbench.datagen.ingest.identity import cache_key, character_id_for, file_sha256, skeleton_id
from mimicbench.datagen.ingest.runner import category_from_map, ingest_assets
from mimicbench.datagen.ingest.uris import external_uri_problems
from mimicbench.cli import main
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.geometry.skinning_torch import linear_blend_skinning_torch
from tests.gltf_edit import add_accessor, write_glb
from tests.gltf_reference import GltfReference, _interpolate, slerp


# --- the reference evaluator, by hand ----------------------------------------------------------

def test_slerp_cubic_and_step_samplers_by_hand():
    qz90 = np.array([0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)])  # (x, y, z, w): 90 deg about Z
    half = slerp(np.array([0, 0, 0, 1.0]), qz90, 0.5)
    np.testing.assert_allclose(half, [0, 0, math.sin(math.pi / 8), math.cos(math.pi / 8)], atol=1e-12)
    # the shorter arc: -q is the same rotation
    np.testing.assert_allclose(slerp(np.array([0, 0, 0, 1.0]), -qz90, 0.5), half, atol=1e-12)
    times = np.array([0.0, 1.0, 3.0])
    vals = np.array([[0.0], [10.0], [30.0]])
    assert _interpolate(times, vals, "LINEAR", 2.0, False)[0] == pytest.approx(20.0)
    assert _interpolate(times, vals, "STEP", 2.9, False)[0] == pytest.approx(10.0)
    assert _interpolate(times, vals, "LINEAR", -1.0, False)[0] == pytest.approx(0.0, abs=1e-12)
    assert _interpolate(times, vals, "LINEAR", 9, False)[0] == pytest.approx(30.0)
    # Hermite: p(s) = (2s^3-3s^2+1) p0 + (s^3-2s^2+s) td b0 + (-2s^3+3s^2) p1 + (s^3-s^2) td a1
    cubic = np.array([[0.0], [1.0], [2.0],   # key 0: in-tangent, value, out-tangent
                      [5.0], [3.0], [0.0]])  # key 1
    s, td = 0.25, 2.0
    want = (2 * s**3 - 3 * s**2 + 1) * 1 + (s**3 - 2 * s**2 + s) * td * 2 + (-2 * s**3 + 3 * s**2) * 3 + (s**3 - s**2) * td * 5
    assert _interpolate(np.array([0.0, 2.0]), cubic, "CUBICSPLINE", 0.5, False)[0] == pytest.approx(want)


def _two_bone_glb(path):
    """A 2-joint skin: joint 0 at the origin, joint 1 at y = 1 (child), a LINEAR clip rotating joint 1
    90 degrees about Z over 1 s, and a vertex at (0, 2, 0) bound to joint 1, one at (0, 1, 0) half/half,
    and an unskinned node under joint 1 carrying a mesh at its local (1, 0, 0)."""
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 2]}],
           "nodes": [{"name": "j0", "children": [1]}, {"name": "j1", "translation": [0, 1, 0], "children": [3]},
                     {"name": "skinned", "mesh": 0, "skin": 0, "translation": [5, 5, 5]},
                     {"name": "rigid", "mesh": 1, "translation": [1, 0, 0]}],
           "meshes": [], "accessors": [], "bufferViews": [], "skins": [], "animations": []}
    blob = bytearray()
    pos = add_accessor(doc, blob, np.array([[0, 2, 0], [0, 1, 0]]))
    joints = add_accessor(doc, blob, np.array([[1, 0, 0, 0], [0, 1, 0, 0]]), dtype=np.uint8)
    weights = add_accessor(doc, blob, np.array([[1, 0, 0, 0], [0.5, 0.5, 0, 0]]))
    ibm = np.stack([np.eye(4), np.linalg.inv(np.array([[1, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 0], [0, 0, 0, 1.0]]))])
    ibm_acc = add_accessor(doc, blob, ibm.transpose(0, 2, 1).reshape(2, 16), kind="MAT4")  # column-major
    doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": joints, "WEIGHTS_0": weights}}]},
                     {"primitives": [{"attributes": {"POSITION": add_accessor(doc, blob, np.zeros((1, 3)))}}]}]
    doc["skins"] = [{"joints": [0, 1], "inverseBindMatrices": ibm_acc}]
    t = add_accessor(doc, blob, np.array([[0.0], [1.0]]))
    r = add_accessor(doc, blob, np.array([[0, 0, 0, 1], [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]]))
    doc["animations"] = [{"name": "bend", "samplers": [{"input": t, "output": r}],
                          "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]
    return write_glb(path, doc, blob)


def test_reference_skins_with_inverse_bind_matrices_by_hand(tmp_path):
    ref = GltfReference(_two_bone_glb(tmp_path / "two.glb"))
    # default pose: the skinned node's own translation (5, 5, 5) is ignored; rigid mesh at j1 + (1, 0, 0)
    np.testing.assert_allclose(ref.vertices(None), [[0, 2, 0], [0, 1, 0], [1, 1, 0]], atol=1e-6)
    # at t = 1: j1 turned 90 deg about Z around (0, 1, 0): (0, 2, 0) -> (-1, 1, 0); the half/half vertex
    # sits on the joint and stays; the rigid mesh (1, 1, 0) -> (0, 2, 0)
    np.testing.assert_allclose(ref.vertices(0, 1.0), [[-1, 1, 0], [0, 1, 0], [0, 2, 0]], atol=1e-6)
    # halfway: slerp gives 45 degrees
    c = math.cos(math.pi / 4)
    np.testing.assert_allclose(ref.vertices(0, 0.5)[0], [-c, 1 + c, 0], atol=1e-6)
    assert ref.clip_range(0) == (0.0, 1.0)


# --- identity, URIs, options -------------------------------------------------------------------

def test_ids_cache_keys_and_skeleton_ids(tmp_path):
    a, b = tmp_path / "a" / "Fox.glb", tmp_path / "b" / "Fox.glb"
    a.parent.mkdir(), b.parent.mkdir()
    a.write_bytes(b"one"), b.write_bytes(b"two")
    taken = {}
    ida = character_id_for(a, taken)
    taken[ida] = str(a)
    idb = character_id_for(b, taken)
    assert ida == "assets/Fox" and idb.startswith("assets/Fox-") and len(idb) == len("assets/Fox-") + 8
    assert character_id_for(a, taken) == "assets/Fox"  # the same file keeps its ID
    ka, kb = cache_key(a, file_sha256(a), {}), cache_key(b, file_sha256(b), {})
    assert ka != kb and ka.startswith("Fox-") and cache_key(a, file_sha256(a), {"bvh_scale": 1.0}) != ka
    assert skeleton_id(["a", "b"], [-1, 0]) == skeleton_id(["a", "b"], [-1, 0])
    assert skeleton_id(["a", "b"], [-1, 0]) != skeleton_id(["a", "b"], [-1, -1])
    assert skeleton_id(["a", "b"], [-1, 0]) != skeleton_id(["a", "c"], [-1, 0])
    # parents by name: the same skeleton listed in another order is the same family only if equal as stored
    assert skeleton_id(["a", "b", "c"], [-1, 0, 0]) != skeleton_id(["a", "c", "b"], [-1, 0, 0])


def _gltf(tmp_path, uri):
    path = tmp_path / "asset" / "Thing.gltf"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": uri, "byteLength": 4}],
                                "images": [{"uri": "textures/skin.png"}]}))
    return path


@pytest.mark.parametrize("uri,bad", [("../secret.bin", True), ("/etc/passwd", True), ("file:///etc/passwd", True),
                                     ("sub/../../x.bin", True), ("data.bin", False), ("sub/data%20x.bin", False),
                                     ("data:application/octet-stream;base64,AAAA", False)])
def test_external_uris_outside_the_folder_are_found(tmp_path, uri, bad):
    assert bool(external_uri_problems(_gltf(tmp_path, uri))) == bad


def test_external_uris_are_refused_with_a_status_row(tmp_path):
    path = _gltf(tmp_path, "../secret.bin")
    s = ingest_assets([path], tmp_path / "out", progress=False)
    assert s["failed"] == 1 and "outside" in s["statuses"][0].reason and "--allow-external-uris" in s["statuses"][0].reason


@pytest.mark.parametrize("kwargs,message", [({"timeout": 0}, "--timeout"), ({"jobs": 0}, "--jobs"),
                                            ({"bvh_scale": -1}, "--bvh-scale"), ({"export": ("stl",)}, "--export"),
                                            ({"category_map": {"x": "dragon"}}, "--category-map"),
                                            ({"split": "holdout"}, "--split")])
def test_options_are_range_checked(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        ingest_assets([tmp_path / "x.glb"], tmp_path / "out", progress=False, **kwargs)
    assert not (tmp_path / "out").exists()  # nothing written


@pytest.mark.parametrize("args,needle", [(["--timeout", "0"], "--timeout: expected a finite number > 0"),
                                         (["--jobs", "0"], "--jobs: expected an integer >= 1"),
                                         (["--export", "stl"], "--export: unknown 'stl'; expected a comma-separated list of obj, bvh"),
                                         (["--bvh-scale", "x"], "--bvh-scale: expected a finite number > 0"),
                                         (["--mesh-unit", "-1"], "--mesh-unit: expected a finite number > 0")])
def test_cli_rejects_bad_options(tmp_path, capsys, args, needle):
    with pytest.raises(SystemExit) as e:
        main(["datagen", "ingest", "x.glb", "--out", str(tmp_path / "o")] + args)
    assert e.value.code == 2 and needle in capsys.readouterr().err


def test_category_map_names_assets(tmp_path):
    from pathlib import Path

    assert category_from_map(Path("/x/Fox.glb"), {"Fox*": "quadruped"}) == "quadruped"
    assert category_from_map(Path("/x/Fox.glb"), {"Fox": "quadruped"}) == "quadruped"
    assert category_from_map(Path("/x/Cat.glb"), {"Fox*": "quadruped"}) is None


# --- scaled LBS ----------------------------------------------------------------------------------

def test_lbs_honours_a_bone_stretch_by_hand():
    rest = np.array([[1.0, 0, 0], [0, 2, 0]])
    keypoints = np.array([[0.0, 0, 0]])
    weights = np.ones((2, 1))
    t = np.array([[[math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4), 0, 0, 1]]])  # 90 deg about Z, moved up 1
    scale = np.array([[[0.5, 2.0, 1.0, 0, 0, 0]]])  # U = diag(0.5, 2, 1) in the rest frame
    # R U p + t: (1,0,0) -> U (0.5,0,0) -> R (0,0.5,0) -> (0,0.5,1); (0,2,0) -> (0,4,0) -> (-4,0,0) -> (-4,0,1)
    got = linear_blend_skinning(rest, keypoints, weights, t, scale)
    np.testing.assert_allclose(got[0], [[0, 0.5, 1], [-4, 0, 1]], atol=1e-6)
    np.testing.assert_allclose(linear_blend_skinning(rest, keypoints, weights, t),
                               linear_blend_skinning(rest, keypoints, weights, t, np.array([[[1, 1, 1, 0, 0, 0.0]]])))
    # a shear term (s_xy) and the torch twin
    sheared = np.array([[[1.0, 1.0, 1.0, 0.3, 0, 0]]])
    want = linear_blend_skinning(rest, keypoints, weights, t, sheared)
    # U = [[1, .3, 0], [.3, 1, 0], [0, 0, 1]]: (1,0,0) -> (1, .3, 0) -> R -> (-.3, 1, 0) -> + t
    np.testing.assert_allclose(want[0, 0], [-0.3, 1, 1], atol=1e-6)
    tt = torch.tensor(t, dtype=torch.float64)
    got_t = linear_blend_skinning_torch(torch.tensor(rest), torch.tensor(keypoints), torch.tensor(weights), tt,
                                        scale=torch.tensor(sheared))
    np.testing.assert_allclose(got_t.numpy(), want, atol=1e-6)
    with pytest.raises(ValueError, match="scale"):
        linear_blend_skinning(rest, keypoints, weights, t, np.ones((1, 1, 3)))


# --- categories on the zoo ---------------------------------------------------------------------

def test_categories_are_inferred_on_the_zoo_and_on_renamed_copies(small_zoo):
    from mimicbench.schemas.shards import read_records

    chars = read_records(small_zoo, "characters")
    assert len({c.category for c in chars}) >= 5
    for c in chars:
        cat, evidence = infer_category(c.bone_names, c.parents, c.keypoints)
        assert cat == c.category, (c.character_id, evidence)
        upper = [n.upper().replace("LEFT", "L_").replace("RIGHT", "R_") if "/" not in n else n for n in c.bone_names]
        assert infer_category(upper, c.parents, c.keypoints)[0] == c.category, (c.character_id, upper[:8])
        opaque, ev = infer_category([f"n{i}" for i in range(c.num_joints)], c.parents, c.keypoints)
        assert opaque in (c.category, "unknown", "humanoid" if c.category == "apparel" else c.category), (c.character_id, ev)
    assert infer_category(["a", "b"], [-1, 0], np.array([[0, 0, 0], [0, 0, 1.0]]))[0] == "unknown"


def _biped_skeleton(style, arm_drop: float, upright: bool, tail: bool = True):
    """A two-legged skeleton by hand (Y up, +Z forward; hips 2 m high): names in ``style``
    (``blender`` ``Thigh.L`` or ``mixamo`` ``mixamorig:LeftUpLeg``), arms hanging from the chest
    down to ``arm_drop`` m above the ground, the body horizontal (head ahead of the hips) or
    upright (head above them), and a five-joint tail when ``tail``."""
    names, parents, points = [], [], []

    def add(name, parent, p):
        names.append(name)
        parents.append(-1 if parent is None else names.index(parent))
        points.append(p)

    mixamo = style == "mixamo"
    n = (lambda base, side="": f"mixamorig:{side}{base}") if mixamo else (lambda base, side="": base + (f".{side[0]}" if side else ""))
    spine = [(0, 2.1, 1.0), (0, 2.2, 1.6), (0, 2.5, 2.1), (0, 2.7, 2.6)] if not upright else \
        [(0, 2.6, 0), (0, 3.1, 0), (0, 3.4, 0), (0, 3.7, 0.1)]
    add(n("Hips"), None, (0, 2.0, 0))
    add(n("Spine"), n("Hips"), spine[0])
    add(n("Chest") if not mixamo else n("Spine1"), n("Spine"), spine[1])
    chest = names[-1]
    add(n("Neck"), chest, spine[2])
    add(n("Head"), n("Neck"), spine[3])
    if tail:
        prev = n("Hips")
        for i in range(1, 6):
            add(f"Tail.{i:03d}" if not mixamo else f"mixamorig:Tail{i}", prev, (0, 2.0 - 0.05 * i, -0.8 * i))
            prev = names[-1]
    for sign, side in ((1, "Left"), (-1, "Right")):
        x = 0.4 * sign
        leg = ["UpLeg", "Leg", "Foot", "ToeBase"] if mixamo else ["Thigh", "Shin", "Foot", "Toe"]
        for j, (base, p) in enumerate(zip(leg, [(x, 1.9, 0.1), (x, 1.0, 0.3), (x, 0.2, -0.1), (x, 0.0, 0.4)])):
            add(n(base, side), n("Hips") if j == 0 else n(leg[j - 1], side), p)
        arm = ["Arm", "ForeArm", "Hand"] if mixamo else ["UpperArm", "Forearm", "Hand"]
        top = spine[1][1] - 0.1
        for j, base in enumerate(arm):
            y = top - (top - arm_drop) * j / 2
            add(n(base, side), chest if j == 0 else n(arm[j - 1], side), (0.3 * sign, y, spine[1][2] + 0.15 * j))
    return names, np.array(parents), np.array(points, float)


@pytest.mark.parametrize("style", ["blender", "mixamo"])
def test_bipedal_dinosaurs_are_unknown_not_quadrupeds(style):
    """A T-rex or a velociraptor (two legs carrying a horizontal body, small arms, a tail) is not
    a quadruped, and nothing in its bones says reptile rather than bird-like biped: ``unknown``
    (a role-label file gives the category). Forelegs named as arms that come down to the ground
    (the Fox) keep it a quadruped; an upright body with the same small arms stays a humanoid."""
    table = [(dict(arm_drop=1.45, upright=False), "unknown", "arms off the ground"),
             (dict(arm_drop=0.0, upright=False), "quadruped", "forelegs named as arms"),
             (dict(arm_drop=1.45, upright=True), "humanoid", "upright"),
             (dict(arm_drop=1.45, upright=False, tail=False), "unknown", "arms off the ground")]
    for kwargs, want, rule in table:
        names, parents, points = _biped_skeleton(style, **kwargs)
        cat, ev = infer_category(names, parents, points)
        assert cat == want and rule in ev["rule"], (kwargs, ev)
        assert ev["legs"] == 2 and ev["arms"] == 2
    names, parents, points = _biped_skeleton(style, arm_drop=1.45, upright=False)
    assert infer_category(names, parents, points * 0.2)[0] == "unknown"  # a velociraptor-sized one


BVH_HEAD = """HIERARCHY
ROOT Hips
{
	OFFSET 0 100 0
	CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
	JOINT Spine
	{
		OFFSET 0 40 5
		CHANNELS 3 Zrotation Yrotation Xrotation
		End Site
		{
			OFFSET 0 30 0
		}
	}
	JOINT LeftLeg
	{
		OFFSET 10 -50 0
		CHANNELS 3 Zrotation Yrotation Xrotation
		End Site
		{
			OFFSET 0 -45 0
		}
	}
}
MOTION
Frames: 1
Frame Time: 0.033333
0 100 0 0 0 0 0 0 0 0 0 0
"""


def test_bvh_rest_height_and_auto_unit_by_hand(tmp_path):
    from mimicbench.datagen.ingest.bvh_units import auto_bvh_scale, bvh_rest_height

    path = tmp_path / "person.bvh"
    path.write_text(BVH_HEAD)
    # heads: hips 100, spine 140, spine end 170, leg 50, leg end 5 -> 170 - 5 = 165 units
    assert bvh_rest_height(path) == pytest.approx(165.0)
    assert auto_bvh_scale(165.0)[:2] == (0.01, "centimetres")
    assert auto_bvh_scale(1.65)[:2] == (1.0, "metres")
    assert auto_bvh_scale(24.0)[0] == pytest.approx(0.056444)  # CMU conversions: 0.24 m in cm, 24 m in metres
    assert auto_bvh_scale(1650.0)[:2] == (0.001, "millimetres")
    assert auto_bvh_scale(0.0) == (0.01, "centimetres", False)
    broken = tmp_path / "broken.bvh"
    broken.write_text(BVH_HEAD.replace("OFFSET 10 -50 0", "OFFSET 10 nan 0"))
    with pytest.raises(ValueError, match="three finite numbers"):
        bvh_rest_height(broken)
    (tmp_path / "not.bvh").write_text("MOTION\n")
    with pytest.raises(ValueError, match="HIERARCHY"):
        bvh_rest_height(tmp_path / "not.bvh")


def test_ingest_option_bvh_scale_accepts_auto_or_a_positive_number():
    from mimicbench.datagen.ingest.params import IngestParams

    IngestParams(bvh_scale="auto").check()
    IngestParams(bvh_scale=0.01).check()
    for bad in (0, -1.0, "cm"):
        with pytest.raises(ValueError, match="--bvh-scale"):
            IngestParams(bvh_scale=bad).check()
