"""A joint between two rigid bodies of a character, from an MMD model (table ``joints``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.columns import Column

TABLE = "joints"
KINDS = ("spring_6dof", "6dof", "point_to_point", "cone_twist", "slider", "hinge")


@dataclass
class JointRecord:
    """One joint, in the dataset frame (metres, Y up, +Z forward), at the character's rest pose.

    Limits are per axis of the joint's own frame (``rotation``), lower then upper: translations in
    metres, rotations in radians (Euler angles). The mirror from MMD's left-handed frame negates
    local z translations and x, y rotations, so those bounds are swapped and negated. A lower
    bound above its upper bound means a free axis (Bullet's convention; kept from the file).
    """

    character_id: str
    joint_index: int
    name: str
    name_en: str
    kind: str
    body_a: int
    body_b: int
    position: np.ndarray
    rotation: np.ndarray
    translation_min: np.ndarray
    translation_max: np.ndarray
    rotation_min: np.ndarray
    rotation_max: np.ndarray
    spring_translation: np.ndarray
    spring_rotation: np.ndarray

    COLUMNS = (
        Column("character_id", "scalar", "string", doc="the character the joint belongs to"),
        Column("joint_index", "scalar", "int32", doc="index of the joint in its file"),
        Column("name", "scalar", "string", doc="name as authored"),
        Column("name_en", "scalar", "string", doc="the file's English name (often empty)"),
        Column("kind", "scalar", "string", doc="`spring_6dof` (MMD's joint) or a PMX 2.1 kind: " + ", ".join(f"`{k}`" for k in KINDS[1:])),
        Column("body_a", "scalar", "int32", doc="`body_index` of the first rigid body"),
        Column("body_b", "scalar", "int32", doc="`body_index` of the second rigid body"),
        Column("position", "list", "float32", doc="(3,) joint origin at rest, metres, dataset frame"),
        Column("rotation", "list", "float32", doc="(4,) joint frame at rest, unit quaternion (w, x, y, z)"),
        Column("translation_min", "list", "float32", doc="(3,) lower translation limits, metres, joint frame"),
        Column("translation_max", "list", "float32", doc="(3,) upper translation limits, metres, joint frame"),
        Column("rotation_min", "list", "float32", doc="(3,) lower rotation limits, radians, joint frame"),
        Column("rotation_max", "list", "float32", doc="(3,) upper rotation limits, radians, joint frame"),
        Column("spring_translation", "list", "float32", doc="(3,) translational spring stiffness as stored (MMD's units)"),
        Column("spring_rotation", "list", "float32", doc="(3,) rotational spring stiffness as stored; MMD's joints have no damping"),
    )
