import json
import re
import struct

import pytest

from datagen.correspond.canonical import canonicalize_bone_name, canonicalize_names

HUMANOID_STYLES = {
    "mixamo": ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:LeftShoulder", "mixamorig:LeftArm",
               "mixamorig:LeftForeArm", "mixamorig:LeftHand", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg",
               "mixamorig:LeftFoot", "mixamorig:LeftToeBase", "mixamorig:LeftHandThumb1"],
    "blender": ["spine", "spine.001", "spine.002", "shoulder.L", "upper_arm.L", "forearm.L", "hand.L", "thigh.L",
                "shin.L", "foot.L", "toe.L", "thumb.01.L"],
    "biped": ["Bip01 Pelvis", "Bip01 Spine", "Bip01 Spine1", "Bip01 L Clavicle", "Bip01 L UpperArm", "Bip01 L Forearm",
              "Bip01 L Hand", "Bip01 L Thigh", "Bip01 L Calf", "Bip01 L Foot", "Bip01 L Toe0", "Bip01 L Finger0"],
    "gltf": ["b_Hips_00", "b_Spine1_01", "b_Spine2_02", "b_LeftShoulder_05", "b_LeftUpperArm_06", "b_LeftForeArm_07",
             "b_LeftHand_08", "b_LeftUpLeg_09", "b_LeftLowerLeg_10", "b_LeftFoot_11", "b_LeftToes_12", "b_LeftThumb1_13"],
}
EXPECTED = ["hips", "spine 1", "spine 2", "left shoulder", "left upper arm", "left forearm", "left hand", "left thigh",
            "left shin", "left foot", "left toe", "left thumb 1"]


@pytest.mark.parametrize("style", sorted(HUMANOID_STYLES))
def test_four_humanoid_styles_reach_one_vocabulary(style):
    assert canonicalize_names(HUMANOID_STYLES[style]) == EXPECTED


@pytest.mark.parametrize("raw,expected", [
    ("Wing.L", "left wing"), ("wing_l_02", "left wing 2"), ("FrontLeg2.R", "right front leg 2"),
    ("Tail01", "tail 1"), ("左腕", "left arm"), ("右ひじ", "right elbow"),
    ("左足首", "left ankle"), ("左人指１", "left index 1"), ("l_hand", "left hand"), ("Hand_R", "right hand"),
    ("CC_Base_L_Upperarm", "left upper arm"), ("Bip001 R Calf", "right shin"), ("mixamorig:LeftArm", "left arm"),
    ("upper_arm.L", "left upper arm"), ("Bip01 L UpperArm", "left upper arm"), ("b_LeftUpperArm_09", "left upper arm"), ("J_Bip_L_UpperArm", "left upper arm"), ("DEF-forearm.R", "right forearm"),
    ("Armature|mixamorig:RightHandIndex2", "right index 2"), ("Bip01 R Finger12", "right index 3"),
    ("upperarm_l", "left upper arm"), ("Neck.001", "neck 1"),
])
def test_single_names(raw, expected):
    assert canonicalize_bone_name(raw) == expected


def test_chains_are_numbered_from_one_across_styles():
    assert canonicalize_names(["Tail", "Tail.001", "Tail.002"]) == ["tail 1", "tail 2", "tail 3"]
    assert canonicalize_names(["Tail01", "Tail02", "Tail03"]) == ["tail 1", "tail 2", "tail 3"]
    assert canonicalize_names(["Neck", "Neck1", "Head"]) == ["neck 1", "neck 2", "head"]
    assert canonicalize_names(["上半身", "上半身2", "首"]) == ["upper body 1", "upper body 2", "neck"]


def test_export_indices_are_dropped_but_segment_numbers_kept():
    exported = ["Hips_000", "Spine_001", "Spine1_002", "LeftUpLeg_003", "LeftLeg_004", "Tail01_005"]
    assert canonicalize_names(exported) == ["hips", "spine 1", "spine 2", "left thigh", "left shin", "tail 1"]
    # numbers that are not the bone indices, or one chain numbered throughout, are segment numbers
    b_style = ["b_Thorax_00", "b_LeftLeg1_1_01", "b_LeftLeg1_2_02", "b_Skirt2_1_03"]
    assert canonicalize_names(b_style) == ["thorax", "left leg 1 1", "left leg 1 2", "skirt 2 1"]
    assert canonicalize_names(["hips", "tail_01", "tail_02"]) == ["hips", "tail 1", "tail 2"]
    assert canonicalize_names(["tail_00", "tail_01", "tail_02"]) == ["tail 0", "tail 1", "tail 2"]
    assert canonicalize_names(["leg_l_01_01", "leg_l_01_02", "leg_l_02_01"]) == ["left leg 1 1", "left leg 1 2",
                                                                                   "left leg 2 1"]


def glb_joint_names(path):
    data = path.read_bytes()
    length = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + length])
    joints = sorted({j for skin in doc.get("skins", []) for j in skin["joints"]})
    return [doc["nodes"][j].get("name", f"node{j}") for j in joints]


def test_every_shared_asset_name_canonicalises_to_words(assets_dir):
    names = {p.stem: glb_joint_names(p) for p in sorted((assets_dir / "glb").glob("*.glb"))}
    bvh = (assets_dir / "bvh" / "CMU_02_01.bvh").read_text()
    names["CMU_02_01"] = re.findall(r"(?:ROOT|JOINT)\s+(\S+)", bvh)
    assert len(names["CMU_02_01"]) == 31 and len(names["Fox"]) == 24
    for asset, raw in names.items():
        canon = canonicalize_names(raw)
        assert len(canon) == len(raw)
        for r, c in zip(raw, canon):
            assert c and c == c.lower() and ":" not in c and "_" not in c, (asset, r, c)
    cmu = dict(zip(names["CMU_02_01"], canonicalize_names(names["CMU_02_01"])))
    assert cmu["LeftUpLeg"] == "left thigh" and cmu["LeftLeg"] == "left shin" and cmu["RightForeArm"] == "right forearm"
