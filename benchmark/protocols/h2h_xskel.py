"""``h2h_xskel``: humanoid-to-humanoid transfer across skeleton families, against ground truth.

Cases: ordered pairs of humanoids (``apparel`` characters count as humanoids) that both carry
hidden role labels and do NOT share a skeleton (different ``skeleton_id``: other bone names,
counts and proportions, e.g. a Mixamo rig and a Biped rig). On the shared-skeleton ``h2h`` a
method that copies rotations by bone name is at the ground truth's own rule; here names differ,
so it is not.

Ground truth (:func:`cross_skeleton_ground_truth`): the source's pose carried over through the
hidden roles, by the same rule as ``h2h``: each target bone takes the local rotation of its
role match (:func:`mimicbench.benchmark.role_match.match_by_role`: same role, else same role class at the
nearest position along the class by skin-weight mass), a bone without a match (an extra spine bone, a finger
the source lacks, apparel) keeps its rest rotation relative to its parent, and the root's
displacement from rest is scaled by the size ratio.

Scores are ``h2h``'s, with the placement-free headline (see :mod:`mimicbench.benchmark.protocols.h2h`).
"""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.normalisation import size_ratio
from mimicbench.benchmark.protocols.base import CasePool
from mimicbench.benchmark.protocols.h2h import SameSkeleton, local_translations, transforms_from_local
from mimicbench.benchmark.role_match import bone_mass, match_by_role
from mimicbench.benchmark.semantic import character_role_classes
from mimicbench.geometry.kinematics import array_to_transforms, local_from_global
from mimicbench.schemas.character import HUMANOID_LIKE


def cross_skeleton_ground_truth(source, target, source_transforms: np.ndarray) -> np.ndarray:
    """Ground-truth target transforms (Kt, 7) for a source pose (Ks, 7) across skeletons.

    Args:
        source, target: character records with ``bone_roles``, ``parents``, ``keypoints``,
            ``weights``, ``vertices`` and ``category``.
        source_transforms: (Ks, 7) the source's pose.
    """
    s_cls, t_cls = character_role_classes(source), character_role_classes(target)
    if s_cls is None or t_cls is None:
        raise ValueError(f"cross-skeleton ground truth: {source.character_id} or {target.character_id} has no "
                         "role labels (bone_roles)")
    match = match_by_role(list(source.bone_roles), s_cls, source.parents, bone_mass(source),
                          list(target.bone_roles), t_cls, target.parents, bone_mass(target))
    t_parents = np.asarray(target.parents)
    q, _ = array_to_transforms(source_transforms)
    src_local = local_from_global(q, np.asarray(source.parents))
    local = np.tile([1.0, 0.0, 0.0, 0.0], (len(t_parents), 1))
    local[match >= 0] = src_local[match[match >= 0]]
    moved = np.zeros((len(t_parents), 3))
    s_roots = np.flatnonzero(np.asarray(source.parents) < 0)
    root_moved = local_translations(source_transforms, source.keypoints, source.parents)[s_roots[0]]
    moved[t_parents < 0] = root_moved * size_ratio(source.vertices, target.vertices)
    return transforms_from_local(local, moved, target.keypoints, t_parents)


class CrossSkeleton(SameSkeleton):
    name = "h2h_xskel"
    title = "humanoid-to-humanoid transfer across skeleton families, scored against role-retargeted ground truth"
    headline = "height"
    counts_as = "h2h"
    """A method that answers ``h2h`` requests answers these (same request, same ground-truth kind)."""

    def candidate_pairs(self, pool: CasePool) -> list[tuple]:
        humans = [c for c in pool.characters
                  if c.category in HUMANOID_LIKE and character_role_classes(c) is not None]
        return [(a, b) for a in humans for b in humans
                if a is not b and (a.skeleton_id != b.skeleton_id or not a.skeleton_id)]

    def ground_truth(self, source, target, source_transforms):
        """The role-retargeted ground truth (:func:`cross_skeleton_ground_truth`)."""
        return cross_skeleton_ground_truth(source, target, source_transforms)
