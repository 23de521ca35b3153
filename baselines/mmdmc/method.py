"""The registered MMDMC methods for the ``apparel`` protocol (MMDMC Table 2's rows):

- ``mmdmc``: the full model (f_c mask, f_s body, f_d apparel), the paper's Body + Apparel row: the
  paper's joint refinement f_j is not part of it (it moves no score by 2 standard errors, even on
  its own training data: ``docs/methods/mmdmc.md``);
- ``mmdmc_body_only``: the Body Module row (f_s alone: apparel skinned to body joints);
- ``mmdmc_no_apparel``: the full model with f_d's displacement zero (same mask and skinning),
  so ``mmdmc`` against it is f_d's effect alone: the paper's Body Module row for this model;
- ``mmdmc_gt_mask``: Full Model + GT Mask (the dataset's apparel vertex mask instead of f_c's;
  the only variant that reads it).

None of them reads the target's skin weights; only ``mmdmc_gt_mask`` reads its apparel mask.
Weights come from the shipped checkpoint (``baselines/mmdmc/checkpoints/<stage>.safetensors``) or
from a training run: ``MIMICBENCH_MMDMC_CHECKPOINTS=RUN`` (a ``mimicbench train mmdmc ... --out RUN``
folder, ``RUN/<stage>/model.safetensors``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.benchmark.protocols.apparel import GT_MASK_TAG

CHECKPOINTS = Path(__file__).resolve().parent / "checkpoints"
ENV = "MIMICBENCH_MMDMC_CHECKPOINTS"
CITATION = ("Rong Wang, Wei Mao, Changsheng Lu, Hongdong Li. Towards High-Quality 3D Motion Transfer with "
            "Realistic Apparel Animation. ECCV 2024.")
STAGES = ("seg", "body", "apparel")
VARIANT_STAGES = {"full": STAGES, "body_only": ("body",), "no_apparel": STAGES}  # f_d's header holds the mask vote and apparel skinning it shares


def checkpoint_path(stage: str, folder: str | os.PathLike | None = None) -> Path:
    """The weights of ``stage``: ``FOLDER/<stage>/model.safetensors`` (a training run) or
    ``FOLDER/<stage>.safetensors`` (the shipped layout); FOLDER defaults to $MIMICBENCH_MMDMC_CHECKPOINTS,
    then the shipped checkpoints."""
    folder = Path(folder or os.environ.get(ENV) or CHECKPOINTS)
    for p in (folder / stage / "model.safetensors", folder / f"{stage}.safetensors"):
        if p.is_file():
            return p
    raise FileNotFoundError(f"no MMDMC weights for stage {stage!r} in {folder} (expected {stage}/model.safetensors "
                            f"or {stage}.safetensors); train them with `mimicbench train mmdmc DATASET --out RUN` "
                            f"and set {ENV}=RUN")


def load_modules(folder=None, device: str = "cpu", stages=STAGES):
    """:class:`~mimicbench.baselines.mmdmc.pipeline.Modules` from checkpoints (see :func:`checkpoint_path`); the
    stages left out of ``stages`` stay None."""
    from mimicbench.baselines.mmdmc.pipeline import Modules
    from mimicbench.baselines.mmdmc.training import BUILDERS
    from mimicbench.training.checkpoint import load_module, read_header

    mods = {s: load_module(checkpoint_path(s, folder), lambda cfg, s=s: BUILDERS[s](cfg, None), device) if s in stages
            else None for s in STAGES}
    config = read_header(checkpoint_path("body", folder))["config"]
    # the mask's piece vote and how apparel is skinned before f_d are the apparel stage's settings,
    # the weights' smoothing (iterations, radius) the body stage's
    apparel = read_header(checkpoint_path("apparel", folder))["config"] if "apparel" in stages else {}
    return Modules(mods["seg"], mods["body"], mods["apparel"], config["knn"], config["threshold"],
                   apparel.get("apparel_skinning", "fs"), bool(apparel.get("mask_by_piece", False)),
                   int(config.get("weight_smoothing", 0)), float(config.get("weight_smoothing_radius", 0.0)))


class Mmdmc(PoseTransferMethod):
    metadata = MethodMetadata(name="mmdmc", version="10", licence="MIT", needs_training=True, citation=CITATION,
                              protocols=("apparel",), tags=("learned", "apparel"),
                              description="MMDMC reference: apparel mask, geodesic-attention skinning, "
                                          "apparel offsets from the body's motion history kept to their lengths by "
                                          "soft ARAP")
    variant = "full"
    uses_gt_mask = False

    def __init__(self):
        self.modules = None
        self.device = "cpu"
        self._prepared: dict = {}

    def weights_fingerprint(self) -> str:
        """Fingerprint of the weights of the stages this variant loads (see :func:`checkpoint_path`)."""
        from mimicbench.schemas.fingerprint import files_fingerprint

        return files_fingerprint({s: checkpoint_path(s) for s in VARIANT_STAGES[self.variant]})

    def setup(self, device: str = "cpu") -> None:
        self.device = device
        self.modules = load_modules(device=device, stages=VARIANT_STAGES[self.variant])

    def transfer(self, requests):
        raise NotImplementedError(f"{self.metadata.name} answers motion requests only (the apparel protocol)")

    def _prepare(self, rig, body):
        from mimicbench.baselines.mmdmc.data import prepare

        key = (rig.character_id, len(rig.vertices), np.asarray(body, bool).tobytes())
        if key not in self._prepared:
            self._prepared[key] = prepare(rig.character_id, rig.vertices, rig.faces, rig.keypoints, rig.parents, body)
        return self._prepared[key]

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per request."""
        from mimicbench.baselines.mmdmc.pipeline import predict

        if self.modules is None:
            self.setup(self.device)
        out = []
        for r in requests:
            prep = self._prepare(r.target, r.body_bones)
            gt = r.extras.get("apparel_vertex_mask") if self.uses_gt_mask else None
            if self.uses_gt_mask and gt is None:
                raise ValueError(f"{self.metadata.name}: needs the ground-truth apparel mask in the request's extras "
                                 f"('apparel_vertex_mask', (N,) bool); the apparel protocol gives it to this method")
            out.append(predict(self.modules, prep, np.asarray(r.transforms, np.float32), self.variant, gt))
        return out


class MmdmcBodyOnly(Mmdmc):
    metadata = MethodMetadata(name="mmdmc_body_only", version="10", licence="MIT", needs_training=True,
                              citation=CITATION, protocols=("apparel",), tags=("learned", "apparel", "ablation"),
                              description="MMDMC ablation: the body module alone (Table 2, Body Module)")
    variant = "body_only"


class MmdmcNoApparel(Mmdmc):
    metadata = MethodMetadata(name="mmdmc_no_apparel", version="10", licence="MIT", needs_training=True,
                              citation=CITATION, protocols=("apparel",), tags=("learned", "apparel", "ablation"),
                              description="MMDMC ablation: full model with f_d's displacement zero (same mask, "
                                          "skinning; f_d's effect is mmdmc against this)")
    variant = "no_apparel"


class MmdmcGtMask(Mmdmc):
    metadata = MethodMetadata(name="mmdmc_gt_mask", version="10", licence="MIT", needs_training=True,
                              citation=CITATION, protocols=("apparel",),
                              tags=("learned", "apparel", "ablation", GT_MASK_TAG),
                              description="MMDMC ablation: full model with the ground-truth apparel mask (Table 2)")
    uses_gt_mask = True
