"""``name_copy``: copy each source bone's rotation to the target bone of the same name.

Source transforms are estimated from the posed source vertices (weighted Kabsch); target bones
with no same-named source bone keep their rest orientation relative to their parent; the root's
displacement is scaled by the ratio of sizes (largest rest extents). Exact up to estimation error
on a shared skeleton.
"""
from __future__ import annotations

import numpy as np

from baselines.posing import inherit_unmatched, pose_target, size_ratio, source_pose
from benchmark.method import MethodMetadata, PoseTransferMethod


class NameCopy(PoseTransferMethod):
    metadata = MethodMetadata(name="name_copy", version="2", licence="MIT",
                              description="rotations copied between bones of the same name")

    def transfer(self, requests):
        return [self._one(r) for r in requests]

    @staticmethod
    def _one(r):
        q_src, t_src = source_pose(r)
        index = {n: i for i, n in enumerate(r.source.bone_names)}
        kt = len(r.target.parents)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (kt, 1))
        matched = np.zeros(kt, bool)
        for j, name in enumerate(r.target.bone_names):
            if name in index:
                q[j] = q_src[index[name]]
                matched[j] = True
        q = inherit_unmatched(q, matched, r.target.parents)
        src_root = int(np.flatnonzero(r.source.parents < 0)[0])
        tgt_root_name = r.target.bone_names[int(np.flatnonzero(r.target.parents < 0)[0])]
        k = index.get(tgt_root_name, src_root)
        disp = (t_src[k] - r.source.keypoints[k]) * size_ratio(r)
        return pose_target(r.target, q, disp)
