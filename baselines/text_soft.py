"""``text_soft``: MimiCAT's initialisation without its learned refinement.

A soft correspondence M (Ks, Kt) between the source's and the target's bones comes from bone
names (the pair's ``m_sink`` from the dataset's ``pairs/`` table when the evaluator passes it,
else computed on the fly by the correspond stage's text encoder). Each target bone's rotation is
the M-weighted rotation average of the source bones (Eq. 4); the target root's displacement is
the M-weighted average of the source keypoints' displacements (the translation part of Eq. 3),
scaled by the ratio of sizes (largest rest extents); joint positions follow by forward
kinematics on the target.

Version 2 scales by sizes instead of heights: a height ratio made a snake's slither 30 times
longer on a humanoid and the return leg's error 30 times larger, so cycle PMD on the demo read
62.2 against identity's 61.1 (reptile sources 250-335).
"""
from __future__ import annotations

import numpy as np

from baselines.posing import pose_target, size_ratio, source_pose
from benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.rotation_average import weighted_quaternion_average


class TextSoft(PoseTransferMethod):
    metadata = MethodMetadata(
        name="text_soft", version="2", licence="MIT",
        description="Sinkhorn soft matching of bone-name embeddings, rotation averaging (Eq. 4)",
        citation="MimiCAT initialisation: S_cos of CLIP/MiniLM bone-name embeddings, Sinkhorn, Eq. 3-4",
    )

    def __init__(self, encoder: str = "minilm", temperature: float | None = None):
        self.encoder = encoder
        self.temperature = temperature
        self._cache: dict[tuple, np.ndarray] = {}

    def transfer(self, requests):
        return [self._one(r) for r in requests]

    def soft_correspondence(self, r) -> np.ndarray:
        """(Ks, Kt) soft matching for the request's two skeletons."""
        if "m_sink" in r.extras:
            return np.asarray(r.extras["m_sink"], dtype=np.float64)
        key = (r.source.bone_names, r.target.bone_names)
        if key not in self._cache:
            from datagen.correspond import correspondence_for_names

            kwargs = {"encoder": self.encoder}
            if self.temperature is not None:
                kwargs["temperature"] = self.temperature
            _, _, m_sink = correspondence_for_names(list(r.source.bone_names), list(r.target.bone_names), **kwargs)
            self._cache[key] = np.asarray(m_sink, dtype=np.float64)
        return self._cache[key]

    def _one(self, r):
        m = self.soft_correspondence(r)
        ks, kt = len(r.source.parents), len(r.target.parents)
        if m.shape != (ks, kt):
            raise ValueError(f"text_soft: correspondence has shape {m.shape}, expected ({ks}, {kt})")
        q_src, t_src = source_pose(r)
        q = weighted_quaternion_average(q_src, m)
        root = int(np.flatnonzero(r.target.parents < 0)[0])
        col = m[:, root] / max(m[:, root].sum(), 1e-12)
        disp = col @ (t_src - r.source.keypoints) * size_ratio(r)
        return pose_target(r.target, q, disp)
