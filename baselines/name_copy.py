"""``name_copy``: carry each source bone's pose over to the target bone of the same name.

The source's transforms are estimated from its posed vertices (weighted Kabsch). A target bone
with a same-named source bone takes that bone's world rotation and, when its parent is the
same-named bone's parent too, its translation relative to the parent beyond the rest offset
(a body bone the clip moves, IK-driven feet), scaled by the ratio of sizes (largest rest
extents); the root takes the same-named bone's displacement, scaled likewise. Target bones with
no same-named source bone keep their rest orientation relative to their parent. This is the
same-skeleton ground-truth rule (:mod:`benchmark.protocols.h2h`) applied to estimated
transforms, so it is exact up to estimation error on a shared skeleton.
"""
from __future__ import annotations

import numpy as np

from baselines.posing import inherit_unmatched, size_ratio, source_pose
from benchmark.method import MethodMetadata, PoseTransferMethod
from benchmark.protocols.h2h import local_translations, transforms_from_local
from mimicbench.kinematics import local_from_global, transforms_to_array
from mimicbench.skinning import linear_blend_skinning


class NameCopy(PoseTransferMethod):
    metadata = MethodMetadata(name="name_copy", version="3", licence="MIT",
                              description="rotations and local translations copied between bones of the same name")

    def transfer(self, requests):
        return [self._one(r) for r in requests]

    @staticmethod
    def _one(r):
        src, tgt = r.source, r.target
        q_src, t_src = source_pose(r)
        ratio = size_ratio(r)
        moved_src = local_translations(transforms_to_array(q_src, t_src), src.keypoints, src.parents) * ratio
        index = {n: i for i, n in enumerate(src.bone_names)}
        src_root = int(np.flatnonzero(src.parents < 0)[0])
        kt = len(tgt.parents)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (kt, 1))
        moved = np.zeros((kt, 3))
        matched = np.zeros(kt, bool)
        for j, name in enumerate(tgt.bone_names):
            i = index.get(name)
            pj = tgt.parents[j]
            if pj < 0:  # a root moves as its same-named bone, else as the source's first root
                moved[j] = (t_src[src_root if i is None else i] - src.keypoints[src_root if i is None else i]) * ratio
            if i is None:
                continue
            q[j], matched[j] = q_src[i], True
            if pj >= 0 and src.parents[i] >= 0 and tgt.bone_names[pj] == src.bone_names[src.parents[i]]:
                moved[j] = moved_src[i]
        q = inherit_unmatched(q, matched, tgt.parents)
        transforms = transforms_from_local(local_from_global(q, tgt.parents), moved, tgt.keypoints, tgt.parents)
        return linear_blend_skinning(tgt.vertices, tgt.keypoints, tgt.weights, transforms).astype(np.float32)
