import pytest

from mimicbench.datagen.correspond.canonical import canonicalize_bone_name, canonicalize_names
from mimicbench.datagen.zoo.naming import bone_names
from tests.test_correspond_real_rigs import load_rig

# A compact humanoid per zoo naming style (roles are the list positions; the stage test uses them)
HUMANOID_ROLES = ["hips", "spine/1", "spine/2", "left/shoulder", "left/upper_arm", "left/forearm", "left/hand",
                  "left/thigh", "left/shin", "left/foot", "left/toe", "left/thumb/1"]
HUMANOID_STYLES = {style: bone_names(HUMANOID_ROLES, style, humanoid=True)
                   for style in ("mixamo", "blender", "biped", "gltf")}

# Every zoo naming style: raw name (as mimicbench.datagen.zoo.naming writes it) -> canonical text, written by hand.
ZOO_TABLE = {
    "mixamo": [("mixamorig:Hips", "hips"), ("mixamorig:Spine", "spine"), ("mixamorig:Spine1", "spine 1"),
               ("mixamorig:LeftShoulder", "left shoulder"), ("mixamorig:LeftArm", "left arm"),
               ("mixamorig:LeftForeArm", "left lower arm"), ("mixamorig:LeftHandThumb1", "left thumb 1"),
               ("mixamorig:RightUpLeg", "right upper leg"), ("mixamorig:RightLeg", "right leg"),
               ("mixamorig:RightToeBase", "right toe"), ("mixamorig:Skirt_03_02", "skirt 3 2")],
    "blender-humanoid": [("spine", "spine"), ("spine.001", "spine 2"), ("shoulder.L", "left shoulder"),
                         ("upper_arm.L", "left upper arm"), ("forearm.L", "left lower arm"),
                         ("thumb.01.L", "left thumb 1"), ("f_index.02.L", "left index 2"),
                         ("thigh.R", "right upper leg"), ("shin.R", "right lower leg"),
                         ("skirt.003.002", "skirt 3 2")],
    "biped": [("Bip01 Pelvis", "hips"), ("Bip01 Spine1", "spine 1"), ("Bip01 L Clavicle", "left shoulder"),
              ("Bip01 L Forearm", "left lower arm"), ("Bip01 L Finger0", "left thumb 1"),
              ("Bip01 L Finger11", "left index 2"), ("Bip01 L Finger42", "left pinky 3"),
              ("Bip01 R Calf", "right lower leg"), ("Bip01 R Toe0", "right toe"), ("Bip01 Hair 12 01", "hair 12 1")],
    "gltf-humanoid": [("b_Hips_00", "hips"), ("b_Spine1_01", "spine 1"), ("b_LeftUpperArm_07", "left upper arm"),
                      ("b_LeftForeArm_08", "left lower arm"), ("b_LeftThumb1_10", "left thumb 1"),
                      ("b_RightUpLeg_13", "right upper leg"), ("b_RightLowerLeg_14", "right lower leg"),
                      ("b_RightToes_16", "right toe"), ("b_Skirt3_2_17", "skirt 3 2")],
    "blender": [("Spine.001", "spine 2"), ("Neck.001", "neck 2"), ("Ear.L", "left ear"), ("Tail", "tail"),
                ("FrontLeg.002.L", "left front leg 3"), ("HindLeg.001.R", "right hind leg 2"),
                ("Wing.002.L", "left wing 3"), ("Leg2.002.L", "left leg 2 3"), ("TailFin", "tail fin"),
                ("PelvicFin.L", "left pelvic fin"), ("Fang.R", "right fang")],
    "snake": [("spine_01", "spine 1"), ("ear_l", "left ear"), ("front_leg_l_03", "left front leg 3"),
              ("hind_leg_r_02", "right hind leg 2"), ("wing_l_01", "left wing 1"), ("leg_l_02_03", "left leg 2 3"),
              ("antenna_r_01", "right antenna 1"), ("abdomen_02", "abdomen 2"), ("pelvic_fin_l", "left pelvic fin"),
              ("dorsal_fin", "dorsal fin")],
    "camel": [("Spine01", "spine 1"), ("Neck02", "neck 2"), ("Ear.L", "left ear"), ("FrontLeg1.L", "left front leg 1"),
              ("HindLeg2.R", "right hind leg 2"), ("Wing3.L", "left wing 3"), ("Leg2_3.L", "left leg 2 3"),
              ("Antenna1.R", "right antenna 1"), ("Abdomen02", "abdomen 2"), ("TailFin", "tail fin")],
    "gltf": [("b_Neck1_03", "neck 1"), ("b_LeftEar_07", "left ear"), ("b_LeftFrontLeg3_11", "left front leg 3"),
             ("b_RightHindLeg2_12", "right hind leg 2"), ("b_LeftLeg2_3_15", "left leg 2 3"),
             ("b_LeftPelvicFin_20", "left pelvic fin"), ("b_Thorax_22", "thorax"), ("b_RightFang_23", "right fang")],
}

