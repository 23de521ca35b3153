"""The cross-category role map: which zoo roles are counterparts across kinds of character.

The zoo stores a hidden role per bone (``left/upper_arm``, ``tail/3``, ``left/leg/2/1``; see
:mod:`mimicbench.datagen.zoo.naming`). Within a category a match is right when the roles are equal. Across
categories the roles differ by name, so each role maps to a **class**, and a match is right when
the classes are equal. Sides stay part of the class (a left arm never counts as a right wing).

| class | humanoid (and apparel) | quadruped, reptile | bird | fish | insect |
|---|---|---|---|---|---|
| ``root`` | hips | hips; snake: root | hips | root | thorax |
| ``spine`` | spine/n | spine/n | spine/n | spine/n | - |
| ``neck`` | neck | neck/n | neck/n | - | - |
| ``head`` | head | head | head | head | head |
| ``jaw`` | - | jaw | beak | - | fang (sided) |
| ``ear`` | - | ear (sided) | - | - | antenna/n (sided) |
| ``forelimb`` | shoulder, upper_arm, forearm, hand, fingers | front_leg/n | wing/n | fin (pectoral) | leg/1/n (first pair) |
| ``midlimb`` | - | - | - | - | leg/i/n, the pairs between the first and the last |
| ``hindlimb`` | thigh, shin, foot, toe | hind_leg/n | leg/n | pelvic_fin | leg/last/n |
| ``tail`` | - | tail/n | tail/n | tail/n, tail_fin | abdomen/n |
| ``dorsal`` | - | - | - | dorsal_fin | - |
| ``apparel`` | apparel/... (apparel humanoids) | - | - | - | - |

So arm ~ front leg ~ wing ~ pectoral fin ~ an insect's first legs, leg ~ hind leg ~ pelvic fin ~
its last legs, and an insect's abdomen, the segments behind the thorax where no leg attaches,
counts as its tail. A snake's body chain is its ``spine``. Sided classes are written
``left/forelimb``; the others have no side.

A role may also name its class directly (``left/forelimb``, ``hindlimb/2``, ``dorsal``,
``apparel``), as a role-label file for a real character does (:mod:`mimicbench.datagen.roles`). An empty
role (``""``, or None) marks a bone without a role: its class is None.
"""
from __future__ import annotations

from mimicbench.datagen.zoo.naming import FINGERS, parse_role

_CLASS = {
    "hips": "root", "root": "root", "thorax": "root",
    "spine": "spine", "neck": "neck", "head": "head",
    "jaw": "jaw", "beak": "jaw", "fang": "jaw",
    "ear": "ear", "antenna": "ear",
    "shoulder": "forelimb", "upper_arm": "forelimb", "forearm": "forelimb", "hand": "forelimb",
    "front_leg": "forelimb", "wing": "forelimb", "fin": "forelimb",
    "thigh": "hindlimb", "shin": "hindlimb", "foot": "hindlimb", "toe": "hindlimb", "hind_leg": "hindlimb",
    "pelvic_fin": "hindlimb",
    "tail": "tail", "tail_fin": "tail", "abdomen": "tail",
    "dorsal_fin": "dorsal",
    **{f: "forelimb" for f in FINGERS},
    "forelimb": "forelimb", "midlimb": "midlimb", "hindlimb": "hindlimb", "dorsal": "dorsal",
}
ROLE_CLASSES = ("root", "spine", "neck", "head", "jaw", "ear", "forelimb", "midlimb", "hindlimb", "tail", "dorsal",
                "apparel")


def role_classes(roles: list[str | None], category: str) -> list[str | None]:
    """The class of every role of one skeleton (the map in the module docstring).

    Args:
        roles: K roles: zoo roles (``left/upper_arm``, ``tail/3``), class names (``left/forelimb``,
            ``spine``), or ``""`` / None for a bone without a role.
        category: the character's category; it tells a bird's or an insect's ``leg`` (hind limbs;
            an insect's by pair) from the others.

    Returns:
        K classes (``left/forelimb``, ``tail``, ...), None where the bone has no role.

    Raises:
        ValueError: a role the map does not know, so a new template cannot go unscored.
    """
    parsed = [parse_role(r) if r else (None, "", []) for r in roles]
    insect_pairs = max((nums[0] for _, part, nums in parsed if part == "leg" and nums and category == "insect"),
                       default=0)
    out: list[str | None] = []
    for role, (side, part, nums) in zip(roles, parsed):
        if not role:
            out.append(None)
            continue
        if role == "apparel" or role.startswith("apparel/"):
            out.append("apparel")
            continue
        if part == "leg":
            if category == "insect" and nums:
                cls = "forelimb" if nums[0] == 1 else "hindlimb" if nums[0] == insect_pairs else "midlimb"
            else:
                cls = "hindlimb"
        elif part in _CLASS:
            cls = _CLASS[part]
        else:
            raise ValueError(f"role {role!r} ({category}): not in the cross-category role map")
        out.append(f"{side}/{cls}" if side else cls)
    return out


def record_role_classes(record) -> list[str | None] | None:
    """The role classes of a character record's bones (:func:`role_classes` of its hidden
    ``bone_roles`` and its ``category``), or None when it has no role at all (no ``bone_roles``, or
    every entry empty): such a character gets no semantic score.

    Args:
        record: a :class:`mimicbench.schemas.character.CharacterRecord` (or anything with ``bone_roles``
            and ``category``).

    Returns:
        K classes, None for each bone without a role; or None.
    """
    roles = record.bone_roles
    if roles is None or not any(roles):
        return None
    return role_classes(list(roles), record.category)
