"""Role-label files (datagen/roles): the format by hand-written examples, attaching to a dataset,
the shared assets' labels against the files' own bone names, no roles in a request, and the
conservative category inference."""
from __future__ import annotations

import dataclasses
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from mimicbench.datagen.correspond.roles import record_role_classes, role_classes
from mimicbench.datagen.ingest.category import infer_category
from mimicbench.datagen.roles.attach import attach_roles, carry_labels
from mimicbench.datagen.roles.labels import RoleLabelError, load_labels, parse_labels
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.validate import validate_dataset

REPO = Path(__file__).resolve().parents[1]
SHARED_LABELS = REPO / "examples" / "roles" / "shared_assets.toml"

ARM = ["Hips", "Spine", "Arm.L", "ForeArm.L", "Hand.L", "Arm.R", "Hair_01", "Hair_02", "Hair_03", "HairIK", "Tail"]


def _write(tmp_path, text: str, name: str = "labels.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- the format ---------------------------------------------------------------------------------

def test_names_globs_classes_and_exclusions_resolve_as_written(tmp_path):
    path = _write(tmp_path, '''
version = 1
[characters."assets/Toy"]
category = "humanoid"
[characters."assets/Toy".bones]
"Hair_*" = "apparel"
Hips = "hips"
"Arm.L" = "left/upper_arm"
"ForeArm.L" = "left/forelimb"
"Hand.L" = "left/forelimb"
"Arm.R" = "right/forelimb/1"
"Hair_02" = ""
"H*" = "head"
''')
    labels = load_labels(path)
    entry = labels.characters["assets/Toy"]
    assert entry.category == "humanoid"
    # exact names first; Hair_02's "" keeps the glob off it; "Hair_*" comes before "H*" in the file,
    # so the hair bones are apparel and only HairIK and Hips-like leftovers take "H*"; Spine and Tail
    # match nothing and have no role
    want = ["hips", "", "left/upper_arm", "left/forelimb", "left/forelimb", "right/forelimb/1",
            "apparel", "", "apparel", "head", ""]
    assert entry.roles_for(ARM) == want
    assert role_classes(want, "humanoid") == ["root", None, "left/forelimb", "left/forelimb", "left/forelimb",
                                              "right/forelimb", "apparel", None, "apparel", "head", None]
    # the same tree as JSON reads the same
    tree = {"version": 1, "characters": {"assets/Toy": {"category": "humanoid", "bones": dict(entry.bones)}}}
    j = load_labels(_write(tmp_path, json.dumps(tree), "labels.json"))
    assert j.characters["assets/Toy"].roles_for(ARM) == want


def test_a_bone_the_character_lacks_is_an_error_naming_it_and_close_names(tmp_path):
    entry = load_labels(_write(tmp_path, '''
[characters.Toy.bones]
"Forearm.L" = "left/forearm"
"Legg.*" = "left/hindlimb"
''')).characters["Toy"]
    with pytest.raises(RoleLabelError) as err:
        entry.roles_for(ARM, "assets/Toy")
    text = str(err.value)
    assert "'Forearm.L' is not a bone of assets/Toy" in text and "'ForeArm.L'" in text
    assert "glob 'Legg.*' matches no bone of assets/Toy" in text


@pytest.mark.parametrize("bones, message", [
    ('"Arm.L" = "upper_arm"', "needs a side"),
    ('"Arm.L" = "forelimb"', "needs a side"),
    ('Spine = "left/spine"', "takes no side"),
    ('Spine = "banana"', "neither a zoo role"),
    ('Spine = " spine"', "without spaces"),
    ('"Arm.L" = "left/upper_arm"\n"Arm.R" = "left/upper_arm"', "given to two bones"),
])
def test_bad_roles_are_errors(tmp_path, bones, message):
    path = _write(tmp_path, f"[characters.Toy.bones]\n{bones}\n")
    with pytest.raises(RoleLabelError, match=message):
        load_labels(path).characters["Toy"].roles_for(ARM)


@pytest.mark.parametrize("tree, message", [
    ({"characters": {"Toy": {"category": "dragon", "bones": {"Hips": "hips"}}}}, "category"),
    ({"characters": {"Toy": {"bones": {"Hips": "hips"}, "colour": 1}}}, "unknown key"),
    ({"version": 2, "characters": {"Toy": {"bones": {"Hips": "hips"}}}}, "version"),
    ({"characters": {}}, "non-empty"),
    ({"roles": {}}, "unknown key"),
])
def test_malformed_files_are_errors(tree, message):
    with pytest.raises(RoleLabelError, match=message):
        parse_labels(tree, "x.toml")


def test_role_classes_take_class_names_and_unlabelled_bones():
    roles = ["left/forelimb", "", None, "tail/3", "apparel", "right/hindlimb/2", "left/upper_arm", "dorsal", "left/ear"]
    assert role_classes(roles, "unknown") == ["left/forelimb", None, None, "tail", "apparel", "right/hindlimb",
                                              "left/forelimb", "dorsal", "left/ear"]
    rec = dataclasses.make_dataclass("R", ["bone_roles", "category"])
    assert record_role_classes(rec(["", ""], "fish")) is None and record_role_classes(rec(None, "fish")) is None
    assert record_role_classes(rec(["", "left/fin"], "fish")) == [None, "left/forelimb"]


def test_correspondence_report_ignores_unlabelled_bones():
    from mimicbench.datagen.correspond.report import pair_scores

    rec = dataclasses.make_dataclass("R", ["character_id", "bone_roles", "category"])
    a = rec("a", ["hips", "", "left/upper_arm"], "humanoid")
    b = rec("b", ["hips", "", "right/upper_arm"], "humanoid")
    s = pair_scores(a, b, np.array([[0, 0], [1, 1], [2, 2]]))
    assert s["agreement"] == 0.5  # hips right, the arms wrong, the unlabelled pair not counted
    assert s["matched"] == 1.0


# --- attaching to a dataset ---------------------------------------------------------------------

def _ingested_copy(rec, cid: str, category: str):
    """A zoo record made to look ingested (source a file, no roles, an inferred category)."""
    meta = {"category": {"value": category, "source": "inferred", "inferred": category, "evidence": {"rule": "r"}}}
    return dataclasses.replace(rec, character_id=cid, source=f"/assets/{cid.split('/')[1]}.glb", bone_roles=None,
                               category=category, meta=meta, split="train")


@pytest.fixture
def tiny(small_zoo, tmp_path):
    """A two-character dataset: a humanoid and a quadruped of the zoo as if ingested (no roles;
    the quadruped's category inferred ``unknown``), plus the zoo's own roles to compare with."""
    chars = {c.character_id: c for c in read_records(small_zoo, "characters")}
    hum, quad = chars["zoo/humanoid-0000"], chars["zoo/quadruped-0000"]
    root = tmp_path / "data"
    write_records(root, "characters", [_ingested_copy(hum, "assets/Biped", "humanoid"),
                                       _ingested_copy(quad, "assets/Dog", "unknown")], "train")
    return root, hum, quad


def _labels_for(rec, key: str, category: str | None = None) -> str:
    lines = [f'[characters."{key}"]'] + ([f'category = "{category}"'] if category else [])
    lines.append(f'[characters."{key}".bones]')
    lines += [f'"{n}" = "{r}"' for n, r in zip(rec.bone_names, rec.bone_roles)]
    return "\n".join(lines) + "\n"


def test_attach_round_trip_validates_and_stores_the_files_roles(tiny, tmp_path, capsys):
    root, hum, quad = tiny
    labels = _write(tmp_path, _labels_for(hum, "Biped") + _labels_for(quad, "assets/Dog", "quadruped")
                    + '[characters.Ghost.bones]\nHips = "hips"\n')
    from mimicbench.cli import main

    assert main(["datagen", "roles", str(root), "--labels", str(labels)]) == 0
    out, err = capsys.readouterr()
    assert "labelled 2 characters" in out and "without roles (no semantic score): 0" in out
    assert "'Ghost' is not in the dataset" in err
    assert validate_dataset(root) == []
    got = {c.character_id: c for c in read_records(root, "characters")}
    assert got["assets/Biped"].bone_roles == list(hum.bone_roles)
    assert got["assets/Dog"].bone_roles == list(quad.bone_roles)
    assert got["assets/Dog"].category == "quadruped"  # the file's category wins over the inferred unknown
    assert got["assets/Dog"].meta["category"] == {"value": "quadruped", "source": "labels", "file": str(labels),
                                                  "inferred": "unknown", "evidence": {"rule": "r"}}
    assert got["assets/Biped"].category == "humanoid" and got["assets/Biped"].meta["category"]["source"] == "inferred"
    assert got["assets/Biped"].meta["roles"]["labelled"] == hum.num_joints
    assert record_role_classes(got["assets/Dog"]) == role_classes(list(quad.bone_roles), "quadruped")
    # a second run with the same file changes nothing and writes nothing
    manifest = (root / "manifest.json").read_bytes()
    assert attach_roles(root, [labels])["written_splits"] == []
    assert (root / "manifest.json").read_bytes() == manifest


def test_labels_that_do_not_fit_write_nothing(tiny, tmp_path):
    root, hum, _ = tiny
    text = _labels_for(hum, "Biped").replace(f'"{hum.bone_names[3]}"', '"NoSuchBone"')
    before = (root / "manifest.json").read_bytes()
    with pytest.raises(RoleLabelError, match="'NoSuchBone' is not a bone of assets/Biped"):
        attach_roles(root, [_write(tmp_path, text)])
    assert (root / "manifest.json").read_bytes() == before
    # a zoo character cannot be relabelled
    zoo = read_records(tiny[0], "characters")[0]
    write_records(root, "characters", [dataclasses.replace(zoo, character_id="zoo/x", source="zoo:humanoid@1")],
                  "val")
    with pytest.raises(RoleLabelError, match="zoo character"):
        attach_roles(root, [_write(tmp_path, '[characters."zoo/x".bones]\nHips = "hips"\n', "z.toml")])


def test_a_killed_run_is_finished_by_a_rerun_and_another_stages_is_refused(tiny, tmp_path):
    from mimicbench.schemas.errors import DatasetError
    from mimicbench.schemas.manifest import is_complete, load_manifest, mark_complete, mark_incomplete

    root, hum, _ = tiny
    labels = _write(tmp_path, _labels_for(hum, "Biped"))
    attach_roles(root, [labels])
    mark_incomplete(root, "datagen roles")  # killed after writing its splits, before marking complete
    assert validate_dataset(root) != []
    attach_roles(root, [labels])
    assert is_complete(load_manifest(root)) and validate_dataset(root) == []
    mark_incomplete(root, "datagen ingest")
    with pytest.raises(DatasetError, match="datagen ingest .*did not finish"):
        attach_roles(root, [labels])
    mark_complete(root)


def test_unlabelled_characters_are_counted(tiny, tmp_path):
    root, hum, _ = tiny
    s = attach_roles(root, [_write(tmp_path, _labels_for(hum, "Biped"))])
    assert s["unlabelled"] == ["assets/Dog"] and list(s["labelled"]) == ["assets/Biped"]


def test_reingested_characters_keep_their_labels(tiny, tmp_path):
    root, hum, quad = tiny
    attach_roles(root, [_write(tmp_path, _labels_for(quad, "Dog", "quadruped"))])
    labelled = {c.character_id: c for c in read_records(root, "characters")}
    fresh = [_ingested_copy(quad, "assets/Dog", "unknown"), _ingested_copy(hum, "assets/Biped", "humanoid")]
    kept = {c.character_id: c for c in carry_labels(list(labelled.values()), fresh)}
    assert kept["assets/Dog"].bone_roles == list(quad.bone_roles) and kept["assets/Dog"].category == "quadruped"
    assert kept["assets/Biped"].bone_roles is None
    renamed = dataclasses.replace(fresh[0], bone_names=[n + "_x" for n in fresh[0].bone_names])
    assert carry_labels(list(labelled.values()), [renamed])[0].bone_roles is None  # other bones: labels dropped


def test_a_request_for_a_labelled_character_carries_no_roles(tiny, tmp_path):
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.request import Rig, TransferRequest

    root, hum, quad = tiny
    attach_roles(root, [_write(tmp_path, _labels_for(hum, "Biped") + _labels_for(quad, "Dog", "quadruped"))])
    data = EvalData.load(root)
    src, tgt = data.characters["assets/Biped"], data.characters["assets/Dog"]
    assert src.record.bone_roles == list(hum.bone_roles)  # the ground truth is there ...
    req = data.request(src, src.rig.vertices, tgt, "case")
    assert isinstance(req, TransferRequest) and "hidden_roles" not in req.extras  # ... and not in the request
    fields = {f.name for f in dataclasses.fields(Rig)} | {f.name for f in dataclasses.fields(TransferRequest)}
    assert not any("role" in f for f in fields)
    strings = set()

    def walk(x):  # every string the request holds, through its dataclasses, tuples, lists and dicts
        if isinstance(x, str):
            strings.add(x)
        elif dataclasses.is_dataclass(x):
            for f in dataclasses.fields(x):
                walk(getattr(x, f.name))
        elif isinstance(x, (list, tuple)):
            for v in x:
                walk(v)
        elif isinstance(x, dict):
            for k, v in x.items():
                walk(k), walk(v)

    walk(req)
    sided = {r for r in list(hum.bone_roles) + list(quad.bone_roles) if "/" in r}  # no bone is named like these
    assert len(sided) > 20 and not sided & strings


# --- the shared assets' labels ------------------------------------------------------------------

def _glb_joint_names(path: Path) -> list[str]:
    """Joint node names of every skin of a GLB, read from its JSON chunk (glTF 2.0 spec)."""
    data = path.read_bytes()
    length, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    gltf = json.loads(data[20:20 + length])
    names = [gltf["nodes"][j].get("name", "") for skin in gltf.get("skins", []) for j in skin["joints"]]
    return list(dict.fromkeys(names))


def _bvh_joint_names(path: Path) -> list[str]:
    head = path.read_text().split("MOTION")[0]
    return re.findall(r"^\s*(?:ROOT|JOINT)\s+(\S+)", head, flags=re.M)


def test_shared_labels_fit_the_shared_assets_bone_names(assets_dir):
    import mmd_bone_tools

    names = {p.stem: _glb_joint_names(p) for p in sorted((assets_dir / "glb").glob("*.glb"))}
    names.update({p.stem: _bvh_joint_names(p) for p in sorted((assets_dir / "bvh").glob("*.bvh"))})
    names["Gene"] = [b.name for b in mmd_bone_tools.load_model(str(assets_dir / "mmd" / "Gene.pmx")).bones]
    labels = load_labels(SHARED_LABELS)
    assert sorted(labels.characters) == sorted(names)  # every shared asset labelled, nothing else
    counts = {}
    for stem, entry in labels.characters.items():
        roles = entry.roles_for(names[stem], stem)
        classes = role_classes(roles, entry.category)
        counts[stem] = sum(bool(r) for r in roles)
        assert entry.category is not None
        sides = {c.split("/")[0] for c in classes if c and "/" in c}
        assert sides == {"left", "right"}, stem
    assert counts["Gene"] == 206 and counts["Fox"] == 22 and counts["CesiumMan"] == 19
    assert counts["Quaternius_Horse"] == 45 and counts["CMU_02_01"] == 31


@pytest.mark.slow
def test_shared_labels_attach_to_ingested_shared_assets(assets_dir, tmp_path):
    """Every shared asset through ingest (Blender; MMD without) with --roles: validate passes and
    every character has the file's category and roles."""
    from mimicbench.cli import main

    out = tmp_path / "assets"
    args = ["datagen", "ingest", str(assets_dir / "glb"), str(assets_dir / "bvh"), str(assets_dir / "mmd" / "Gene.pmx"),
            "--out", str(out), "--quiet", "--roles", str(SHARED_LABELS)]
    assert main(args) == 0
    assert validate_dataset(out) == []
    labels = load_labels(SHARED_LABELS)
    chars = read_records(out, "characters")
    assert len(chars) == 14
    for c in chars:
        entry = labels.characters[Path(c.source).stem]
        assert c.category == entry.category and c.meta["category"]["source"] == "labels"
        assert c.bone_roles == entry.roles_for(list(c.bone_names))


# --- conservative category inference ------------------------------------------------------------

def _skeleton(spec):
    """Names, parents and points from ``[(name, parent name or None, (x, y, z)), ...]``."""
    names = [n for n, _, _ in spec]
    parents = np.array([-1 if p is None else names.index(p) for _, p, _ in spec])
    return names, parents, np.array([pt for _, _, pt in spec], float)


def _chain(prefix_names, parent, points):
    out, prev = [], parent
    for n, p in zip(prefix_names, points):
        out.append((n, prev, p))
        prev = n
    return out


def test_a_biped_dinosaur_without_arms_is_unknown():
    spec = [("Hips", None, (0, 2, 0)), ("Spine", "Hips", (0, 2.1, 1)), ("Neck", "Spine", (0, 2.4, 2)),
            ("Head", "Neck", (0, 2.6, 2.6))]
    spec += _chain([f"Tail.{i}" for i in range(1, 6)], "Hips", [(0, 2 - 0.05 * i, -0.8 * i) for i in range(1, 6)])
    for s, x in (("L", 0.4), ("R", -0.4)):
        spec += _chain([f"Thigh.{s}", f"Shin.{s}", f"Foot.{s}", f"Toe.{s}"], "Hips",
                       [(x, 1.9, 0.1), (x, 1.0, 0.3), (x, 0.2, -0.1), (x, 0.0, 0.4)])
    cat, ev = infer_category(*_skeleton(spec))
    assert cat == "unknown" and ev["legs"] == 2 and ev["arms"] == 0 and ev["tail"]


def test_a_six_legged_insect_named_like_a_bird_is_unknown():
    """Wings and legs ``Leg1.L``, ``Leg2.L``, ``Leg3.L`` on the thorax: one leg by name on each
    side, three chains; a wasp, not a bird."""
    spec = [("Thorax", None, (0, 1, 0)), ("Head", "Thorax", (0, 1, 0.5)), ("Abdomen", "Thorax", (0, 1, -0.6))]
    for s, x in (("L", 1), ("R", -1)):
        spec += _chain([f"Wing1.{s}", f"Wing2.{s}"], "Thorax", [(0.2 * x, 1.2, 0), (0.8 * x, 1.3, 0)])
        for i, z in enumerate((0.3, 0.0, -0.3), start=1):
            spec += _chain([f"Leg{i}.{s}", f"Leg{i}_end.{s}"], "Thorax", [(0.2 * x, 0.9, z), (0.6 * x, 0.0, z)])
    cat, ev = infer_category(*_skeleton(spec))
    assert cat == "unknown" and ev["wings"] == 2 and ev["leg_chains"] == {"left": 3, "right": 3}, ev


def test_arms_named_as_front_legs_that_do_not_reach_the_ground_are_unknown():
    spec = [("Hips", None, (0, 2, 0)), ("Chest", "Hips", (0, 2.1, 1)), ("Head", "Chest", (0, 2.5, 2))]
    for s, x in (("L", 0.4), ("R", -0.4)):
        spec += _chain([f"BackLeg.{s}", f"BackShin.{s}", f"BackFoot.{s}"], "Hips",
                       [(x, 1.9, 0), (x, 1.0, 0.2), (x, 0.0, 0.1)])
        spec += _chain([f"FrontLeg.{s}", f"FrontLowLeg.{s}"], "Chest", [(x / 2, 1.9, 1.1), (x / 2, 1.5, 1.3)])
    cat, ev = infer_category(*_skeleton(spec))
    assert cat == "unknown" and ev["legs"] == 4 and ev["legs_reach_ground"] is False


def test_clear_humanoid_quadruped_and_bird_rigs_keep_their_category():
    hum = [("mixamorig:Hips", None, (0, 1, 0)), ("mixamorig:Spine", "mixamorig:Hips", (0, 1.2, 0)),
           ("mixamorig:Neck", "mixamorig:Spine", (0, 1.5, 0)), ("mixamorig:Head", "mixamorig:Neck", (0, 1.6, 0))]
    for s, x in (("Left", 1), ("Right", -1)):
        hum += _chain([f"mixamorig:{s}Arm", f"mixamorig:{s}ForeArm", f"mixamorig:{s}Hand"], "mixamorig:Spine",
                      [(0.2 * x, 1.45, 0), (0.5 * x, 1.45, 0), (0.75 * x, 1.45, 0)])
        hum += _chain([f"mixamorig:{s}UpLeg", f"mixamorig:{s}Leg", f"mixamorig:{s}Foot"], "mixamorig:Hips",
                      [(0.1 * x, 0.95, 0), (0.1 * x, 0.5, 0), (0.1 * x, 0.05, 0)])
    assert infer_category(*_skeleton(hum))[0] == "humanoid"
    # a quadruped whose hooves are IK bones without a parent (as Quaternius rigs have)
    quad = [("Back", None, (0, 1.5, -1)), ("Torso", "Back", (0, 1.5, 0)), ("Head", "Torso", (0, 2, 1.2))]
    for s, x in (("L", 0.3), ("R", -0.3)):
        quad += _chain([f"FrontUpperLeg.{s}", f"FrontLowerLeg.{s}"], "Torso", [(x, 1.4, 0.8), (x, 1.0, 0.7)])
        quad += [(f"IKFrontLeg.{s}", None, (x, 0.2, 0.9))]
        quad += _chain([f"BackUpperLeg.{s}", f"BackLowerLeg.{s}"], "Back", [(x, 1.4, -1), (x, 0.6, -1.2)])
        quad += [(f"IKBackLeg.{s}", None, (x, 0.2, -0.9))]
    cat, ev = infer_category(*_skeleton(quad))
    assert cat == "quadruped" and ev["legs_reach_ground"], ev
    bird = [("Hips", None, (0, 1, 0)), ("Neck", "Hips", (0, 1.3, 0.3)), ("Head", "Neck", (0, 1.5, 0.4))]
    for s, x in (("L", 1), ("R", -1)):
        bird += _chain([f"Wing1.{s}", f"Wing2.{s}"], "Hips", [(0.2 * x, 1.1, 0), (0.7 * x, 1.1, 0)])
        bird += _chain([f"Leg1.{s}", f"Leg2.{s}"], "Hips", [(0.1 * x, 0.8, 0), (0.1 * x, 0.0, 0)])
    assert infer_category(*_skeleton(bird))[0] == "bird"


def test_a_snake_whose_root_branches_into_body_and_tail_is_a_reptile():
    """No limbs, a flat body: 20 spine joints to the head (jaw, three tongue joints, two eyes) and 15
    tail joints, both from the root. No single chain covers half the joints; the path from the
    tail's tip to the tongue's does (40 of 43)."""
    spec = [("Root", None, (0, 0.1, 0))]
    spec += _chain([f"Spine{i}" for i in range(20)], "Root", [(0.05 * np.sin(i), 0.1, 0.1 * (i + 1)) for i in range(20)])
    spec += [("Head", "Spine19", (0, 0.12, 2.1)), ("Jaw", "Head", (0, 0.08, 2.2)),
             ("Eye.L", "Head", (0.03, 0.15, 2.15)), ("Eye.R", "Head", (-0.03, 0.15, 2.15))]
    spec += _chain([f"Tongue{i}" for i in range(3)], "Head", [(0, 0.1, 2.2 + 0.05 * i) for i in range(3)])
    spec += _chain([f"Tail{i}" for i in range(15)], "Root", [(0.05 * np.cos(i), 0.1, -0.1 * (i + 1)) for i in range(15)])
    cat, ev = infer_category(*_skeleton(spec))
    assert cat == "reptile" and ev["longest_path"] == 40 and ev["longest_chain"] == 21, ev
