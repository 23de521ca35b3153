"""Relaxation frames: from the rest pose into a clip's first pose, simulated and then dropped.

MMD relaxes physics by blending into the first pose over some frames (MMDMC holds the first pose
about 100 frames and drops the first 30). Here the body blends from rest into the first pose over
the first half of ``n`` frames (smoothstep in time: slerp of rotations, lerp of positions) and
holds it for the second half, so the apparel settles before frame 0 is recorded.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.geometry.quaternion import quat_normalize, quat_slerp


def blend_poses(a: np.ndarray, b: np.ndarray, s) -> np.ndarray:
    """Poses between poses a and b (K, 7): slerp rotations, lerp positions.

    ``s`` in [0, 1]: a float gives one pose (K, 7) float64, an array (S,) gives (S, K, 7).
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    s = np.asarray(s, np.float64)
    w = s[..., None, None]  # (..., 1, 1)
    q = quat_slerp(quat_normalize(a[:, :4]), quat_normalize(b[:, :4]), s[..., None])
    return np.concatenate([q, (1 - w) * a[:, 4:] + w * b[:, 4:]], axis=-1)


def substep_poses(previous: np.ndarray, poses: np.ndarray, substeps: int) -> np.ndarray:
    """The body poses of every physics step of frames ``poses`` (F, K, 7): frame f's ``substeps``
    steps blend (:func:`blend_poses`) from frame f - 1 (``previous`` (K, 7) before the first)
    into frame f, the last one at frame f itself. Returns (F * substeps, K, 7) float64; the same
    numbers as :func:`blend_poses` frame by frame, computed at once.
    """
    b = np.asarray(poses, np.float64)
    a = np.concatenate([np.asarray(previous, np.float64)[None], b[:-1]])  # (F, K, 7)
    s = np.arange(1, substeps + 1) / substeps  # (S,)
    w = s[:, None, None]  # (S, 1, 1)
    q = quat_slerp(quat_normalize(a[:, None, :, :4]), quat_normalize(b[:, None, :, :4]), s[:, None])
    t = (1 - w) * a[:, None, :, 4:] + w * b[:, None, :, 4:]
    return np.concatenate([q, t], axis=-1).reshape((-1,) + b.shape[1:])


def relax_frames(rest_keypoints: np.ndarray, first: np.ndarray, n: int) -> np.ndarray:
    """(n, K, 7) float64 body poses leading from rest into ``first`` (K, 7); n = 0 gives none."""
    rest = rest_transforms(rest_keypoints).astype(np.float64)
    blend = max(1, n // 2)
    frames = []
    for i in range(n):
        x = min(1.0, (i + 1) / blend)
        frames.append(blend_poses(rest, first, x * x * (3 - 2 * x)))
    return np.stack(frames) if frames else np.zeros((0,) + rest.shape)
