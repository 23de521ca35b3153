"""``text_soft``: MimiCAT's initialisation without its learned refinement.

A soft correspondence M (Ks, Kt) between the source's and the target's bones comes from bone
names (the pair's ``m_sink`` from the dataset's ``pairs/`` table when the evaluator passes it,
else computed on the fly by the correspond stage's text encoder). Each target bone's rotation is
the M-weighted rotation average of the source bones (Eq. 4). The translation part of Eq. 3 gives
each target keypoint j the M-weighted displacement of the source keypoints,
``sum_i M_ij (t_i - cbar_i) / sum_i M_ij``, scaled by the ratio of sizes (largest rest extents);
the target keeps its own bone lengths, so forward kinematics fixes every joint relative to the
root and the root is placed where the keypoints best follow those displacements (least squares
over all keypoints: the mean of what each one is missing).

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np

from mimicbench.baselines.posing import pose_target, size_ratio, source_pose
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.geometry.kinematics import forward_kinematics, local_from_global
from mimicbench.geometry.rotation_average import weighted_quaternion_average


class TextSoft(PoseTransferMethod):
    metadata = MethodMetadata(
        name="text_soft", version="5", licence="MIT",
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
            from mimicbench.datagen.correspond.pair import correspondence_for_names

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
        mass = m.sum(axis=0)
        has = mass > 0
        wanted = (m[:, has] / mass[has]).T @ (t_src - r.source.keypoints) * size_ratio(r)  # Eq. 3, (Kt', 3)
        _, at_rest_root = forward_kinematics(local_from_global(q, r.target.parents), r.target.keypoints,
                                             r.target.parents)
        disp = (wanted - (at_rest_root - r.target.keypoints)[has]).mean(axis=0) if has.any() else np.zeros(3)
        return pose_target(r.target, q, disp)
