"""Relaxation frames: from the rest pose into a clip's first pose, simulated and then dropped.

MMD relaxes physics by blending into the first pose over some frames (MMDMC holds the first pose
about 100 frames and drops the first 30). Here the body blends from rest into the first pose over
the first half of ``n`` frames (smoothstep in time: slerp of rotations, lerp of positions) and
holds it for the second half, so the apparel settles before frame 0 is recorded.
"""
from __future__ import annotations

import numpy as np

from mimicbench.kinematics import rest_transforms
from mimicbench.quaternion import quat_normalize, quat_slerp


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


def relax_frames(rest_keypoints: np.ndarray, first: np.ndarray, n: int) -> np.ndarray:
    """(n, K, 7) float64 body poses leading from rest into ``first`` (K, 7); n = 0 gives none."""
    rest = rest_transforms(rest_keypoints).astype(np.float64)
    blend = max(1, n // 2)
    frames = []
    for i in range(n):
        x = min(1.0, (i + 1) / blend)
        frames.append(blend_poses(rest, first, x * x * (3 - 2 * x)))
    return np.stack(frames) if frames else np.zeros((0,) + rest.shape)
