"""``npt`` behind the adapter API (and the base of ``cgt``).

For each request the posed source and the target rest mesh are centred and scaled as
:mod:`mimicbench.baselines.npt.placement` says (NPT ignores global translation, as its evaluation does), the
network answers the posed target in that frame, and :func:`mimicbench.baselines.npt.placement.place` puts it
back where the target stands, moved as the source moved. Every target vertex is answered; the pose
encoder sees as many of the posed source's vertices as training drew (the checkpoint config's
``points``, a fixed draw: a max over 7,000 vertices is not the max over 512 that training saw;
every vertex when ``points`` is 0). The method reads no rig: neither skeleton nor skin weights.

Weights: ``checkpoints/<stage>.safetensors`` next to this file (shipped), or a training run given as
``checkpoint=`` or by the environment variable ``MIMICBENCH_NPT_CHECKPOINT`` (a ``mimicbench train npt
... --out RUN`` folder, ``RUN/npt/model.safetensors``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mimicbench.baselines.checkpointed import CheckpointedMethod
from mimicbench.benchmark.method import MethodMetadata

CITATION = ("Jiashun Wang, Chao Wen, Yanwei Fu, Haitao Lin, Tianyun Zou, Xiangyang Xue, Yinda Zhang. Neural Pose "
            "Transfer by Spatially Adaptive Instance Normalization. CVPR 2020 (re-implemented from the paper)")

LICENCE = ("MIT (this re-implementation and its weights, trained here); the authors' code "
           "(jiashunwang/Neural-Pose-Transfer) carries no licence file, and none of it or of their weights ships")


class Npt(CheckpointedMethod):
    """Neural Pose Transfer with the shipped (or a given) checkpoint."""

    metadata = MethodMetadata(name="npt", version="6", licence=LICENCE, needs_training=True, citation=CITATION,
                              reads_rig=False,
                              tags=("learned", "published", "re-implemented from the paper"),
                              description="Neural Pose Transfer (max-pool pose code, SPAdaIN decoder whose first block has "
                                          "no instance norm), re-implemented from the paper, trained on the zoo")
    stage = "npt"
    env = "MIMICBENCH_NPT_CHECKPOINT"
    shipped = Path(__file__).resolve().parent / "checkpoints"

    def pose_rows(self, count: int):
        """(P,) sorted rows of a posed source of ``count`` vertices the pose encoder sees: a draw of the
        config's ``points`` (generator seed 0, as :func:`mimicbench.baselines.pose_pairs.subsample` draws in training)."""
        from mimicbench.baselines.pose_pairs import subsample

        return subsample(count, int(self.config.get("points", 0)), np.random.default_rng(0))

    def _answer(self, pose, identity):
        """The network's centred answer (1, Nt, 3) for pose (1, Ns, 3) and identity (1, Nt, 3) tensors."""
        return self.module(pose, identity)


    def transfer(self, requests):
        import torch

        from mimicbench.baselines.npt.placement import centred, place

        if self.module is None:
            self.setup(self.device)
        out = []
        for r in requests:
            rows = self.pose_rows(len(r.source_posed))
            pose = torch.as_tensor(centred(r.source_posed, r.source.vertices)[rows], device=self.device)[None]
            identity = torch.as_tensor(centred(r.target.vertices, r.target.vertices), device=self.device)[None]
            with torch.no_grad():
                answer = self._answer(pose, identity)[0].cpu().numpy()
            out.append(place(answer, r.source.vertices, r.source_posed, r.target.vertices))
        return out


class NptConstantCode(Npt):
    """Ablation of ``npt``: the decoder conditioned on a constant code (zeros) instead of the source's pose
    code, with the shipped (or a given) weights; what is left is what the identity mesh alone gives."""

    metadata = MethodMetadata(name="npt_constant_code", version="6", licence=LICENCE, needs_training=True,
                              citation=CITATION, reads_rig=False, tags=("learned", "published", "ablation"),
                              description="npt with its pose code replaced by a constant (zeros)")

    def _answer(self, pose, identity):
        import torch

        width = self.module.encoder.features.net[-3].out_channels
        return self.module(pose, identity, code=torch.zeros(pose.shape[0], width, device=pose.device))
