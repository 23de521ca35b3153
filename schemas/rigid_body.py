"""A rigid body of a character's physics, from an MMD model (table ``rigid_bodies``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.columns import Column

TABLE = "rigid_bodies"
# the tables of a character's own physics (an MMD file): stages that keep its bones keep them too
PHYSICS_TABLES = (TABLE, "joints")
SHAPES = ("sphere", "box", "capsule")
MODES = ("static", "dynamic", "dynamic_bone")


@dataclass
class RigidBodyRecord:
    """One rigid body, in the dataset frame (metres, Y up, +Z forward), at the character's rest pose.

    ``size`` (3,) float32 metres: sphere (radius, 0, 0); box half extents (x, y, z); capsule
    (radius, cylinder height, 0) along the body's local Y axis. ``position`` (3,) and
    ``rotation`` (4,) unit quaternion (w, x, y, z) place the body in the character's rest frame.
    """

    character_id: str
    body_index: int
    name: str
    name_en: str
    bone: int
    shape: str
    size: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    mass: float
    linear_damping: float
    angular_damping: float
    restitution: float
    friction: float
    collision_group: int
    collision_mask: int
    mode: str

    COLUMNS = (
        Column("character_id", "scalar", "string", doc="the character whose bones the body follows or drives"),
        Column("body_index", "scalar", "int32", doc="index of the body in its file; `joints` refer to it"),
        Column("name", "scalar", "string", doc="name as authored (Japanese in MMD files)"),
        Column("name_en", "scalar", "string", doc="the file's English name (often empty)"),
        Column("bone", "scalar", "int32", doc="index into the character's bones (its order), -1 for none"),
        Column("shape", "scalar", "string", doc="`sphere`, `box` or `capsule`"),
        Column("size", "list", "float32", doc="(3,) metres: sphere (radius, 0, 0); box half extents; capsule (radius, height, 0) along local Y"),
        Column("position", "list", "float32", doc="(3,) centre at rest, metres, dataset frame"),
        Column("rotation", "list", "float32", doc="(4,) orientation at rest, unit quaternion (w, x, y, z), dataset frame"),
        Column("mass", "scalar", "float32", doc="mass as stored (MMD's units; static bodies ignore it)"),
        Column("linear_damping", "scalar", "float32", doc="0..1 as stored"),
        Column("angular_damping", "scalar", "float32", doc="0..1 as stored"),
        Column("restitution", "scalar", "float32", doc="as stored"),
        Column("friction", "scalar", "float32", doc="as stored"),
        Column("collision_group", "scalar", "int32", doc="0..15; the body's group bit is `1 << collision_group`"),
        Column("collision_mask", "scalar", "int32", doc="16 bits as stored: bit g set = collides with group g (the complement of the non-collision groups MMD's editors show; Bullet's mask)"),
        Column("mode", "scalar", "string", doc="`static` (follows its bone), `dynamic` (physics drives the bone), `dynamic_bone` (physics rotation, bone translation)"),
    )
