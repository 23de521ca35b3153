"""Shared steps of the skeleton-driven baselines: read the source's pose off its posed
vertices, and pose a target from per-bone global rotations."""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.request import Rig, TransferRequest
from mimicbench.geometry.kinematics import forward_kinematics, local_from_global, transforms_to_array
from mimicbench.geometry.pose_readoff import read_rig_pose
from mimicbench.geometry.skinning import linear_blend_skinning


def source_pose(request: TransferRequest) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (Ks, 4) and posed keypoint positions (Ks, 3) of the posed source.

    Read off the posed source vertices by the joint fit of all bones, with the bones the mesh does
    not determine completed from the skeleton (:func:`mimicbench.geometry.pose_readoff.read_pose`, the read-off
    every skeleton method and the protocols share).
    """
    pose = read_rig_pose(request.source, request.source_posed)
    return pose.rotations, pose.positions


def size_ratio(request: TransferRequest) -> float:
    """Target size / source size: the rest meshes' largest bounding-box sides (the benchmark's
    size, :func:`mimicbench.benchmark.normalisation.size_ratio`). Heights would not do: a snake's height is
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


def carried_translations(request: TransferRequest, q_src: np.ndarray, t_src: np.ndarray,
                         match: np.ndarray) -> np.ndarray:
    """Local translations (Kt, 3) for the target's bones from a one-to-one bone match.

    ``match[j]`` is the source bone of target bone j, or -1. A root takes its match's
    displacement from rest (the source's first root's when unmatched); another bone takes its
    match's translation relative to its parent beyond the rest offset (see
    :func:`mimicbench.benchmark.protocols.h2h.local_translations`) when its parent is matched to that
    bone's parent, else none. All scaled by :func:`size_ratio`.
    """
    from mimicbench.benchmark.protocols.h2h import local_translations

    src, tgt = request.source, request.target
    ratio = size_ratio(request)
    moved_src = local_translations(transforms_to_array(q_src, t_src), src.keypoints, src.parents) * ratio
    src_root = int(np.flatnonzero(src.parents < 0)[0])
    moved = np.zeros((len(tgt.parents), 3))
    for j, p in enumerate(tgt.parents):
        i = int(match[j])
        if p < 0:
            k = src_root if i < 0 else i
            moved[j] = (t_src[k] - src.keypoints[k]) * ratio
        elif i >= 0 and src.parents[i] >= 0 and match[p] == src.parents[i]:
            moved[j] = moved_src[i]
    return moved


def pose_target_local(target: Rig, global_rotations: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """Target vertices (Nt, 3) float32 posed by global rotations (Kt, 4) and local translations
    (Kt, 3) (:func:`carried_translations`) via forward kinematics and LBS."""
    from mimicbench.benchmark.protocols.h2h import transforms_from_local

    transforms = transforms_from_local(local_from_global(global_rotations, target.parents), moved,
                                       target.keypoints, target.parents)
    return linear_blend_skinning(target.vertices, target.keypoints, target.weights, transforms).astype(np.float32)
