"""``name_copy``: carry each source bone's pose over to the target bone of the same name.

The source's transforms are read off its posed vertices (the shared joint fit,
:func:`mimicbench.baselines.posing.source_pose`). A target bone
with a same-named source bone takes that bone's world rotation and, when its parent is the
same-named bone's parent too, its translation relative to the parent beyond the rest offset
(a body bone the clip moves, IK-driven feet), scaled by the ratio of sizes (largest rest
extents); a root takes the same-named bone's displacement (else the source root's), scaled
likewise. Target bones with no same-named source bone keep their rest orientation relative to
their parent. This is the same-skeleton ground-truth rule (:mod:`mimicbench.benchmark.protocols.h2h`)
applied to estimated transforms, so it is exact up to estimation error on a shared skeleton
(real assets with translated bones: PMD 0.57 where rotations alone gave 16.3).
"""
from __future__ import annotations

import numpy as np

from mimicbench.baselines.posing import carried_translations, inherit_unmatched, pose_target_local, source_pose
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod


class NameCopy(PoseTransferMethod):
    metadata = MethodMetadata(name="name_copy", version="5", licence="MIT",
                              description="rotations and local translations copied between bones of the same name")

    def transfer(self, requests):
        return [self._one(r) for r in requests]

    @staticmethod
    def _one(r):
        q_src, t_src = source_pose(r)
        index = {n: i for i, n in enumerate(r.source.bone_names)}
        match = np.array([index.get(n, -1) for n in r.target.bone_names])
        q = np.tile([1.0, 0.0, 0.0, 0.0], (len(match), 1))
        q[match >= 0] = q_src[match[match >= 0]]
        q = inherit_unmatched(q, match >= 0, r.target.parents)
        return pose_target_local(r.target, q, carried_translations(r, q_src, t_src, match))
