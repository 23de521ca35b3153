"""Shared steps of the skeleton-driven baselines: read the source's pose off its posed
vertices, and pose a target from per-bone global rotations."""
from __future__ import annotations

import numpy as np

from benchmark.request import Rig, TransferRequest
from mimicbench.kinematics import array_to_transforms, forward_kinematics, local_from_global, transforms_to_array
from mimicbench.quaternion import quat_apply
from mimicbench.skinning import linear_blend_skinning
from mimicbench.transform_estimation import estimate_transforms


def source_pose(request: TransferRequest) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (Ks, 4) and posed keypoint positions (Ks, 3) of the posed source.

    Estimated per keypoint by weighted Kabsch; a keypoint that owns no vertices inherits its
    parent's rotation and follows it rigidly.
    """
    s = request.source
    transforms, owned = estimate_transforms(s.vertices, request.source_posed, s.weights, s.keypoints)
    q, t = array_to_transforms(transforms)
    for k, p in enumerate(s.parents):
        if not owned[k] and p >= 0:
            q[k] = q[p]
            t[k] = t[p] + quat_apply(q[p], s.keypoints[k] - s.keypoints[p])
    return q, t


def size_ratio(request: TransferRequest) -> float:
    """Target size / source size: the rest meshes' largest bounding-box sides (the benchmark's
    size, :func:`benchmark.normalisation.size_ratio`). Heights would not do: a snake's height is
    its thickness, so a humanoid's steps would shrink 30-fold on it and a snake's grow 30-fold on
    a humanoid."""
    return request.target.size / request.source.size


def pose_target(target: Rig, global_rotations: np.ndarray, root_displacement: np.ndarray) -> np.ndarray:
    """Target vertices (Nt, 3) float32 posed by global rotations (Kt, 4) via FK and LBS.

    Args:
        target: the target rig.
        global_rotations: (Kt, 4) rest-relative world rotations of the target's bones.
        root_displacement: (3,) displacement of every root from its rest position, metres.
    """
    local = local_from_global(global_rotations, target.parents)
    roots = target.parents < 0
    root_pos = np.array(target.keypoints, dtype=np.float64)
    root_pos[roots] += root_displacement
    g_rot, g_pos = forward_kinematics(local, target.keypoints, target.parents, root_pos)
    return linear_blend_skinning(target.vertices, target.keypoints, target.weights, transforms_to_array(g_rot, g_pos))


def inherit_unmatched(global_rotations: np.ndarray, matched: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Give each unmatched bone its parent's global rotation (identity relative to the parent)."""
    q = np.array(global_rotations, dtype=np.float64)
    for k, p in enumerate(parents):
        if not matched[k]:
            q[k] = q[p] if p >= 0 else np.array([1.0, 0.0, 0.0, 0.0])
    return q
