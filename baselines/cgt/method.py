"""``cgt`` behind the adapter API: placement as NPT's (:mod:`mimicbench.baselines.npt.method`), attention capped.

The posed source and the target rest mesh are centred and scaled as :mod:`mimicbench.baselines.npt.placement`
says and the answer put back where the target stands. CGT's attention is dense over every pair of
points in the paper; here every target vertex attends over at most ``cap`` points of the posed
source (the checkpoint config's ``cap``, 256 in the ``cpu`` preset; a farthest-point subsample,
:mod:`mimicbench.baselines.cgt.sampling`), and the decoder runs on every target vertex.

Weights: ``checkpoints/cgt.safetensors`` (shipped), ``checkpoint=`` or ``MIMICBENCH_CGT_CHECKPOINT``
(``RUN/cgt/model.safetensors``).
"""
from __future__ import annotations

from pathlib import Path

from mimicbench.benchmark.method import MethodMetadata
from mimicbench.baselines.npt.method import Npt

CITATION = ("Haoyu Chen, Hao Tang, Zitong Yu, Nicu Sebe, Guoying Zhao. Geometry-Contrastive Transformer for "
            "Generalized 3D Pose Transfer. AAAI 2022 (re-implemented from the paper)")

LICENCE = ("MIT (this re-implementation and its weights, trained here); the authors' code (mikecheninoulu/CGT) "
           "carries no licence file, and none of it or of their weights ships")


class Cgt(Npt):
    """CGT with the shipped (or a given) checkpoint."""

    metadata = MethodMetadata(name="cgt", version="5", licence=LICENCE, needs_training=True, citation=CITATION,
                              reads_rig=False,
                              tags=("learned", "published", "re-implemented from the paper"),
                              description="CGT (shared point encoder, a CGPBlock before each of four SPAdaIN blocks; "
                                          "attention over 256 farthest source points in the cpu preset), "
                                          "re-implemented from the paper")
    stage = "cgt"
    env = "MIMICBENCH_CGT_CHECKPOINT"
    shipped = Path(__file__).resolve().parent / "checkpoints"

    def setup(self, device: str = "cpu") -> None:
        super().setup(device)
        self.cap = int(self.config["cap"])

    def _answer(self, pose, identity):
        import torch

        from mimicbench.baselines.cgt.training import capped_rows

        rows = {k: torch.as_tensor(v, device=self.device)
                for k, v in capped_rows(pose[0].cpu().numpy(), identity[0].cpu().numpy(), self.cap).items()}
        return self.module(pose, identity, **rows)


class CgtNoAttention(Cgt):
    """Ablation of ``cgt``: every CGPBlock removed (the decoder stream never reads the pose), with the
    shipped (or a given) weights."""

    metadata = MethodMetadata(name="cgt_no_attention", version="5", licence=LICENCE, needs_training=True,
                              citation=CITATION, reads_rig=False, tags=("learned", "published", "ablation"),
                              description="cgt with its attention (CGPBlocks) removed")

    def setup(self, device: str = "cpu") -> None:
        super().setup(device)
        self.module.attention = False
