"""Which strings a role-label file may give a bone, and what each means.

A role is either a **zoo role** (``left/upper_arm``, ``spine/2``, ``left/front_leg/3``,
``tail/4``, ``apparel/hair/1/2``; :mod:`mimicbench.datagen.zoo.naming`) or a **class**, optionally sided and
numbered (``left/forelimb``, ``hindlimb``, ``tail``, ``head``, ``apparel``;
:data:`mimicbench.datagen.correspond.roles.ROLE_CLASSES`). Both map to a class through
:func:`mimicbench.datagen.correspond.roles.role_classes`. ``""`` means: no role.

Sides: limbs and ears (``forelimb``, ``midlimb``, ``hindlimb``, ``ear`` and the zoo parts that
map to them) need ``left/`` or ``right/``; ``root``, ``spine``, ``neck``, ``head``, ``tail``,
``dorsal`` and ``apparel`` take none; ``jaw`` may take one (an insect's fangs).
"""
from __future__ import annotations

from mimicbench.datagen.correspond.roles import ROLE_CLASSES, role_classes
from mimicbench.datagen.zoo.naming import parse_role

SIDES = ("left", "right")
SIDED_CLASSES = frozenset({"forelimb", "midlimb", "hindlimb", "ear"})
"""Classes whose bones must say their side."""
UNSIDED_CLASSES = frozenset({"root", "spine", "neck", "head", "tail", "dorsal", "apparel"})
"""Classes whose bones take no side (``jaw`` may take one or none)."""
CLASS_NAMES = frozenset(ROLE_CLASSES)


def role_problem(role: str, category: str = "unknown") -> str | None:
    """Why ``role`` is not a role a label file may give, or None when it is (``""`` is allowed).

    Args:
        role: the string to check.
        category: the character's category (an insect's ``leg`` roles are classed by pair).
    """
    if not isinstance(role, str):
        return f"expected a string, got {type(role).__name__} {role!r}"
    if role == "":
        return None
    if role != role.strip() or "//" in role or role.endswith("/"):
        return f"{role!r}: a role is words joined by '/', without spaces around it or empty parts"
    try:
        (cls,) = role_classes([role], category)
    except ValueError:
        return (f"{role!r} is neither a zoo role (left/upper_arm, spine/2, tail/3, left/front_leg/1, ...) nor a "
                f"class ({', '.join(ROLE_CLASSES)}, sided as left/forelimb)")
    side, part, _ = parse_role(role)
    base = cls.split("/")[-1]
    if base in SIDED_CLASSES and side is None:
        return f"{role!r}: a {base} role needs a side (left/{role} or right/{role})"
    if base in UNSIDED_CLASSES and side is not None:
        return f"{role!r}: a {base} role takes no side"
    return None


def is_class_role(role: str) -> bool:
    """True when ``role`` names a class without a number (``left/forelimb``, ``tail``, ``head``) or
    is an apparel role (``apparel``, ``apparel/hair``): such a role may label many bones of one
    character; any other role (``left/upper_arm``, ``tail/3``) labels one bone."""
    if role == "apparel" or role.startswith("apparel/"):
        return True
    _, part, nums = parse_role(role)
    return part in CLASS_NAMES and not nums