# Every shared asset: raw name -> canonical text, written by hand (a sample of each rig's bones).
ASSET_TABLE = {
    "CesiumMan": [("Skeleton_torso_joint_1", "torso 1"), ("leg_joint_R_1", "right leg 1"),
                  ("leg_joint_L_5", "left leg 5"), ("torso_joint_3", "torso 3"), ("Skeleton_arm_joint_R", "right arm"),
                  ("Skeleton_arm_joint_R__2_", "right arm 2"), ("Skeleton_arm_joint_L__4_", "left arm 4"),
                  ("Skeleton_neck_joint_1", "neck 1")],
    "RobotExpressive": [("FootL", "left foot"), ("Palm2L", "left palm 2"), ("ThumbL", "left thumb"),
                        ("Middle1R", "right middle 1"), ("LowerArmL", "left lower arm"), ("UpperArmR", "right upper arm"),
                        ("ShoulderL", "left shoulder"), ("Torso_1", "torso 1"), ("UpperLegR", "right upper leg"),
                        ("PoleTargetL", "left pole target"), ("Bone", "bone")],
    "Fox": [("_rootJoint", "root"), ("b_Root_00", "root"), ("b_Hip_01", "hips"), ("b_Spine02_03", "spine 2"),
            ("b_RightForeArm_07", "right lower arm"), ("b_LeftForeArm_010", "left lower arm"),
            ("b_Tail03_014", "tail 3"), ("b_LeftLeg01_015", "left leg 1"), ("b_RightFoot02_022", "right foot 2")],
    "Quaternius_Horse": [("Body", "body"), ("Torso", "torso"), ("Torso2", "torso 2"), ("Neck1", "neck 1"),
                         ("Ear4.L", "left ear 4"), ("FrontShoulder.L", "left front shoulder"),
                         ("FrontUpperLeg.R", "right front upper leg"), ("BackLeg.L", "left back leg"),
                         ("BackLowerLeg.R", "right back lower leg"), ("Tail7", "tail 7"),
                         ("PoleTargetBack.L", "left pole target back"), ("IKFrontLeg.R", "right ik front leg"),
                         ("FFB.L", "left ffb")],
    "Quaternius_Husky": [("Torso3", "torso 3"), ("Neck3", "neck 3"), ("BackUpperLeg.L", "left back upper leg"),
                         ("Tail6", "tail 6"), ("FF.R", "right ff")],
    "Quaternius_Rat": [("root", "root"), ("FrontFoot.R", "right front foot"), ("FrontUpLeg.R", "right front upper leg"),
                       ("FrontLowLeg.L", "left front lower leg"), ("BackLeg.R", "right back leg"),
                       ("Shoulders", "shoulders"), ("Hips", "hips"), ("Torso", "torso")],
    "Quaternius_Stegosaurus": [("BackUpLeg.L", "left back upper leg"), ("BackLowLeg.R", "right back lower leg"),
                               ("Tail5", "tail 5"), ("FrontLeg.L", "left front leg"), ("BackFoot.R", "right back foot")],
    "Quaternius_Triceratops": [("Body", "body"), ("FrontUpLeg.R", "right front upper leg"), ("Neck", "neck")],
    "Quaternius_Dolphin": [("Root", "root"), ("Spine4", "spine 4"), ("TopFlipper.L", "left top flipper"),
                           ("MidFlipper.R", "right mid flipper"), ("BottomFlipper.L", "left bottom flipper")],
    "Quaternius_MantaRay": [("Spine1", "spine 1"), ("Tail", "tail"), ("BottomFlipper.R", "right bottom flipper")],
    "Quaternius_Farmer": [("Abdomen", "abdomen"), ("Torso", "torso"), ("Chest", "chest"),
                          ("UpperArm.L", "left upper arm"), ("LowerArm.R", "right lower arm"), ("Index2.L", "left index 2"),
                          ("Thumb3.R", "right thumb 3"), ("UpperLeg.L", "left upper leg"), ("LowerLeg.R", "right lower leg")],
    "Quaternius_Punk": [("Root", "root"), ("Pinky4.L", "left pinky 4"), ("Foot.R", "right foot")],
    "CMU_02_01": [("Hips", "hips"), ("LHipJoint", "left hip"), ("RHipJoint", "right hip"),
                  ("LeftUpLeg", "left upper leg"), ("LeftLeg", "left leg"), ("LeftToeBase", "left toe"),
                  ("LowerBack", "lower back"), ("Spine1", "spine 1"), ("Neck1", "neck 1"), ("LeftArm", "left arm"),
                  ("RightForeArm", "right lower arm"), ("LeftFingerBase", "left finger base"),
                  ("LeftHandIndex1", "left index 1"), ("LThumb", "left thumb"), ("RThumb", "right thumb")],
    "Gene": [("全ての親", "master"), ("センター", "center"), ("下半身", "lower body"), ("上半身", "upper body"),
             ("上半身2", "upper body 2"), ("首", "neck"), ("頭", "head"), ("左目", "left eye"), ("左肩", "left shoulder"),
             ("左腕", "left arm"), ("左腕捩", "left arm twist"), ("左ひじ", "left lower arm"), ("左手首", "left hand"),
             ("右親指０", "right thumb 0"), ("左人指１", "left index 1"), ("左薬指２", "left ring 2"),
             ("右小指３", "right pinky 3"), ("左足", "left leg"), ("左ひざ", "left lower leg"), ("右足首", "right foot"),
             ("左足ＩＫ", "left leg ik"), ("後髪A1_2", "back hair a 1 2"), ("右横髪2_3", "right side hair 2 3")],
}


