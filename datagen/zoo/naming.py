"""Bone-naming styles: the same role gets a different name in each, as in real assets.

Humanoid styles: ``mixamo`` (``mixamorig:LeftArm``), ``blender`` (``upper_arm.L``), ``biped``
(3ds Max, ``Bip01 L UpperArm``), ``gltf`` (glTF-export style ``b_LeftUpperArm_09``, the joint
index appended). Other-category styles: ``blender`` (``Wing.L``, ``Wing.001.L``), ``snake``
(``wing_l_02``), ``camel`` (``FrontLeg2.R``, ``Tail01``), ``gltf`` (``b_LeftWing2_05``).
Roles are ``[side/]part[/n[/m]]`` (e.g. ``left/index/2``, ``tail/3``, ``apparel/skirt/4/2``).
"""
from __future__ import annotations

HUMANOID_STYLES = ("mixamo", "blender", "biped", "gltf")
ANIMAL_STYLES = ("blender", "snake", "camel", "gltf")

FINGERS = ("thumb", "index", "middle", "ring", "pinky")

_MIXAMO = {"hips": "Hips", "neck": "Neck", "head": "Head", "shoulder": "{S}Shoulder", "upper_arm": "{S}Arm",
           "forearm": "{S}ForeArm", "hand": "{S}Hand", "thigh": "{S}UpLeg", "shin": "{S}Leg",
           "foot": "{S}Foot", "toe": "{S}ToeBase"}
_BLENDER = {"hips": "spine", "neck": "neck", "head": "head", "shoulder": "shoulder.{s}",
            "upper_arm": "upper_arm.{s}", "forearm": "forearm.{s}", "hand": "hand.{s}", "thigh": "thigh.{s}",
            "shin": "shin.{s}", "foot": "foot.{s}", "toe": "toe.{s}"}
_BIPED = {"hips": "Bip01 Pelvis", "neck": "Bip01 Neck", "head": "Bip01 Head", "shoulder": "Bip01 {s} Clavicle",
          "upper_arm": "Bip01 {s} UpperArm", "forearm": "Bip01 {s} Forearm", "hand": "Bip01 {s} Hand",
          "thigh": "Bip01 {s} Thigh", "shin": "Bip01 {s} Calf", "foot": "Bip01 {s} Foot", "toe": "Bip01 {s} Toe0"}
_GLTF = {"hips": "Hips", "neck": "Neck", "head": "Head", "shoulder": "{S}Shoulder", "upper_arm": "{S}UpperArm",
         "forearm": "{S}ForeArm", "hand": "{S}Hand", "thigh": "{S}UpLeg", "shin": "{S}LowerLeg",
         "foot": "{S}Foot", "toe": "{S}Toes"}


def parse_role(role: str) -> tuple[str | None, str, list[int]]:
    """Split a role into (side or None, part, trailing numbers): ``left/wing/2`` -> ("left", "wing", [2])."""
    tokens = role.split("/")
    side = tokens[0] if tokens[0] in ("left", "right") else None
    rest = tokens[1:] if side else tokens
    nums = []
    while rest and rest[-1].isdigit():
        nums.insert(0, int(rest.pop()))
    return side, "_".join(rest), nums


def camel(part: str) -> str:
    """``front_leg`` -> ``FrontLeg``; ``apparel_skirt`` -> ``Skirt`` (the apparel prefix dropped)."""
    words = [w for w in part.split("_") if w and w != "apparel"]
    return "".join(w[:1].upper() + w[1:] for w in words)


def humanoid_name(role: str, style: str, index: int) -> str:
    """Name of a humanoid (or apparel humanoid) bone ``role`` in ``style``; ``index`` is its joint index."""
    side, part, nums = parse_role(role)
    S = {"left": "Left", "right": "Right", None: ""}[side]
    s = {"left": "L", "right": "R", None: ""}[side]
    if part in FINGERS:
        n = nums[0]
        fi = FINGERS.index(part)
        if style == "mixamo":
            return f"mixamorig:{S}Hand{camel(part)}{n}"
        if style == "blender":
            return f"{'thumb' if part == 'thumb' else 'f_' + part}.{n:02d}.{s}"
        if style == "biped":
            return f"Bip01 {s} Finger{fi}{'' if n == 1 else n - 1}"
        return f"b_{S}{camel(part)}{n}_{index:02d}"
    if part == "spine":
        n = nums[0]
        return {"mixamo": f"mixamorig:Spine{'' if n == 1 else n - 1}", "blender": f"spine.{n:03d}",
                "biped": f"Bip01 Spine{'' if n == 1 else n - 1}", "gltf": f"b_Spine{n}_{index:02d}"}[style]
    table = {"mixamo": _MIXAMO, "blender": _BLENDER, "biped": _BIPED, "gltf": _GLTF}[style]
    if part in table and not nums:
        name = table[part].format(S=S, s=s)
        return {"mixamo": "mixamorig:" + name, "gltf": f"b_{name}_{index:02d}"}.get(style, name)
    # apparel chains and anything else: a generic name in the style's manner
    num = "_".join(f"{n:02d}" for n in nums)
    if style == "mixamo":
        return f"mixamorig:{S}{camel(part)}{'_' + num if num else ''}"
    if style == "blender":
        return f"{part.replace('apparel_', '')}{'.' + '.'.join(f'{n:03d}' for n in nums) if nums else ''}{'.' + s if s else ''}"
    if style == "biped":
        return f"Bip01 {s + ' ' if s else ''}{camel(part)}{' '.join(f'{n:02d}' for n in nums) and ' ' + ' '.join(f'{n:02d}' for n in nums)}"
    return f"b_{S}{camel(part)}{'_'.join(str(n) for n in nums)}_{index:02d}"


def animal_name(role: str, style: str, index: int) -> str:
    """Name of a non-humanoid bone ``role`` in ``style``; ``index`` is its joint index."""
    side, part, nums = parse_role(role)
    P = camel(part)
    if style == "blender":
        base = P + "".join(str(n) for n in nums[:-1])
        if nums and nums[-1] > 1:
            base += f".{nums[-1] - 1:03d}"
        return base + {"left": ".L", "right": ".R", None: ""}[side]
    if style == "snake":
        parts = [part] + ([side[0]] if side else []) + [f"{n:02d}" for n in nums]
        return "_".join(parts)
    if style == "camel":
        if side:
            return P + "_".join(str(n) for n in nums) + {"left": ".L", "right": ".R"}[side]
        return P + "_".join(f"{n:02d}" for n in nums)
    if style == "gltf":
        S = {"left": "Left", "right": "Right", None: ""}[side]
        return f"b_{S}{P}{'_'.join(str(n) for n in nums)}_{index:02d}"
    raise ValueError(f"style: expected one of {ANIMAL_STYLES}, got {style!r}")


def bone_names(roles: list[str], style: str, humanoid: bool) -> list[str]:
    """Names for all roles in ``style`` (unique; raises if a style would repeat a name)."""
    if humanoid and style not in HUMANOID_STYLES:
        raise ValueError(f"style: expected one of {HUMANOID_STYLES} for a humanoid, got {style!r}")
    fn = humanoid_name if humanoid else animal_name
    names = [fn(r, style, i) for i, r in enumerate(roles)]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"style {style!r} gives repeated bone names {dup[:5]}")
    return names
