"""Rigid bodies and joints for a character's apparel chains, in MMD's style, for characters that
have none (the zoo's): a dynamic capsule along every apparel bone, a static capsule on the body
bone each chain hangs from, and a spring joint from each body to its parent bone's body.

Capsule radius 15% of the bone's length (at least 1 cm), cylinder the bone's length; joints allow
+-0.5 rad of swing and +-0.2 rad of twist with rotational springs; apparel bodies collide with
everything but apparel (group 2) and static ones with everything. Written into PMX by
:mod:`mimicbench.datagen.mmd.pmx_writer`, they bring the apparel back when the file is ingested.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.retarget.retarget import rotation_between
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

APPAREL_GROUP, BODY_GROUP = 2, 0


def _bone_axis(keypoints: np.ndarray, parents: np.ndarray, k: int) -> tuple[np.ndarray, float]:
    """A bone's direction and length: towards its first child, else continuing its parent's."""
    children = np.flatnonzero(parents == k)
    if len(children):
        d = keypoints[children[0]] - keypoints[k]
    elif parents[k] >= 0:
        d = 0.5 * (keypoints[k] - keypoints[parents[k]])
    else:
        d = np.array([0.0, 0.05, 0.0])
    n = float(np.linalg.norm(d))
    return (d / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])), max(n, 1e-3)


def chain_physics(character) -> tuple[list[RigidBodyRecord], list[JointRecord]]:
    """Bodies and joints for ``character``'s apparel bones (``apparel_bone_mask``); none without."""
    kp = np.asarray(character.keypoints, np.float64)
    parents = np.asarray(character.parents)
    apparel = [int(k) for k in np.flatnonzero(character.apparel_bone_mask)]
    anchors = sorted({int(parents[k]) for k in apparel if parents[k] >= 0 and not character.apparel_bone_mask[parents[k]]})
    bodies, joints, body_of = [], [], {}
    for k in anchors + apparel:
        dynamic = bool(character.apparel_bone_mask[k])
        axis, length = _bone_axis(kp, parents, k)
        radius = max(0.15 * length, 0.01)
        body_of[k] = len(bodies)
        bodies.append(RigidBodyRecord(
            character.character_id, len(bodies), character.bone_names[k], "", k, "capsule",
            np.float32([radius, length, 0.0]), (kp[k] + 0.5 * length * axis).astype(np.float32),
            rotation_between([0.0, 1.0, 0.0], axis).astype(np.float32), 1.0 if dynamic else 0.0, 0.5, 0.5, 0.0, 0.5,
            APPAREL_GROUP if dynamic else BODY_GROUP, 0xFFFF & ~(1 << APPAREL_GROUP) if dynamic else 0xFFFF,
            "dynamic" if dynamic else "static"))
    for k in apparel:
        p = int(parents[k])
        if p in body_of:
            joints.append(JointRecord(
                character.character_id, len(joints), character.bone_names[k], "", "spring_6dof", body_of[p],
                body_of[k], kp[k].astype(np.float32), np.float32([1, 0, 0, 0]), np.zeros(3, np.float32),
                np.zeros(3, np.float32), np.float32([-0.5, -0.2, -0.5]), np.float32([0.5, 0.2, 0.5]),
                np.zeros(3, np.float32), np.float32([50, 50, 50])))
    return bodies, joints
