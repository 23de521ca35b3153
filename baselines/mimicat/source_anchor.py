"""The source keypoints MimiCAT's structured initialisation reads translations from.

The structured initialisation (:func:`mimicbench.baselines.mimicat.initialisation.structured_pose`)
carries each source bone's local translation (its keypoint's offset from its parent beyond the
rest offset) to the matched target bone, and the source root's displacement to the target's root.
Both are only meaningful where the mesh determines the parent's keypoint. The shared read-off
(:func:`mimicbench.geometry.pose_readoff.read_pose`) completes a bone the mesh does not determine
(no skin weight: a rig's ``root`` or ``Body``) rigidly from its parent, and leaves such a root at
its rest position. On a rig whose weightless root carries the clip's motion (artist rigs such as
the shared RobotExpressive and Quaternius dinosaurs), the body's whole displacement and the
mismatch of the completed rotation then read as local translations of the weighted bones below
the root, half the character's height on some frames; carried to a target bone whose parent owns
vertices, they tear the target's mesh apart.

:func:`anchor_source_keypoints` re-places the keypoints so that:

- a bone whose parent the mesh does not determine carries no local translation (the stretch
  between a weightless parent and its child is not visible on the mesh);
- a root the mesh does not determine is displaced by the skin-weighted mean of what its topmost
  determined descendants' local translations would have moved them (the whole body's motion),
  so the displacement moves the target's root instead of one target bone;
- every other bone keeps its local translation as read.

Rotations are not changed. On a rig whose every bone is determined (every zoo character) the
keypoints are returned unchanged.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import quat_apply
from mimicbench.geometry.validation import check_parents


def anchor_source_keypoints(q: np.ndarray, t: np.ndarray, rest: np.ndarray, parents: np.ndarray,
                            supported: np.ndarray, weight_below: np.ndarray) -> np.ndarray:
    """Source keypoints (K, 3) float64 re-placed as the module docstring says.

    Args:
        q: (K, 4) read-off global rotations (w, x, y, z), rest-relative.
        t: (K, 3) read-off posed keypoints, metres.
        rest: (K, 3) rest keypoints, metres.
        parents: (K,) parent indices, -1 for a root, in the data contract's topological order
            (``parents[k] < k``), so index order visits every parent before its children.
        supported: (K,) bool, the bones the mesh determines (``PoseReadOff.supported``).
        weight_below: (K,) total skin weight of each bone and its descendants (vertices), the
            weight of a topmost determined bone in its root's displacement.
    """
    q, t, rest = (np.asarray(a, np.float64) for a in (q, t, rest))
    parents = check_parents(parents)
    supported = np.asarray(supported, bool)
    k_bones = len(parents)
    for name, a, shape in (("q", q, (k_bones, 4)), ("t", t, (k_bones, 3)), ("rest", rest, (k_bones, 3)),
                           ("supported", supported, (k_bones,)), ("weight_below", np.asarray(weight_below), (k_bones,))):
        if a.shape != shape:
            raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
    if supported.all():
        return t.copy()
    has_parent = parents >= 0
    par = np.where(has_parent, parents, 0)
    # each bone's local translation in its parent's frame, as the initialisation reads it
    local = np.zeros_like(t)
    rot_back = np.concatenate([q[par][:, :1], -q[par][:, 1:]], axis=1)
    local[has_parent] = (quat_apply(rot_back, t - t[par]) - (rest - rest[par]))[has_parent]
    root_of = np.empty(k_bones, int)
    all_above_unsupported = np.zeros(k_bones, bool)  # every ancestor of the bone is undetermined
    for k in range(k_bones):
        p = parents[k]
        root_of[k] = k if p < 0 else root_of[p]
        all_above_unsupported[k] = p >= 0 and not supported[p] and (parents[p] < 0 or all_above_unsupported[p])
    disp = {}
    for r in np.flatnonzero(~has_parent):
        if supported[r]:
            continue
        top = np.flatnonzero((root_of == r) & all_above_unsupported & supported)
        w = np.asarray(weight_below, np.float64)[top]
        if len(top) and w.sum() > 0:
            moved = quat_apply(q[parents[top]], local[top])  # (T, 3) world offset of each from rigid
            disp[r] = (w[:, None] * moved).sum(axis=0) / w.sum()
    out = np.empty_like(t)
    for k in range(k_bones):
        p = parents[k]
        if p < 0:
            out[k] = t[k] + disp.get(k, 0.0)
            continue
        carried = local[k] if supported[p] else 0.0
        out[k] = out[p] + quat_apply(q[p], rest[k] - rest[p] + carried)
    return out
