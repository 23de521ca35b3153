"""An MMD model as stored in its file (PMX, or PMD converted to PMX's terms): MMD units,
MMD's left-handed Y-up frame, Japanese names. :mod:`mimicbench.datagen.mmd.records` converts it to the
dataset's frame."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# PMX bone flags (PMX 2.0 spec, "bone flag")
BONE_TAIL_IS_BONE = 0x0001
BONE_ROTATABLE = 0x0002
BONE_MOVABLE = 0x0004
BONE_VISIBLE = 0x0008
BONE_OPERABLE = 0x0010
BONE_IK = 0x0020
BONE_GRANT_LOCAL = 0x0080
BONE_GRANT_ROTATION = 0x0100
BONE_GRANT_TRANSLATION = 0x0200
BONE_FIXED_AXIS = 0x0400
BONE_LOCAL_AXIS = 0x0800
BONE_AFTER_PHYSICS = 0x1000
BONE_EXTERNAL_PARENT = 0x2000

DEFORM_NAMES = ("BDEF1", "BDEF2", "BDEF4", "SDEF", "QDEF")
SHAPE_NAMES = ("sphere", "box", "capsule")
MODE_NAMES = ("static", "dynamic", "dynamic_bone")  # MMD: bone-following, physics, physics + bone


@dataclass
class IKLink:
    """One link of an IK chain: a bone and optional Euler angle limits (radians, MMD frame)."""

    bone: int
    limit_min: np.ndarray | None = None  # (3,) or None
    limit_max: np.ndarray | None = None


@dataclass
class IKChain:
    """IK solved by CCD: move ``links`` so that ``target`` reaches the IK bone's position."""

    target: int
    loop: int
    limit_angle: float  # radians a link may turn per iteration (MMD's "unit angle")
    links: list[IKLink]


@dataclass
class MMDBone:
    """A bone as stored: head ``position`` (3,) in model space, MMD units."""

    name: str
    name_en: str
    position: np.ndarray
    parent: int
    layer: int = 0
    flags: int = BONE_ROTATABLE | BONE_VISIBLE | BONE_OPERABLE
    tail_bone: int = -1
    tail_offset: np.ndarray | None = None
    grant_parent: int = -1
    grant_ratio: float = 0.0
    fixed_axis: np.ndarray | None = None
    local_x: np.ndarray | None = None
    local_z: np.ndarray | None = None
    ik: IKChain | None = None

    @property
    def grant_rotation(self) -> bool:
        return bool(self.flags & BONE_GRANT_ROTATION) and self.grant_parent >= 0

    @property
    def grant_translation(self) -> bool:
        return bool(self.flags & BONE_GRANT_TRANSLATION) and self.grant_parent >= 0

    @property
    def after_physics(self) -> bool:
        return bool(self.flags & BONE_AFTER_PHYSICS)


@dataclass
class MMDRigidBody:
    """A rigid body as stored: shape size (3,) (sphere: radius; box: half extents; capsule:
    radius, height), ``position`` (3,) in model space (PMD's bone offsets already added),
    ``rotation`` (3,) Euler radians (MMD applies Z, then X, then Y: R = Ry Rx Rz)."""

    name: str
    name_en: str
    bone: int
    group: int
    mask: int  # 16 bits as stored: bit g set = collides with group g (as MMD players pass it to Bullet)
    shape: int
    size: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    mass: float
    linear_damping: float
    angular_damping: float
    restitution: float
    friction: float
    mode: int


@dataclass
class MMDJoint:
    """A 6-DOF spring joint as stored (PMX joint type 0)."""

    name: str
    name_en: str
    kind: int
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


@dataclass
class MMDModel:
    """The parts of a PMX/PMD file the dataset uses.

    Arrays: ``positions`` (N, 3) float32 and ``normals`` (N, 3) float32 in MMD units and frame;
    ``deform`` (N,) int8 index into :data:`DEFORM_NAMES`; ``weight_bones`` (N, 4) int32 (-1
    unused) and ``weight_values`` (N, 4) float32 as stored (BDEF2 and SDEF hold w, 1-w);
    ``sdef_vertices`` (S,) int64 the SDEF vertices and ``sdef`` (S, 3, 3) float32 their C, R0, R1
    points (MMD units and frame); ``faces`` (M, 3) int64 as stored (MMD's clockwise front faces).
    """

    format: str  # "PMX 2.0", "PMX 2.1", "PMD 1.0"
    name: str
    name_en: str
    comment: str
    positions: np.ndarray
    normals: np.ndarray
    deform: np.ndarray
    weight_bones: np.ndarray
    weight_values: np.ndarray
    faces: np.ndarray
    bones: list[MMDBone]
    rigid_bodies: list[MMDRigidBody] = field(default_factory=list)
    joints: list[MMDJoint] = field(default_factory=list)
    num_materials: int = 0
    num_morphs: int = 0
    morph_names: list[str] = field(default_factory=list)
    sdef_vertices: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    sdef: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3), np.float32))
