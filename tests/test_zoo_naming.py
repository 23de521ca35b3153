"""Bone-naming styles of the zoo: real-asset styles, unique names."""
import pytest

from mimicbench.datagen.zoo.naming import ANIMAL_STYLES, HUMANOID_STYLES, animal_name, bone_names, humanoid_name, parse_role


@pytest.mark.parametrize("style,expected", [
    ("mixamo", "mixamorig:LeftArm"), ("blender", "upper_arm.L"), ("biped", "Bip01 L UpperArm"),
    ("gltf", "b_LeftUpperArm_09")])
def test_humanoid_styles_name_the_left_upper_arm_like_real_assets(style, expected):
    assert humanoid_name("left/upper_arm", style, 9) == expected


@pytest.mark.parametrize("role,style,expected", [
    ("left/wing/1", "blender", "Wing.L"), ("left/wing/2", "snake", "wing_l_02"),
    ("right/front_leg/2", "camel", "FrontLeg2.R"), ("tail/1", "camel", "Tail01"),
    ("left/wing/2", "blender", "Wing.001.L")])
def test_animal_styles(role, style, expected):
    assert animal_name(role, style, 0) == expected


def test_parse_role():
    assert parse_role("left/leg/2/3") == ("left", "leg", [2, 3])
    assert parse_role("apparel/skirt/4/1") == (None, "apparel_skirt", [4, 1])
    assert parse_role("head") == (None, "head", [])


def test_names_are_unique_in_every_style():
    roles = (["hips", "spine/1", "spine/2", "neck", "head"]
             + [f"{s}/{p}" for s in ("left", "right") for p in ("shoulder", "upper_arm", "forearm", "hand", "thigh")]
             + [f"{s}/{f}/{i}" for s in ("left", "right") for f in ("thumb", "index", "pinky") for i in (1, 2, 3)]
             + [f"apparel/skirt/{c}/{j}" for c in range(1, 13) for j in range(1, 5)])
    for style in HUMANOID_STYLES:
        names = bone_names(roles, style, humanoid=True)
        assert len(set(names)) == len(roles), style
    animal = ["hips", "tail/1", "tail/2"] + [f"{s}/leg/{i}/{j}" for s in ("left", "right") for i in (1, 2, 3)
                                             for j in (1, 2, 3, 4)]
    for style in ANIMAL_STYLES:
        assert len(set(bone_names(animal, style, humanoid=False))) == len(animal), style


def test_repeated_names_are_refused():
    with pytest.raises(ValueError, match="repeated"):
        bone_names(["tail/1", "tail/1"], "snake", humanoid=False)
