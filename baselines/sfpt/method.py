"""``sfpt`` behind the adapter API: Skeleton-free Pose Transfer, mesh-only at test time.

For a transfer request: the source's and the target's handle weights come from their rest meshes
alone (:class:`baselines.sfpt.model.SkinningPredictor`), the source's handle transforms from its rest
and posed meshes (:class:`baselines.sfpt.model.PosePredictor`), and the target is deformed by LBS
over the handles (:func:`baselines.sfpt.handles.deform`). Each mesh is seen in its unit-height rest
frame (rest box centre, rest height) and the answer mapped back with the target's. Every vertex is
used; EdgeConv neighbours are each vertex's ``knn`` nearest rest vertices. No rig is read.

For a motion request (the ``apparel`` protocol, as MMDMC's Table 2 compares SPT there): each frame's
body pose is the character posed by its body bones alone (every apparel bone's weight moved to the
nearest body bone, :func:`baselines.body_only.body_weights`: what a body-only motion source shows),
and SFPT transfers that mesh onto the character's own rest mesh, so apparel moves with the handles
SFPT assigns it to.

Weights: ``checkpoints/sfpt.safetensors`` next to this file (shipped), or a training run given as
``checkpoint=`` or by ``MIMICBENCH_SFPT_CHECKPOINT`` (``RUN/sfpt/model.safetensors``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from baselines.checkpointed import CheckpointedMethod
from benchmark.method import MethodMetadata

CITATION = ("Zhouyingcheng Liao, Jimei Yang, Jun Saito, Gerard Pons-Moll, Yang Zhou. Skeleton-free Pose Transfer "
            "for Stylized 3D Characters. ECCV 2022 (re-implemented from the paper)")


class Sfpt(CheckpointedMethod):
    """Skeleton-free Pose Transfer with the shipped (or a given) checkpoint."""

    metadata = MethodMetadata(name="sfpt", version="1", licence="MIT", needs_training=True, citation=CITATION,
                              protocols=("h2h", "cct", "apparel"),
                              tags=("learned", "published", "re-implemented from the paper"),
                              description="Skeleton-free Pose Transfer (40 learned handles, EdgeConv skinning and "
                                          "pose predictors), re-implemented from the paper, trained on the zoo")
    stage = "sfpt"
    env = "MIMICBENCH_SFPT_CHECKPOINT"
    shipped = Path(__file__).resolve().parent / "checkpoints"

    def __init__(self, checkpoint: str | os.PathLike | None = None):
        super().__init__(checkpoint)
        self.knn = 8
        self.chunk = 4  # motion frames through the networks at once
        self._chars: dict = {}

    def setup(self, device: str = "cpu") -> None:
        super().setup(device)
        self.knn = int(self.config["knn"])

    def _character(self, vertices: np.ndarray, key) -> tuple:
        """(rest (1, N, 3), neighbours (N, k), handle weights (1, N, H)) tensors of a rest mesh, cached."""
        import torch

        from baselines.pose_pairs import neighbours
        from baselines.sfpt.training import unit_frame

        if key not in self._chars:
            rest = unit_frame(vertices, vertices)
            nb = torch.as_tensor(neighbours(rest, self.knn), device=self.device)
            rest_t = torch.as_tensor(rest, device=self.device)[None]
            with torch.no_grad():
                self._chars[key] = (rest_t, nb, self.module.skinning(rest_t, nb))
        return self._chars[key]

    def _pose_onto(self, source_vertices, source_key, source_posed: np.ndarray, target_vertices, target_key):
        """(F, Nt, 3) float32 metres: the target posed like each of the source's posed meshes (F, Ns, 3),
        ``chunk`` frames through the networks at a time."""
        import torch

        from baselines.sfpt.handles import deform
        from baselines.sfpt.training import unit_frame
        from mimicbench.mesh import unit_height_frame

        rest_s, nb_s, w_s = self._character(source_vertices, source_key)
        rest_t, _, w_t = self._character(target_vertices, target_key)
        centre, height = unit_height_frame(target_vertices)
        out = []
        for i in range(0, len(source_posed), self.chunk):
            posed = torch.as_tensor(np.stack([unit_frame(p, source_vertices) for p in source_posed[i:i + self.chunk]]),
                                    device=self.device)
            f = len(posed)
            with torch.no_grad():
                r, t = self.module.pose(rest_s.expand(f, -1, -1), posed, w_s.expand(f, -1, -1), nb_s)
                moved = deform(rest_t.expand(f, -1, -1), w_t.expand(f, -1, -1), r, t).cpu().numpy()
            out.append(moved.astype(np.float64) * height + centre)
        return np.concatenate(out).astype(np.float32)

    def transfer(self, requests):
        if self.module is None:
            self.setup(self.device)
        return [self._pose_onto(r.source.vertices, (r.source.character_id, len(r.source.vertices)),
                                np.asarray(r.source_posed)[None], r.target.vertices,
                                (r.target.character_id, len(r.target.vertices)))[0] for r in requests]

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per motion request (see the module docstring)."""
        from baselines.body_only import body_weights
        from mimicbench.skinning import linear_blend_skinning
        from mimicbench.weights import SparseWeights

        if self.module is None:
            self.setup(self.device)
        out = []
        for r in requests:
            rig = r.target
            weights = SparseWeights.from_dense(body_weights(rig, r.body_bones))
            body = linear_blend_skinning(rig.vertices, rig.keypoints, weights, np.asarray(r.transforms, np.float32))
            key = (rig.character_id, len(rig.vertices))
            out.append(self._pose_onto(rig.vertices, key, body, rig.vertices, key))
        return out
