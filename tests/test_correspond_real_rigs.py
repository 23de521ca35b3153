"""Correspondences between real artist rigs, against bone pairs labelled by hand.

Skeletons are read here from the files themselves, independently of the ingest stage: a GLB is
a 12-byte header, then a chunk header (length, type) and the glTF JSON, whose nodes give names,
children and local transforms (joint rest positions are the composed node transforms, glTF 2.0
section 3.5.3); a BVH's HIERARCHY gives names and offsets; the PMX is read with mmd-bone-tools
(a second parser), its left-handed z mirrored.

The labels (:data:`LABELLED`) were written by looking at each rig's bone names, parents and rest
positions: the same limb segment, the same trunk bone. Where a chain has no clear counterpart
(a horse's hip bone against a fox's), nothing is labelled.
"""
from __future__ import annotations

import itertools
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from mimicbench.datagen.correspond.pair import correspondence_for_skeletons
from tests.correspond_rig_tables import RIG_TABLES, table_rig


def _quat_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _local(node) -> np.ndarray:
    if "matrix" in node:
        return np.array(node["matrix"], float).reshape(4, 4).T  # column-major in glTF
    m = np.eye(4)
    m[:3, :3] = _quat_matrix(node.get("rotation", [0, 0, 0, 1])) * np.array(node.get("scale", [1, 1, 1]), float)
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def glb_skeleton(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Joint names, parents (K,) and rest positions (K, 3) of every skin joint of a GLB."""
    data = path.read_bytes()
    magic, _, _ = struct.unpack("<4sII", data[:12])
    length, kind = struct.unpack("<I4s", data[12:20])
    assert magic == b"glTF" and kind == b"JSON", path
    doc = json.loads(data[20:20 + length])
    nodes = doc["nodes"]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    world: dict[int, np.ndarray] = {}

    def to_world(i: int) -> np.ndarray:
        if i not in world:
            p = parent.get(i)
            world[i] = (to_world(p) if p is not None else np.eye(4)) @ _local(nodes[i])
        return world[i]

    joints = sorted({j for skin in doc.get("skins", []) for j in skin["joints"]})
    index = {j: k for k, j in enumerate(joints)}
    parents = []
    for j in joints:
        p = parent.get(j)
        while p is not None and p not in index:
            p = parent.get(p)
        parents.append(index[p] if p is not None else -1)
    return ([nodes[j].get("name", f"node{j}") for j in joints], np.array(parents),
            np.array([to_world(j)[:3, 3] for j in joints]))


def bvh_skeleton(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Joint names, parents and rest positions (summed OFFSETs) of a BVH hierarchy."""
    names, parents, positions, stack = [], [], [], []
    pending = None
    for line in path.read_text().split("MOTION")[0].splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] in ("ROOT", "JOINT"):
            pending = words[1]
        elif words[0] == "End":
            pending = "<end>"
        elif words[0] == "{":
            stack.append(pending)
        elif words[0] == "OFFSET" and stack[-1] != "<end>":
            parent = next((names.index(n) for n in reversed(stack[:-1]) if n != "<end>"), -1)
            offset = np.array([float(w) for w in words[1:4]])
            names.append(stack[-1])
            parents.append(parent)
            positions.append(offset + (positions[parent] if parent >= 0 else 0.0))
        elif words[0] == "}":
            stack.pop()
    return names, np.array(parents), np.array(positions)


