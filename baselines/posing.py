"""Shared steps of the skeleton-driven baselines: read the source's pose off its posed
vertices, and pose a target from per-bone global rotations."""
from __future__ import annotations

import numpy as np

from benchmark.request import Rig, TransferRequest
from mimicbench.kinematics import array_to_transforms, forward_kinematics, local_from_global, transforms_to_array
from mimicbench.quaternion import quat_angle, quat_apply
from mimicbench.rotation_average import weighted_quaternion_average
from mimicbench.skinning import linear_blend_skinning
from mimicbench.transform_estimation import estimate_transforms
from schemas.weights import as_dense


AGREE_DEGREES = 20.0
"""Children's rotations that agree within this many degrees give a bone without vertices its rotation
(:func:`source_pose`)."""


def source_pose(request: TransferRequest) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (Ks, 4) and posed keypoint positions (Ks, 3) of the posed source.

    Estimated per keypoint by weighted Kabsch. A keypoint that owns no vertices cannot be read off
    the mesh: when at least two of its children have vertices at or below them and their global
    rotations agree within :data:`AGREE_DEGREES`, it takes their average (weighted by the skin
    weight at and below each child; children are read first), since what it turns is what hangs
    below it (a rig's ``Body`` that carries a clip's whole-body turn); otherwise it inherits its
    parent's rotation. Either way it follows its parent rigidly (a root keeps its rest position).
    Rigs whose every keypoint owns vertices (every zoo character) read exactly as by Kabsch.
    """
    s = request.source
    transforms, owned = estimate_transforms(s.vertices, request.source_posed, s.weights, s.keypoints)
    q, t = array_to_transforms(transforms)
    if not owned.all():
        q = _rotations_from_children(q, owned, s)
    for k, p in enumerate(s.parents):
        if not owned[k] and p >= 0:
            t[k] = t[p] + quat_apply(q[p], s.keypoints[k] - s.keypoints[p])
    return q, t


def _rotations_from_children(q: np.ndarray, owned: np.ndarray, rig: Rig) -> np.ndarray:
    """Rotations (K, 4) of the keypoints that own no vertices (``owned`` (K,) False), by
    :func:`source_pose`'s rule, from the read-off ``q`` (K, 4) of the others."""
    parents = np.asarray(rig.parents)
    below = as_dense(rig.weights, len(parents)).sum(axis=0).astype(np.float64)  # skin weight at and below
    for k in range(len(parents) - 1, -1, -1):  # parents come before children
        if parents[k] >= 0:
            below[parents[k]] += below[k]
    q = np.array(q, dtype=np.float64)
    known, from_children = owned.copy(), np.zeros(len(parents), bool)
    for k in range(len(parents) - 1, -1, -1):
        if owned[k]:
            continue
        kids = np.flatnonzero((parents == k) & known & (below > 0))
        if len(kids) >= 2 and np.degrees(quat_angle(q[kids][:, None], q[kids][None])).max() <= AGREE_DEGREES:
            q[k] = weighted_quaternion_average(q[kids], below[kids][:, None])[0]
            known[k] = from_children[k] = True
    for k, p in enumerate(parents):
        if not owned[k] and not from_children[k] and p >= 0:
            q[k] = q[p]
    return q


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


def carried_translations(request: TransferRequest, q_src: np.ndarray, t_src: np.ndarray,
                         match: np.ndarray) -> np.ndarray:
    """Local translations (Kt, 3) for the target's bones from a one-to-one bone match.

    ``match[j]`` is the source bone of target bone j, or -1. A root takes its match's
    displacement from rest (the source's first root's when unmatched); another bone takes its
    match's translation relative to its parent beyond the rest offset (see
    :func:`benchmark.protocols.h2h.local_translations`) when its parent is matched to that
    bone's parent, else none. All scaled by :func:`size_ratio`.
    """
    from benchmark.protocols.h2h import local_translations

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
    from benchmark.protocols.h2h import transforms_from_local

    transforms = transforms_from_local(local_from_global(global_rotations, target.parents), moved,
                                       target.keypoints, target.parents)
    return linear_blend_skinning(target.vertices, target.keypoints, target.weights, transforms).astype(np.float32)
