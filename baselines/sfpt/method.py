"""``sfpt`` behind the adapter API: Skeleton-free Pose Transfer, mesh-only at test time.

For a transfer request, each mesh in its unit-height rest frame (rest box centre, rest height), with its
vertex normals and mesh edges (:mod:`mimicbench.baselines.sfpt.mesh_graph`):

1. handle weights of the source and of the target from their rest meshes
   (:class:`mimicbench.baselines.sfpt.model.SkinningPredictor`);
2. the target's shape code at rest (:class:`mimicbench.baselines.sfpt.model.ShapeEncoder`);
3. the handle transforms from the source's pose code, the target's shape code and the source handles'
   Kabsch fit (:meth:`mimicbench.baselines.sfpt.model.SkeletonFreePoseTransfer.predict`);
4. the target deformed over its handles (:func:`mimicbench.baselines.sfpt.handles.deform`), mapped back to metres;
5. test-time ARAP (:class:`mimicbench.baselines.mimicat.arap.ArapRefiner`, libigl): vertices whose largest handle
   weight is at least 0.5 stay where the handles put them, the others are re-solved as rigid as possible
   from the target's rest mesh.

No rig is read. For a motion request (the ``apparel`` protocol, as MMDMC's Table 2 compares SPT there):
each frame's body pose is the character posed by its body bones alone (every apparel bone's weight
moved to the nearest body bone, :func:`mimicbench.baselines.body_only.body_weights`), transferred onto the
character's own rest mesh.

``sfpt_kabsch_only`` (:class:`SfptKabschOnly`) replaces step 3 by the Kabsch fit itself.

Weights: ``checkpoints/sfpt.safetensors`` next to this file (shipped), or a training run given as
``checkpoint=`` or by ``MIMICBENCH_SFPT_CHECKPOINT``: its last stage, ``RUN/decoder/model.safetensors``
(the pose decoder trained on), else ``RUN/sfpt/model.safetensors``.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mimicbench.baselines.checkpointed import CheckpointedMethod
from mimicbench.benchmark.method import MethodMetadata

CITATION = ("Zhouyingcheng Liao, Jimei Yang, Jun Saito, Gerard Pons-Moll, Yang Zhou. Skeleton-free Pose Transfer "
            "for Stylized 3D Characters. ECCV 2022 (re-implemented from the paper)")

LICENCE = ("MIT for this re-implementation and its weights (trained here, from the paper; the public code read "
           "to learn, none copied). The original code and its pretrained weights "
           "(zycliao/skeleton-free-pose-transfer) are under the Adobe Research License: non-commercial use only")


class Sfpt(CheckpointedMethod):
    """Skeleton-free Pose Transfer with the shipped (or a given) checkpoint.

    Args:
        checkpoint: a training run or a folder of shipped weights (default: the shipped ones).
        arap: run the test-time ARAP refinement (step 5).
    """

    metadata = MethodMetadata(name="sfpt", version="5", licence=LICENCE, needs_training=True, citation=CITATION,
                              protocols=("h2h", "cct", "apparel"), reads_rig=False,
                              tags=("learned", "published", "re-implemented from the paper"),
                              description="Skeleton-free Pose Transfer (40 learned handles, EdgeConv over mesh "
                                          "edges on positions and normals, target-conditioned pose decoder, "
                                          "test-time ARAP), re-implemented from the paper, trained on the zoo")
    stage = "sfpt"
    env = "MIMICBENCH_SFPT_CHECKPOINT"
    shipped = Path(__file__).resolve().parent / "checkpoints"
    kabsch_only = False

    def __init__(self, checkpoint: str | os.PathLike | None = None, arap: bool = True):
        super().__init__(checkpoint)
        self.arap = bool(arap)
        self._chars: dict = {}
        self._refiner = None

    def weights_path(self) -> Path:
        """``sfpt.safetensors`` (shipped), else a run's ``decoder`` stage, else its ``sfpt`` stage."""
        from mimicbench.baselines.checkpointed import checkpoint_path

        run_decoder = self.checkpoint / "decoder" / "model.safetensors"
        if not (self.checkpoint / f"{self.stage}.safetensors").is_file() and run_decoder.is_file():
            return run_decoder
        return checkpoint_path(self.checkpoint, self.stage)

    def _character(self, vertices: np.ndarray, faces: np.ndarray, key) -> dict:
        """Cached tensors of a rest mesh in its unit-height frame: ``rest`` (N, 3), ``faces`` (M, 3),
        ``edges`` (E, 2), ``normals`` (N, 3), ``weights`` (N, H) and its shape ``code`` (H, code)."""
        import torch

        from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals
        from mimicbench.baselines.sfpt.frame import unit_frame

        if key not in self._chars:
            rest = torch.as_tensor(unit_frame(vertices, vertices), device=self.device)
            f = torch.as_tensor(np.asarray(faces, np.int64), device=self.device)
            edges = torch.as_tensor(mesh_edges(faces, len(vertices)), device=self.device)
            with torch.no_grad():
                normals = vertex_normals(rest, f)
                weights = self.module.skinning(rest, normals, edges)
                code = self.module.encoder(rest, normals, weights, edges)
            self._chars[key] = {"rest": rest, "faces": f, "edges": edges, "normals": normals, "weights": weights,
                                "code": code}
        return self._chars[key]

    def _pose_onto(self, source, source_posed: np.ndarray, target) -> np.ndarray:
        """(Nt, 3) float32 metres: the target rig's mesh posed like the source's posed mesh (Ns, 3)."""
        import torch

        from mimicbench.baselines.sfpt.handles import deform, transform_matrices
        from mimicbench.baselines.sfpt.mesh_graph import vertex_normals
        from mimicbench.baselines.sfpt.frame import unit_frame
        from mimicbench.geometry.mesh import unit_height_frame

        s = self._character(source.vertices, source.faces, (source.character_id, len(source.vertices)))
        t = self._character(target.vertices, target.faces, (target.character_id, len(target.vertices)))
        posed = torch.as_tensor(unit_frame(source_posed, source.vertices), device=self.device)
        with torch.no_grad():
            normals = (s["normals"], vertex_normals(posed, s["faces"]))
            pred = self.module.predict(s["rest"], posed, normals, s["weights"], s["edges"], t["code"],
                                       kabsch_only=self.kabsch_only)
            moved = deform(t["rest"], t["weights"], *transform_matrices(pred)).cpu().numpy()
        centre, height = unit_height_frame(target.vertices)
        out = (moved.astype(np.float64) * height + centre).astype(np.float32)
        if self.arap:
            out = self._refine(target, t["weights"].cpu().numpy(), out)
        return out

    def _refine(self, target, weights: np.ndarray, posed: np.ndarray) -> np.ndarray:
        from mimicbench.baselines.mimicat.arap import ArapRefiner

        if self._refiner is None:
            self._refiner = ArapRefiner()
        key = f"sfpt/{target.character_id}/{len(target.vertices)}"
        return self._refiner.refine(key, target.vertices, target.faces, weights, posed)

    def transfer(self, requests):
        if self.module is None:
            self.setup(self.device)
        return [self._pose_onto(r.source, np.asarray(r.source_posed), r.target) for r in requests]

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per motion request (see the module docstring)."""
        from mimicbench.baselines.body_only import body_weights
        from mimicbench.geometry.skinning import linear_blend_skinning
        from mimicbench.geometry.weights import SparseWeights

        if self.module is None:
            self.setup(self.device)
        out = []
        for r in requests:
            rig = r.target
            weights = SparseWeights.from_dense(body_weights(rig, r.body_bones))
            body = linear_blend_skinning(rig.vertices, rig.keypoints, weights, np.asarray(r.transforms, np.float32))
            out.append(np.stack([self._pose_onto(rig, frame, rig) for frame in body]))
        return out


class SfptKabschOnly(Sfpt):
    """Ablation of ``sfpt``: the pose decoder replaced by the bare Kabsch fit of each source handle (the
    learned handle weights and test-time ARAP kept)."""

    metadata = MethodMetadata(name="sfpt_kabsch_only", version="5", licence=LICENCE, needs_training=True,
                              citation=CITATION, protocols=("h2h", "cct", "apparel"), reads_rig=False,
                              tags=("learned", "published", "ablation"),
                              description="sfpt with its pose decoder replaced by the handles' Kabsch fit")
    kabsch_only = True
