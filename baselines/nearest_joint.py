"""``nearest_joint``: match joints by rest position, copy rotations and local translations.

Rest keypoints of both characters are normalised to unit height (each by its own rest mesh),
matched one-to-one by the Hungarian algorithm on Euclidean distance, and each matched target bone
takes its source bone's global rotation, and its translation relative to its parent when the
parents are matched too (scaled by the size ratio); unmatched bones follow their parent. The
root moves like the source's root. Positions come from forward kinematics on the target's
skeleton.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from mimicbench.baselines.posing import carried_translations, inherit_unmatched, pose_target_local, size_ratio, source_pose
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.geometry.hungarian import hungarian_match
from mimicbench.geometry.mesh import normalize_unit_height


def nearest_joint_pairs(source, target) -> np.ndarray:
    """(P, 2) int (source bone, target bone) pairs: the Hungarian match of the two characters' rest
    keypoints, each normalised to unit height by its own rest mesh, on Euclidean distance."""
    ks = normalize_unit_height(source.keypoints, source.vertices)
    kt = normalize_unit_height(target.keypoints, target.vertices)
    pairs, _ = hungarian_match(cdist(ks, kt), maximize=False)
    return pairs


class NearestJoint(PoseTransferMethod):
    metadata = MethodMetadata(name="nearest_joint", version="5", licence="MIT",
                              description="Hungarian matching of unit-height rest joints")

    pairs = staticmethod(nearest_joint_pairs)
    """(source, target) -> (P, 2) bone pairs; a subclass may match otherwise."""

    def transfer(self, requests):
        return [self._one(r) for r in requests]

    def _one(self, r):
        q_src, t_src = source_pose(r)
        pairs = self.pairs(r.source, r.target)
        kt = r.target.keypoints
        q = np.tile([1.0, 0.0, 0.0, 0.0], (len(kt), 1))
        matched = np.zeros(len(kt), bool)
        q[pairs[:, 1]] = q_src[pairs[:, 0]]
        matched[pairs[:, 1]] = True
        q = inherit_unmatched(q, matched, r.target.parents)
        match = np.full(len(kt), -1)
        match[pairs[:, 1]] = pairs[:, 0]
        moved = carried_translations(r, q_src, t_src, match)
        src_root = int(np.flatnonzero(r.source.parents < 0)[0])
        moved[r.target.parents < 0] = (t_src[src_root] - r.source.keypoints[src_root]) * size_ratio(r)
        return pose_target_local(r.target, q, moved)
