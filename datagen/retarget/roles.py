"""Humanoid bone roles from bone names, through the correspondence stage's canonical names.

A bone's canonical name (``mimicbench.datagen.correspond.canonical``: ``mixamorig:LeftForeArm`` -> ``left lower
arm``, MMD's ``左腕`` -> ``left arm``, CMU's ``LeftUpLeg`` -> ``left upper leg``) is looked up in a
table of the names each role goes by across conventions; roles use the zoo's vocabulary (``hips``,
``spine/1``, ``left/upper_arm``, ...). The first bone (parents first) that takes a role keeps it.
Canonical names say no chain position (``Spine``, ``Spine1`` stay ``spine``, ``spine 1``, as
written), so spine bones take spine/1, spine/2, ... in parents-first order (the first is the hips
when no bone is called hips or pelvis, Rigify's convention), and a bare ``arm`` or
``leg`` whose upper segment is taken is the lower one (Mixamo's ``LeftLeg`` below ``LeftUpLeg``).
"""
from __future__ import annotations

from typing import Sequence

# role -> canonical names (without the side word) that mean it
ROLE_NAMES = {
    "hips": ("hips", "lower body"),
    "spine/1": ("spine 1", "spine", "upper body 1", "upper body"),
    "spine/2": ("spine 2", "upper body 2", "chest"),
    "spine/3": ("spine 3", "upper body 3", "upper chest"),
    "neck": ("neck", "neck 1"),
    "head": ("head",),
    "shoulder": ("shoulder",),
    "upper_arm": ("upper arm", "arm"),
    "forearm": ("lower arm", "forearm", "elbow"),
    "hand": ("hand", "wrist"),
    "thigh": ("upper leg", "thigh", "leg"),
    "shin": ("lower leg", "shin", "knee"),
    "foot": ("foot", "ankle"),
    "toe": ("toe",),
}
SIDED = {"shoulder", "upper_arm", "forearm", "hand", "thigh", "shin", "foot", "toe"}
# The roles whose head gives a role's direction at rest (bone head -> that head), first found wins
DIRECTION_CHILD = {
    "hips": ("spine/1",), "spine/1": ("spine/2", "neck"), "spine/2": ("spine/3", "neck"), "spine/3": ("neck",),
    "neck": ("head",), "shoulder": ("upper_arm",), "upper_arm": ("forearm",), "forearm": ("hand",),
    "thigh": ("shin",), "shin": ("foot",), "foot": ("toe",),
}
_LOOKUP = {name: role for role, names in ROLE_NAMES.items() for name in names}


def role_of(canonical: str) -> str | None:
    """The role of one canonical name (``left upper arm`` -> ``left/upper_arm``), or None."""
    side = None
    for s in ("left", "right"):
        if canonical.startswith(s + " "):
            side, canonical = s, canonical[len(s) + 1:]
    role = _LOOKUP.get(canonical)
    if role is None or (role in SIDED) != (side is not None):
        return None
    return f"{side}/{role}" if side else role


def humanoid_roles(bone_names: Sequence[str]) -> dict[str, int]:
    """Role -> bone index for the bones whose names say a humanoid role (bones in parents-first
    order, so the first bone with a role is the one nearest the root)."""
    from mimicbench.datagen.correspond.canonical import canonicalize_names

    out: dict[str, int] = {}
    canon = canonicalize_names(list(bone_names))
    spines = 0 if any(role_of(c) == "hips" for c in canon) else -1  # Rigify: a chain called spine starts at the hips
    for i, c in enumerate(canon):
        role = role_of(c)
        if role in ("spine/1", "spine/2", "spine/3") and c.split(" ")[0] in ("spine", "upper"):
            spines += 1
            role = ("hips" if spines == 0 else f"spine/{spines}") if spines <= 3 else None
        elif role is not None and role in out and role.endswith(("/upper_arm", "/thigh")):
            role = role.replace("upper_arm", "forearm").replace("thigh", "shin")
        if role is not None and role not in out:
            out[role] = i
    return out


def direction_children(role: str) -> list[str]:
    """The roles whose head, seen from ``role``'s head, gives ``role``'s direction (the first that
    both skeletons have is used)."""
    side, base = role.split("/", 1) if role.split("/")[0] in ("left", "right") else ("", role)
    return [f"{side}/{c}" if side and c in SIDED else c for c in DIRECTION_CHILD.get(base, ())]