def pmx_skeleton(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Bone names, parents and rest positions of a PMX (mmd-bone-tools' reader; z mirrored)."""
    from mmd_bone_tools import load_model

    bones = load_model(str(path)).bones
    pos = np.array([b.position for b in bones], float) * np.array([1.0, 1.0, -1.0])
    return [b.name for b in bones], np.array([b.parent for b in bones]), pos


def load_rig(assets_dir: Path, name: str):
    if name in RIG_TABLES:
        return table_rig(name)
    if name == "CMU_02_01":
        return bvh_skeleton(assets_dir / "bvh" / "CMU_02_01.bvh")
    if name == "Gene":
        return pmx_skeleton(assets_dir / "mmd" / "Gene.pmx")
    return glb_skeleton(assets_dir / "glb" / f"{name}.glb")


def _sides(pairs):
    """Expand ``{s}`` to the two sides in each rig's own spelling (``{L}``/``{R}`` for a letter)."""
    out = []
    for a, b in pairs:
        if "{" not in a + b:
            out.append((a, b))
            continue
        for left in (True, False):
            sub = {"s": "L" if left else "R", "side": "Left" if left else "Right", "j": "左" if left else "右",
                   "c": "L" if left else "R"}
            out.append((a.format(**sub), b.format(**sub)))
    return out


QUADRUPED_SHARED = ["Body", "Back", "Torso", "Torso2", "Torso3", "Neck1", "Neck2", "Neck3", "Head", "Tail1", "Tail2",
                    "Tail3", "Tail4", "Tail5", "Tail6"] + [f"{p}.{s}" for p in (
                        "FrontShoulder", "FrontUpperLeg", "FrontLowerLeg", "BackShoulder", "BackLeg", "BackUpperLeg",
                        "BackLowerLeg", "Ear1", "Ear2", "Ear3", "Ear4") for s in "LR"]
DINO = ["root", "Body", "Back", "Tail1", "Tail2", "Tail3", "Tail4", "Tail5", "Hips", "Torso", "Shoulders", "Neck",
        "Head"] + [f"{p}.{s}" for p in ("BackLeg", "BackUpLeg", "BackLowLeg", "FrontLeg", "FrontUpLeg", "FrontLowLeg",
                                         "BackFoot", "FrontFoot") for s in "LR"]
FLIPPERS = ["Root", "Spine1", "Spine2", "Spine3", "Spine4", "Tail", "Head"] + [
    f"{p}Flipper.{s}" for p in ("Top", "Mid", "Bottom") for s in "LR"]

# (source rig, target rig): [(source bone, target bone), ...] labelled by hand
LABELLED = {
    ("Quaternius_Horse", "Quaternius_Husky"): [(n, n) for n in QUADRUPED_SHARED],
    ("Quaternius_Stegosaurus", "Quaternius_Triceratops"): [(n, n) for n in DINO],
    ("Quaternius_Dolphin", "Quaternius_MantaRay"): [(n, n) for n in FLIPPERS],
    ("CesiumMan", "RobotExpressive"): [
        ("Skeleton_arm_joint_R", "ShoulderR"), ("Skeleton_arm_joint_R__2_", "UpperArmR"),
        ("Skeleton_arm_joint_R__3_", "LowerArmR"), ("Skeleton_arm_joint_L__4_", "ShoulderL"),
        ("Skeleton_arm_joint_L__3_", "UpperArmL"), ("Skeleton_arm_joint_L__2_", "LowerArmL"),
        ("leg_joint_R_1", "UpperLegR"), ("leg_joint_R_2", "LowerLegR"), ("leg_joint_L_1", "UpperLegL"),
        ("leg_joint_L_2", "LowerLegL"), ("Skeleton_neck_joint_1", "Neck")],
    ("CMU_02_01", "Quaternius_Farmer"): _sides([
        ("Hips", "Hips"), ("Head", "Head"), ("{side}UpLeg", "UpperLeg.{s}"), ("{side}Leg", "LowerLeg.{s}"),
        ("{side}Foot", "Foot.{s}"), ("{side}Shoulder", "Shoulder.{s}"), ("{side}Arm", "UpperArm.{s}"),
        ("{side}ForeArm", "LowerArm.{s}"), ("{side}Hand", "Hand.{s}")]),
    ("Gene", "Quaternius_Farmer"): _sides([
        ("首", "Neck"), ("頭", "Head"), ("{j}肩", "Shoulder.{s}"), ("{j}腕", "UpperArm.{s}"),
        ("{j}ひじ", "LowerArm.{s}"), ("{j}手首", "Hand.{s}"), ("{j}足", "UpperLeg.{s}"), ("{j}ひざ", "LowerLeg.{s}"),
        ("{j}足首", "Foot.{s}")]),
    # Quaternius horse and husky hind legs: BackShoulder is a short hip connector, BackLeg the
    # femur (hip to stifle), BackUpperLeg the tibia (stifle to hock); the rat's and the dinosaurs'
    # BackLeg is the connector and BackUpLeg the femur. Labels follow the bones, not the words.
    ("Quaternius_Farmer", "Quaternius_Horse"): _sides([
        ("Head", "Head"), ("Neck", "Neck1"), ("Shoulder.{s}", "FrontShoulder.{s}"),
        ("UpperArm.{s}", "FrontUpperLeg.{s}"), ("LowerArm.{s}", "FrontLowerLeg.{s}"),
        ("UpperLeg.{s}", "BackLeg.{s}"), ("LowerLeg.{s}", "BackUpperLeg.{s}")]),
    ("Quaternius_Farmer", "Quaternius_Stegosaurus"): _sides([
        ("Head", "Head"), ("Neck", "Neck"), ("Shoulder.{s}", "FrontLeg.{s}"), ("UpperArm.{s}", "FrontUpLeg.{s}"),
        ("LowerArm.{s}", "FrontLowLeg.{s}"), ("UpperLeg.{s}", "BackUpLeg.{s}"), ("LowerLeg.{s}", "BackLowLeg.{s}")]),
    ("Fox", "Quaternius_Husky"): [
        ("b_Head_05", "Head"), ("b_Tail01_012", "Tail1"), ("b_Tail02_013", "Tail2"), ("b_Tail03_014", "Tail3"),
        ("b_LeftUpperArm_09", "FrontUpperLeg.L"), ("b_LeftForeArm_010", "FrontLowerLeg.L"),
        ("b_RightUpperArm_06", "FrontUpperLeg.R"), ("b_RightForeArm_07", "FrontLowerLeg.R"),
        ("b_LeftLeg01_015", "BackLeg.L"), ("b_LeftLeg02_016", "BackUpperLeg.L"), ("b_LeftFoot01_017", "BackLowerLeg.L"),
        ("b_RightLeg01_019", "BackLeg.R"), ("b_RightLeg02_020", "BackUpperLeg.R"),
        ("b_RightFoot01_021", "BackLowerLeg.R")],
    ("Quaternius_Rat", "Quaternius_Horse"): _sides([
        ("Head", "Head"), ("Tail1", "Tail1"), ("Tail2", "Tail2"), ("FrontLeg.{s}", "FrontShoulder.{s}"),
        ("FrontUpLeg.{s}", "FrontUpperLeg.{s}"), ("FrontLowLeg.{s}", "FrontLowerLeg.{s}"),
        ("BackLeg.{s}", "BackShoulder.{s}"), ("BackUpLeg.{s}", "BackLeg.{s}"), ("BackLowLeg.{s}", "BackUpperLeg.{s}")]),
}

# Pairs across kinds on rigs the method was never tuned on before (tables in
# tests/correspond_rig_tables.py, and the CMU mocap skeleton). Labels follow the bones (their
# rest positions and parents), not the words: a Quaternius animal's BackLeg runs hip to stifle
# (the femur, under the short BackShoulder connector), its BackUpperLeg stifle to hock, its
# BackLowerLeg hock to paw; a dinosaur's BackLeg is the connector. A mech's MidLeg is the shin of
# its three-segment leg. Foot.L of the knight and the mechs is an IK root at the foot: the foot.
#
# The split was fixed at 23:58 UTC on 1 Dec 2026, before any tuning: TUNED (the issue's failures
# and two more) may be looked at while choosing rules and weights; HELD_OUT was labelled from the
# tables alone and its agreement is only reported, never used to choose anything.
TUNED = {
    ("CMU_02_01", "Quaternius_MechGeorge"): _sides([  # mocap -> robot
        ("Hips", "Body"), ("LowerBack", "Torso"), ("Spine1", "Chest"), ("Neck", "Neck"), ("Head", "Head"),
        ("{side}UpLeg", "UpperLeg.{s}"), ("{side}Leg", "MidLeg.{s}"), ("{side}Foot", "Foot.{s}"),
        ("{side}Shoulder", "Shoulder.{s}"), ("{side}Arm", "UpperArm.{s}"), ("{side}ForeArm", "LowerArm.{s}")]),
    ("Quaternius_Knight", "Quaternius_MechGeorge"): _sides([  # humanoid -> robot
        ("Body", "Body"), ("Abdomen", "Torso"), ("Torso", "Chest"), ("Neck", "Neck"), ("Head", "Head"),
        ("Shoulder.{s}", "Shoulder.{s}"), ("UpperArm.{s}", "UpperArm.{s}"), ("LowerArm.{s}", "LowerArm.{s}"),
        ("UpperLeg.{s}", "UpperLeg.{s}"), ("LowerLeg.{s}", "MidLeg.{s}"), ("Foot.{s}", "Foot.{s}")]),
    ("CMU_02_01", "Quaternius_Soldier"): _sides([  # mocap -> game rig
        ("Hips", "Hips"), ("LowerBack", "Abdomen"), ("Spine", "Torso"), ("Spine1", "Chest"), ("Neck", "Neck"),
        ("Head", "Head"), ("{side}UpLeg", "UpperLeg.{s}"), ("{side}Leg", "LowerLeg.{s}"), ("{side}Foot", "Foot.{s}"),
        ("{side}Shoulder", "Shoulder.{s}"), ("{side}Arm", "UpperArm.{s}"), ("{side}ForeArm", "LowerArm.{s}"),
        ("{side}Hand", "Hand.{s}"), ("{side}HandIndex1", "Index1.{s}"), ("{c}Thumb", "Thumb1.{s}")]),
    ("Quaternius_MechGeorge", "Quaternius_Wolf"): _sides([  # robot -> quadruped
        ("Body", "Back"), ("Neck", "Neck1"), ("Head", "Head"), ("Shoulder.{s}", "FrontShoulder.{s}"),
        ("UpperArm.{s}", "FrontUpperLeg.{s}"), ("LowerArm.{s}", "FrontLowerLeg.{s}"), ("UpperLeg.{s}", "BackLeg.{s}"),
        ("MidLeg.{s}", "BackUpperLeg.{s}"), ("LowerLeg.{s}", "BackLowerLeg.{s}")]),
    ("Quaternius_Soldier", "Quaternius_Stag"): _sides([  # humanoid -> quadruped
        ("Hips", "Back"), ("Neck", "Neck1"), ("Head", "Head"), ("Shoulder.{s}", "FrontShoulder.{s}"),
        ("UpperArm.{s}", "FrontUpperLeg.{s}"), ("LowerArm.{s}", "FrontLowerLeg.{s}"), ("UpperLeg.{s}", "BackLeg.{s}"),
        ("LowerLeg.{s}", "BackUpperLeg.{s}"), ("Foot.{s}", "BackLowerLeg.{s}")]),
    ("Quaternius_Wolf", "Quaternius_Wasp"): _sides([  # quadruped -> winged insect
        ("Head", "Head"), ("Tail1", "Abdomen"), ("Tail2", "Abdomen2"), ("Tail3", "Abdomen3"),
        ("FrontShoulder.{s}", "TopLeg1.{s}"), ("FrontUpperLeg.{s}", "TopLeg2.{s}"), ("FrontLowerLeg.{s}", "TopLeg3.{s}"),
        ("BackShoulder.{s}", "BottomLeg1.{s}"), ("BackLeg.{s}", "BottomLeg2.{s}"),
        ("BackUpperLeg.{s}", "BottomLeg3.{s}")]),
}
HELD_OUT = {
    ("Quaternius_AstronautFlamingo", "Quaternius_MechStan"): _sides([  # humanoid -> robot
        ("Body", "Body"), ("Abdomen", "Torso"), ("Torso", "Chest"), ("Neck", "Neck"), ("Head", "Head"),
        ("Shoulder.{s}", "Shoulder.{s}"), ("UpperArm.{s}", "UpperArm.{s}"), ("LowerArm.{s}", "LowerArm.{s}"),
        ("Index1.{s}", "Index1.{s}"), ("Pinky1.{s}", "Pinky1.{s}"), ("Thumb1.{s}", "Thumb1.{s}"),
        ("UpperLeg.{s}", "UpperLeg.{s}"), ("LowerLeg.{s}", "LowerLeg.{s}"), ("Foot.{s}", "Foot.{s}")]),
    ("Quaternius_PlatformerCharacter", "Quaternius_Alpaca"): _sides([  # humanoid -> quadruped
        ("Body", "Back"), ("Neck", "Neck1"), ("Head", "Head"), ("Shoulder.{s}", "FrontShoulder.{s}"),
        ("UpperArm.{s}", "FrontUpperLeg.{s}"), ("LowerArm.{s}", "FrontLowerLeg.{s}"), ("UpperLeg.{s}", "BackLeg.{s}"),
        ("LowerLeg.{s}", "BackUpperLeg.{s}"), ("Ear1.{s}", "Ear1.{s}"), ("Ear2.{s}", "Ear2.{s}"),
        ("Ear3.{s}", "Ear3.{s}")]),
    ("Quaternius_MechMike", "Quaternius_Deer"): _sides([  # robot -> quadruped
        ("Body", "Back"), ("Neck", "Neck1"), ("Head", "Head"), ("Shoulder.{s}", "FrontShoulder.{s}"),
        ("UpperArm.{s}", "FrontUpperLeg.{s}"), ("LowerArm.{s}", "FrontLowerLeg.{s}"), ("UpperLeg.{s}", "BackLeg.{s}"),
        ("LowerLeg.{s}", "BackUpperLeg.{s}")]),
    ("Quaternius_Parasaurolophus", "Quaternius_Wasp"): _sides([  # quadruped -> winged insect
        ("Head", "Head"), ("Tail1", "Abdomen"), ("Tail2", "Abdomen2"), ("Tail3", "Abdomen3"),
        ("FrontLeg.{s}", "TopLeg1.{s}"), ("FrontUpLeg.{s}", "TopLeg2.{s}"), ("FrontLowLeg.{s}", "TopLeg3.{s}"),
        ("BackLeg.{s}", "BottomLeg1.{s}"), ("BackUpLeg.{s}", "BottomLeg2.{s}"), ("BackLowLeg.{s}", "BottomLeg3.{s}")]),
    ("CMU_02_01", "Quaternius_PlatformerCharacter"): _sides([  # mocap -> game rig
        ("Hips", "Body"), ("Spine1", "Torso"), ("Neck", "Neck"), ("Head", "Head"), ("{side}Shoulder", "Shoulder.{s}"),
        ("{side}Arm", "UpperArm.{s}"), ("{side}ForeArm", "LowerArm.{s}"), ("{side}Hand", "Fist.{s}"),
        ("{side}UpLeg", "UpperLeg.{s}"), ("{side}Leg", "LowerLeg.{s}"), ("{side}Foot", "Foot.{s}")]),
    ("Quaternius_Donkey", "Quaternius_Velociraptor"): _sides([  # quadruped -> biped dinosaur
        ("Head", "Head"), ("Neck1", "Neck"), ("Tail1", "Tail1"), ("Tail2", "Tail2"), ("Tail3", "Tail3"),
        ("FrontShoulder.{s}", "FrontLeg.{s}"), ("FrontUpperLeg.{s}", "FrontUpLeg.{s}"),
        ("FrontLowerLeg.{s}", "FrontLowLeg.{s}"), ("BackShoulder.{s}", "BackLeg.{s}"), ("BackLeg.{s}", "BackUpLeg.{s}"),
        ("BackUpperLeg.{s}", "BackLowLeg.{s}")]),
}


@pytest.fixture(scope="module")
def rigs(assets_dir):
    names = {n for labels in (LABELLED, TUNED, HELD_OUT) for pair in labels for n in pair}
    return {n: load_rig(assets_dir, n) for n in names}


def _labelled_hits(rigs, method, labelled=LABELLED):
    """Share of labelled bones matched as labelled, over ``labelled`` and per pair, and the dropped
    labelled source bones (left unmatched) per pair."""
    hits, per_pair, dropped = 0, {}, {}
    for (src, tgt), labels in labelled.items():
        na, pa, ka = rigs[src]
        nb, pb, kb = rigs[tgt]
        _, h, m = correspondence_for_skeletons(na, pa, ka, nb, pb, kb, method=method)
        got = {na[i]: nb[j] for i, j in h}
        ok = sum(got.get(a) == b for a, b in labels)
        per_pair[(src, tgt)] = ok / len(labels)
        dropped[(src, tgt)] = [a for a, _ in labels if a not in got]
        hits += ok
        assert m.shape == (len(na), len(nb)) and np.all(m.sum(1) <= 1 + 1e-4)
    return hits / sum(len(v) for v in labelled.values()), per_pair, dropped


def _match(rigs, src, tgt, method="structure"):
    na, pa, ka = rigs[src]
    nb, pb, kb = rigs[tgt]
    _, h, _ = correspondence_for_skeletons(na, pa, ka, nb, pb, kb, method=method)
    return {na[i]: nb[j] for i, j in h}


def test_readers_agree_with_the_files(rigs):
    names, parents, pos = rigs["CMU_02_01"]
    assert len(names) == 31 and names[:3] == ["Hips", "LHipJoint", "LeftUpLeg"] and parents[2] == 1
    np.testing.assert_allclose(pos[2], [1.36306, -1.79463, 0.83929])  # the BVH's OFFSET of LeftUpLeg
    names, parents, _ = rigs["Quaternius_Horse"]
    assert len(names) == 50 and names[parents[names.index("BackLeg.L")]] == "BackShoulder.L"
    names, parents, _ = rigs["Gene"]
    assert len(names) == 224 and names[parents[names.index("左ひじ")]] == "左腕捩"
    for name, (n, p, k) in rigs.items():
        assert len(n) == len(p) == len(k) and np.isfinite(k).all() and (p < len(n)).all(), name
    for (src, tgt), labels in {**LABELLED, **TUNED, **HELD_OUT}.items():  # every label names real bones
        assert all(a in rigs[src][0] and b in rigs[tgt][0] for a, b in labels), (src, tgt)
        assert len({a for a, _ in labels}) == len(labels), (src, tgt)  # one label a source bone
    assert not set(TUNED) & set(HELD_OUT) and not set(LABELLED) & set(HELD_OUT)
    names, parents, pos = rigs["Quaternius_MechGeorge"]  # a table: parents by name, heads as read
    assert names[parents[names.index("MidLeg.L")]] == "UpperLeg.L" and parents[names.index("Foot.L")] == -1
    np.testing.assert_allclose(pos[names.index("Head")], [0.072, 4.917, -0.083])


def test_structure_method_matches_hand_labelled_real_rig_bones(rigs):
    structure, per_pair, _ = _labelled_hits(rigs, "structure")
    text, text_per_pair, _ = _labelled_hits(rigs, "text")
    print(f"\nhand-labelled real-rig bones matched as labelled: structure {structure:.1%}, text {text:.1%}")
    for key in per_pair:
        print(f"  {key[0]:24s} -> {key[1]:24s} structure {per_pair[key]:5.0%}  text {text_per_pair[key]:5.0%}")
    assert structure >= 0.9
    assert structure > text
    # identical skeletons match bone for bone
    assert per_pair[("Quaternius_Stegosaurus", "Quaternius_Triceratops")] == pytest.approx(1.0)
    # a humanoid's arms go to the front legs, its legs to the hind legs (the issue's failures)
    assert per_pair[("Quaternius_Farmer", "Quaternius_Horse")] >= 0.9


@pytest.mark.parametrize("split", ["tuned", "held_out"])
def test_agreement_on_new_rig_pairs_across_kinds(rigs, split):
    """The issue's bar on pairs across kinds (robot, quadruped, winged insect, mocap, game rigs): at
    least 90% of labelled bones matched as labelled by ``structure``, on the pairs tuned on and on
    the held-out ones, reported per pair with ``text`` and the labelled bones left unmatched."""
    labelled = TUNED if split == "tuned" else HELD_OUT
    structure, per_pair, dropped = _labelled_hits(rigs, "structure", labelled)
    text, text_per_pair, _ = _labelled_hits(rigs, "text", labelled)
    print(f"\n{split}: structure {structure:.1%}, text {text:.1%}")
    for key in per_pair:
        print(f"  {key[0]:30s} -> {key[1]:28s} structure {per_pair[key]:5.0%}  text {text_per_pair[key]:5.0%}"
              f"  dropped by structure: {dropped[key] or '-'}")
    assert structure >= 0.9 and structure > text


# The issue's failures (source bone -> wanted), on the rigs it names: a mocap skeleton (CMU), a
# robot (a Quaternius mech, and RobotExpressive in its own naming style), a knight, a soldier and
# a wolf. On the Quaternius wolf (and the husky, the same skeleton) BackLeg is the femur below the
# BackShoulder connector: a robot's upper leg is BackLeg by the bones, as the hand labels above
# have it; the issue's "UpperLeg.L -> BackUpperLeg.L" read the words. What the issue asks of the
# chain (no link shifted, none on another chain) is checked link by link.
ISSUE_CASES = [
    ("CMU_02_01", "Quaternius_MechGeorge", {"Hips": "Body", "Spine1": "Chest", "Head": "Head"}),
    ("CMU_02_01", "RobotExpressive", {"Hips": "Body", "LeftFoot": "FootL", "RightFoot": "FootR"}),
    ("Quaternius_Knight", "Quaternius_MechGeorge", {"Body": "Body", "Torso": "Chest", "Foot.L": "Foot.L"}),
    ("CMU_02_01", "Quaternius_Soldier", {"Hips": "Hips", "LowerBack": "Abdomen", "Spine": "Torso", "Spine1": "Chest"}),
    ("Quaternius_MechGeorge", "Quaternius_Wolf", {"UpperLeg.L": "BackLeg.L", "MidLeg.L": "BackUpperLeg.L",
                                                 "LowerLeg.L": "BackLowerLeg.L", "UpperLeg.R": "BackLeg.R",
                                                 "MidLeg.R": "BackUpperLeg.R", "LowerLeg.R": "BackLowerLeg.R"}),
    ("RobotExpressive", "Quaternius_Husky", {"UpperLegL": "BackLeg.L", "LowerLegL": "BackUpperLeg.L",
                                            "UpperArmL": "FrontUpperLeg.L", "LowerArmL": "FrontLowerLeg.L"}),
    ("Quaternius_Rat", "Quaternius_Horse", {"BackLeg.L": "BackShoulder.L", "BackUpLeg.L": "BackLeg.L",
                                           "BackLowLeg.L": "BackUpperLeg.L"}),
]


@pytest.mark.parametrize("src, tgt, want", ISSUE_CASES, ids=[f"{a}->{b}" for a, b, _ in ISSUE_CASES])
def test_the_issues_failures(rigs, src, tgt, want):
    got = _match(rigs, src, tgt)
    assert {a: got.get(a) for a in want} == want
    if src == "CMU_02_01":  # the mocap feet are never dropped (their names are the robots' feet)
        assert got.get("LeftFoot") and got.get("RightFoot")


def test_text_method_sends_a_spine_to_a_finger_and_structure_does_not(rigs):
    """The issue's text failure, kept as published (``text`` is the paper's method); the default
    never matches a centre bone to a sided one unless their names agree."""
    assert _match(rigs, "CMU_02_01", "Quaternius_MechGeorge", "text")["Spine1"] == "Pinky1.L"
    assert _match(rigs, "CMU_02_01", "Quaternius_MechGeorge")["Spine1"] == "Chest"


def _features(rig):
    from mimicbench.datagen.correspond.canonical import canonicalize_names
    from mimicbench.datagen.correspond.structure import skeleton_features

    names, parents, kp = rig
    return skeleton_features(canonicalize_names(names), parents, kp)


def test_chains_are_matched_as_sequences_on_every_labelled_pair(rigs):
    """On every pair (tuned or not: a property, not a score): a bone meets only a bone of the same
    chain kind and side (:data:`CHAIN_KINDS`) unless their names are the same or synonyms; trunk
    bones never meet a limb's (a hand, a foot); two links of one trunk or limb path matched into
    one path keep their order, so no link jumps past its neighbour."""
    for (src, tgt) in {**LABELLED, **TUNED, **HELD_OUT}:
        fa, fb = _features(rigs[src]), _features(rigs[tgt])
        na, pa, ka = rigs[src]
        nb, pb, kb = rigs[tgt]
        _, h, _ = correspondence_for_skeletons(na, pa, ka, nb, pb, kb)
        for i, j in h:
            same_name = fa.name_key[i] == fb.name_key[j]
            assert fa.chain[i] == fb.chain[j] or same_name, (src, tgt, na[i], nb[j])
            assert (fa.seq_id[i] == 0) <= (fb.side[j] == 0), (src, tgt, na[i], nb[j])
        for (i1, j1), (i2, j2) in itertools.combinations(h.tolist(), 2):
            if fa.seq_id[i1] == fa.seq_id[i2] >= 0 and fb.seq_id[j1] == fb.seq_id[j2] >= 0:
                assert (fa.seq_pos[i1] - fa.seq_pos[i2]) * (fb.seq_pos[j1] - fb.seq_pos[j2]) >= 0, \
                    (src, tgt, na[i1], nb[j1], na[i2], nb[j2])


def test_no_match_rule_never_drops_a_bone_with_a_same_named_or_synonym_counterpart(rigs):
    """Per pair: every source bone whose canonical name (after the synonyms hips / pelvis / body,
    chest / upper spine; foot / ankle are one word already) is a target bone's is matched, unless
    every such target bone is taken by another match (one-to-one)."""
    for (src, tgt) in {**LABELLED, **TUNED, **HELD_OUT}:
        fa, fb = _features(rigs[src]), _features(rigs[tgt])
        got = _match(rigs, src, tgt)
        names, taken = rigs[src][0], set(got.values())
        free = {fb.name_key[j] for j, n in enumerate(rigs[tgt][0]) if n not in taken}
        lost = [names[i] for i in range(len(names)) if fa.name_key[i] in free and names[i] not in got]
        assert not lost, (src, tgt, lost)
