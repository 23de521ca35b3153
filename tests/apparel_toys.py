"""A hand-built character for the apparel tests: a box torso with one 4-link chain hanging beside it.

Everything here is written out by hand (trimesh primitives, one-hot weights, poses by explicit
rotation about Y), so tests compare the simulation against numbers that do not come from the
stage's own code.
"""
from __future__ import annotations

import numpy as np
import trimesh

from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.motion import MotionRecord

TORSO_HEAD = np.array([0.0, 1.0, 0.0])
CHAIN_X = 0.25
LINK = 0.1
LINKS = 4


def chain_heads(horizontal: bool = False) -> np.ndarray:
    """(4, 3) rest heads of the chain bones: x = 0.25, from y = 1.0 down in 0.1 m steps (or along +X)."""
    if horizontal:
        return np.array([[CHAIN_X + i * LINK, 1.0, 0.0] for i in range(LINKS)])
    return np.array([[CHAIN_X, 1.0 - i * LINK, 0.0] for i in range(LINKS)])


def make_character(character_id: str = "toy/pendulum", horizontal: bool = False) -> CharacterRecord:
    """Bone 0 ``torso`` (a 0.3 x 0.4 x 0.2 m box above y = 1.0), bones 1-4 ``skirt_1..4`` (apparel),
    hanging down from (0.25, 1, 0) or, with ``horizontal``, sticking out along +X."""
    box = trimesh.creation.box(extents=(0.3, 0.4, 0.2))
    box.apply_translation([0.0, 1.2, 0.0])
    verts, faces, owner = [box.vertices], [box.faces], [np.zeros(len(box.vertices), int)]
    offset = len(box.vertices)
    for i, head in enumerate(chain_heads(horizontal)):
        cyl = trimesh.creation.cylinder(radius=0.02, height=LINK, sections=12)
        if horizontal:
            cyl.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))  # Z -> X
            cyl.apply_translation(head + [LINK / 2, 0.0, 0.0])
        else:
            cyl.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))  # Z -> Y
            cyl.apply_translation(head + [0.0, -LINK / 2, 0.0])
        verts.append(cyl.vertices)
        faces.append(cyl.faces + offset)
        owner.append(np.full(len(cyl.vertices), i + 1))
        offset += len(cyl.vertices)
    v = np.concatenate(verts).astype(np.float32)
    f = np.concatenate(faces).astype(np.int32)
    own = np.concatenate(owner)
    idx = np.zeros((len(v), 8), np.int32)
    val = np.zeros((len(v), 8), np.float32)
    idx[:, 0], val[:, 0] = own, 1.0
    keypoints = np.concatenate([TORSO_HEAD[None], chain_heads(horizontal)]).astype(np.float32)
    bones = np.array([False] + [True] * LINKS)
    return CharacterRecord(
        character_id=character_id, category="apparel", source="test", split="train", vertices=v, faces=f,
        keypoints=keypoints, parents=np.array([-1, 0, 1, 2, 3], np.int32),
        bone_names=["torso"] + [f"skirt_{i + 1}" for i in range(LINKS)], weight_indices=idx, weight_values=val,
        apparel_vertex_mask=bones[own], apparel_bone_mask=bones, bone_roles=None, skeleton_id=None,
        height=float(np.ptp(v[:, 1])), meta={})


def turn_about_y(angles: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """(F, K, 7) float32: every bone rotated rigidly by ``angles[f]`` about the Y axis through the torso head."""
    frames = []
    for a in angles:
        q = np.array([np.cos(a / 2), 0.0, np.sin(a / 2), 0.0])
        c, s = np.cos(a), np.sin(a)
        rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        t = (np.asarray(keypoints, np.float64) - TORSO_HEAD) @ rot.T + TORSO_HEAD
        frames.append(np.concatenate([np.tile(q, (len(keypoints), 1)), t], axis=1))
    return np.array(frames, np.float32)


def make_motion(record: CharacterRecord, angles: np.ndarray, name: str = "turn", fps: float = 30.0) -> MotionRecord:
    transforms = turn_about_y(angles, record.keypoints)
    return MotionRecord(motion_id=f"{record.character_id}/{name}", character_id=record.character_id, name=name,
                        split=record.split, fps=fps, num_frames=len(angles), num_joints=len(record.parents),
                        transforms=transforms, source="test")


def quick_turn(frames: int = 60, turn_frames: int = 4) -> np.ndarray:
    """Angles (F,): a quarter turn in ``turn_frames`` frames, then held."""
    return np.minimum(np.arange(frames) / turn_frames, 1.0) * (np.pi / 2)