@pytest.mark.parametrize("style", sorted(ZOO_TABLE))
def test_zoo_naming_styles_table(style):
    raw = [r for r, _ in ZOO_TABLE[style]]
    assert canonicalize_names(raw) == [t for _, t in ZOO_TABLE[style]]
    # context-free: each name alone gives the same text as within its list
    assert [canonicalize_bone_name(r) for r in raw] == [t for _, t in ZOO_TABLE[style]]


def test_zoo_naming_functions_write_the_tabled_names():
    """The table's raw names are the ones the zoo writes (so the table covers the zoo's real styles)."""
    written = {n for style in ("mixamo", "blender", "biped", "gltf") for roles in (
        ["hips", "spine/1", "spine/2", "left/shoulder", "left/upper_arm", "left/forearm", "left/thumb/1", "left/index/2",
         "left/pinky/3", "right/thigh", "right/shin", "right/toe", "apparel/skirt/3/2", "apparel/hair/12/1"],)
        for n in bone_names(roles, style, humanoid=True)}
    written |= {n for style in ("blender", "snake", "camel", "gltf") for n in bone_names(
        ["hips", "spine/1", "spine/2", "neck/1", "neck/2", "head", "left/ear", "tail/1", "left/front_leg/1",
         "left/front_leg/3", "right/hind_leg/2", "left/wing/1", "left/wing/3", "left/leg/2/3", "right/antenna/1",
         "abdomen/2", "tail_fin", "left/pelvic_fin", "dorsal_fin", "thorax", "right/fang"], style, humanoid=False)}
    tabled = {r for rows in ZOO_TABLE.values() for r, _ in rows} - {"b_Hips_00", "b_Spine1_01"}
    assert {r for r in tabled if not r.startswith("b_")} <= written
    assert any(r.startswith("b_Left") for r in written)


