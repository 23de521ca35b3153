"""Procedural motion clips: rotation-vector curves per joint, turned into stored transforms.

A clip generator returns local rotations as rotation vectors (F, K, 3) (axis times angle in
radians, axes in the rest frame, since rotations are relative to rest) and a root offset (F, 3)
metres. :func:`clip_transforms` scales both by a ramp that is 0 at frame 0, so every clip starts
at the rest pose exactly, then runs :func:`mimicbench.geometry.kinematics.forward_kinematics`.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import Skeleton
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_from_axis_angle

FPS = 30.0
NUM_FRAMES = 45
MAX_FRAMES = 10_000  # frames a clip at most (about 5.5 minutes at 30 fps)
RAMP_FRAMES = 8


def ramp(num_frames: int, ramp_frames: int = RAMP_FRAMES) -> np.ndarray:
    """(F,) smoothstep from 0 at frame 0 to 1 at ``ramp_frames``."""
    x = np.clip(np.arange(num_frames) / ramp_frames, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def rotvec_to_quat(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) from rotation vectors (..., 3) (zero vector -> identity)."""
    angle = np.linalg.norm(rotvec, axis=-1)
    axis = np.where(angle[..., None] > 1e-12, rotvec, np.array([1.0, 0.0, 0.0]))
    return quat_from_axis_angle(axis, angle)


def clip_transforms(skel: Skeleton, rotvec: np.ndarray, root_offset: np.ndarray, use_ramp: bool = True) -> np.ndarray:
    """Stored transforms (F, K, 7) float32 of a clip.

    Args:
        skel: the skeleton (heads are the rest keypoints).
        rotvec: (F, K, 3) local rotations as rotation vectors, radians.
        root_offset: (F, 3) root translation from rest, metres.
        use_ramp: blend in from the rest pose over the first frames.
    """
    f = rotvec.shape[0]
    w = ramp(f) if use_ramp else np.ones(f)
    w[0] = 0.0
    local = rotvec_to_quat(rotvec * w[:, None, None])
    roots = np.repeat(skel.heads[None], f, axis=0)
    root = skel.parents < 0
    roots[:, root] += (root_offset * w[:, None])[:, None, :]
    g_rot, g_pos = forward_kinematics(local, skel.heads, skel.parents, roots)
    return transforms_to_array(g_rot, g_pos)


def random_poses(skel: Skeleton, rng: np.random.Generator, num_frames: int = NUM_FRAMES, key_every: int = 15,
                 scale: float = 0.8) -> np.ndarray:
    """Rotation vectors (F, K, 3): random keyframes within each joint's limit, smoothly blended.

    Keyframe 0 is the rest pose; each later key draws a uniform direction and an angle up to
    ``scale * limit``; frames between keys interpolate the rotation vectors with a smoothstep
    (a convex blend, so angles stay within the limits).
    """
    k = skel.num_joints
    nkeys = int(np.ceil((num_frames - 1) / key_every)) + 1
    d = rng.normal(size=(nkeys, k, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    keys = d * (rng.uniform(0, 1, size=(nkeys, k, 1)) * scale * skel.limits[None, :, None])
    keys[0] = 0.0
    t = np.arange(num_frames) / key_every
    i0 = np.minimum(np.floor(t).astype(int), nkeys - 2)
    x = np.clip(t - i0, 0, 1)
    x = x * x * (3 - 2 * x)
    return (1 - x)[:, None, None] * keys[i0] + x[:, None, None] * keys[i0 + 1]
