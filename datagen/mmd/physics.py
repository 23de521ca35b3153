"""An MMD model's rigid bodies and joints as dataset records, in the dataset's frame.

Positions are scaled and mirrored (:mod:`mimicbench.datagen.mmd.frame`); orientations are MMD's Euler
angles (R = Ry Rx Rz), mirrored, as quaternions; joint limits are expressed in the joint's own
frame, where the mirror negates local z translations and x, y rotations, so those intervals are
swapped and negated; sizes are scaled; spring stiffness, mass, damping, restitution, friction and
collision filters are kept as stored.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.mmd import frame
from mimicbench.datagen.mmd.model import MMDModel, MODE_NAMES, SHAPE_NAMES
from mimicbench.schemas.joint import KINDS, JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord


def body_size(shape: int, size: np.ndarray, scale: float) -> np.ndarray:
    """(3,) metres: sphere (r, 0, 0), box half extents, capsule (r, h, 0)."""
    s = np.asarray(size, np.float64) * scale
    keep = {0: [1, 0, 0], 1: [1, 1, 1], 2: [1, 1, 0]}[shape]
    return (s * keep).astype(np.float32)


def physics_records(model: MMDModel, character_id: str, new_index: np.ndarray,
                    scale: float = frame.MMD_UNIT_METRES) -> tuple[list[RigidBodyRecord], list[JointRecord]]:
    """Rigid-body and joint records of ``model``; ``new_index`` (K,) maps file bone indices to the
    character's bone order (see :func:`mimicbench.datagen.mmd.records.topological_order`)."""
    bodies = []
    for i, rb in enumerate(model.rigid_bodies):
        bodies.append(RigidBodyRecord(
            character_id=character_id, body_index=i, name=rb.name, name_en=rb.name_en,
            bone=int(new_index[rb.bone]) if rb.bone >= 0 else -1, shape=SHAPE_NAMES[rb.shape],
            size=body_size(rb.shape, rb.size, scale), position=frame.point(rb.position, scale).astype(np.float32),
            rotation=frame.euler_yxz_to_quat(frame.euler(rb.rotation)).astype(np.float32), mass=rb.mass,
            linear_damping=rb.linear_damping, angular_damping=rb.angular_damping, restitution=rb.restitution,
            friction=rb.friction, collision_group=int(rb.group), collision_mask=int(rb.mask), mode=MODE_NAMES[rb.mode]))
    joints = []
    for i, j in enumerate(model.joints):
        tlo, thi = frame.interval(j.translation_min, j.translation_max, frame.MIRROR)
        rlo, rhi = frame.interval(j.rotation_min, j.rotation_max, frame.ANGLE_MIRROR)
        joints.append(JointRecord(
            character_id=character_id, joint_index=i, name=j.name, name_en=j.name_en, kind=KINDS[j.kind],
            body_a=int(j.body_a), body_b=int(j.body_b), position=frame.point(j.position, scale).astype(np.float32),
            rotation=frame.euler_yxz_to_quat(frame.euler(j.rotation)).astype(np.float32),
            translation_min=(tlo * scale).astype(np.float32), translation_max=(thi * scale).astype(np.float32),
            rotation_min=rlo.astype(np.float32), rotation_max=rhi.astype(np.float32),
            spring_translation=np.asarray(j.spring_translation, np.float32),
            spring_rotation=np.asarray(j.spring_rotation, np.float32)))
    return bodies, joints