@pytest.mark.parametrize("asset", sorted(ASSET_TABLE))
def test_shared_asset_names_table(assets_dir, asset):
    names, _, _ = load_rig(assets_dir, asset)
    canon = dict(zip(names, canonicalize_names(names)))
    for raw, text in ASSET_TABLE[asset]:
        assert raw in canon, (asset, raw)
        assert canon[raw] == text, (asset, raw, canon[raw])
    for raw, text in canon.items():  # every bone of the rig: plain words
        assert text and text == text.lower() and ":" not in text and "_" not in text, (asset, raw, text)


def test_identical_raw_names_give_identical_text():
    # the causes seen on real rigs: chain renumbering made Torso "torso 1" beside Torso2 and "torso" elsewhere
    for name in ("Torso", "Abdomen", "Neck", "Tail", "Spine", "Hips", "LeftLeg"):
        alone = canonicalize_bone_name(name)
        for context in (["Torso2", "Torso3"], ["Abdomen1", "Abdomen2"], ["Neck1", "Head"], ["Tail.001"],
                        ["Spine1", "Spine2"], ["LeftUpLeg", "LeftForeArm"]):
            assert canonicalize_names([name] + context)[0] == alone, (name, context)
    assert canonicalize_names(["Torso", "Torso2"]) == ["torso", "torso 2"]
    assert canonicalize_names(["Tail", "Tail.001", "Tail.002"]) == ["tail", "tail 2", "tail 3"]


def test_sided_hip_joint_is_not_the_pelvis():
    assert canonicalize_bone_name("LHipJoint") == "left hip"
    assert canonicalize_bone_name("Hip") == "hips" and canonicalize_bone_name("Pelvis") == "hips"
    assert canonicalize_bone_name("UpperArmL") == "left upper arm" and canonicalize_bone_name("LowerLegR") == "right lower leg"


def test_export_indices_are_dropped_but_segment_numbers_kept():
    exported = ["Hips_000", "Spine_001", "Spine1_002", "LeftUpLeg_003", "LeftLeg_004", "Tail01_005"]
    assert canonicalize_names(exported) == ["hips", "spine", "spine 1", "left upper leg", "left leg", "tail 1"]
    # numbers that are not the bone indices, or one chain numbered throughout, are segment numbers
    b_style = ["b_Thorax_00", "b_LeftLeg1_1_01", "b_LeftLeg1_2_02", "b_Skirt2_1_03"]
    assert canonicalize_names(b_style) == ["thorax", "left leg 1 1", "left leg 1 2", "skirt 2 1"]
    assert canonicalize_names(["hips", "tail_01", "tail_02"]) == ["hips", "tail 1", "tail 2"]
    assert canonicalize_names(["tail_00", "tail_01", "tail_02"]) == ["tail 0", "tail 1", "tail 2"]


@pytest.mark.parametrize("raw,expected", [
    ("Wing.L", "left wing"), ("wing_l_02", "left wing 2"), ("FrontLeg2.R", "right front leg 2"),
    ("Tail01", "tail 1"), ("l_hand", "left hand"), ("Hand_R", "right hand"),
    ("CC_Base_L_Upperarm", "left upper arm"), ("Bip001 R Calf", "right lower leg"),
    ("J_Bip_L_UpperArm", "left upper arm"), ("DEF-forearm.R", "right lower arm"),
    ("Armature|mixamorig:RightHandIndex2", "right index 2"), ("Bip01 R Finger12", "right index 3"),
    ("upperarm_l", "left upper arm"), ("Neck.001", "neck 2"), ("LeftKnee", "left lower leg"),
    ("Elbow_R", "right lower arm"),
])
def test_single_names(raw, expected):
    assert canonicalize_bone_name(raw) == expected
