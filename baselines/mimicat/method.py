"""``mimicat`` and its ablations behind the adapter API.

The cascade of MimiCAT: the source's pose is read off its posed vertices (the joint fit of all
bones, :func:`mimicbench.baselines.posing.source_pose`), its keypoints re-placed where the mesh does not
determine a parent (:mod:`mimicbench.baselines.mimicat.source_anchor`); the frozen shape encoder E gives shape tokens; G
the soft correspondence M (at the Sinkhorn temperature ``transfer.m_temperature`` of the transfer
checkpoint's config, 1 for checkpoints without it), read as ``transfer.m_decode`` says (``soft``
for checkpoints without it, ``hungarian``: one to one, ``hungarian_sym``: one to one from G's M
of both directions, one assignment of the pair); H the target's transforms from its
initialisation (``transfer.init`` of the transfer checkpoint's config: ``structured`` for the
presets and the shipped checkpoint, ``paper``, Eq. 3-4 as published, for a config without the
key); the refinement of H's answer: target bones G matches to no source bone share the turn
between their matched neighbours and are moved into the ranges the range model predicts from the
target's shape (:mod:`mimicbench.baselines.mimicat.range_model`); LBS poses the target; ARAP
(:mod:`mimicbench.baselines.mimicat.arap`) refines it only when ``arap=True`` (off by default: the
shared joint-fit read-off returns an LBS pose's transforms exactly, an ARAP-refined mesh's not). The shipped checkpoints' configs are the documented ones
(:func:`mimicbench.baselines.mimicat.config.shipped_config`): ``structured``, ``hungarian_sym``, temperature 0.1.

Weights: the checkpoint folder given as ``checkpoint=`` or by the environment variable
``MIMICAT_CHECKPOINT``, else the bundled one (``baselines/mimicat/checkpoints``). A folder holds
either ``<stage>.safetensors`` files (the bundled layout) or a training run's
``<stage>/model.safetensors`` (``mimicbench train mimicat DATA --out RUN``), stages ``shape``,
``corr``, ``transfer`` and, for ``mimicat_no_prior``, ``transfer_no_prior``; the range model is
the folder's ``range.safetensors`` (or ``range/model.safetensors``), else the bundled one.

Registered names:
- ``mimicat``: the full model.
- ``mimicat_naive_avg`` (ablation A1): the same weights with Eq. 4's rotation average replaced
  by the normalised plain weighted sum of quaternions in the initialisation. With a one-to-one M
  (``hungarian_sym``, the shipped config) every column holds one quaternion, so both give that
  quaternion and A1 answers exactly as ``mimicat``; it differs only with ``m_decode=soft``.
- ``mimicat_no_prior`` (ablation A2): the pose prior left out in both its forms, H trained
  without L_reg and no range model (the interpolation of unmatched bones kept).
- ``mimicat_init_only``: the shipped G, its M of both directions decoded as one one-to-one
  assignment of the pair (``hungarian_sym``) and the structured initialisation, H, the
  interpolation and the range model off (the initialisation is the answer), so that H's own
  contribution shows on the leaderboard.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod

BUNDLED = Path(__file__).parent / "checkpoints"
CITATION = ("Chai et al., MimiCAT: Mimic with Correspondence-Aware Cascade-Transformer for Category-Free 3D Pose "
            "Transfer, arXiv 2511.18370 (re-implemented from the paper)")


def checkpoint_path(folder: Path, stage: str) -> Path:
    """The weights of ``stage`` in a checkpoint folder (bundled or run layout)."""
    from mimicbench.training.checkpoint import stage_weights

    return stage_weights(folder, stage, "mimicat")


class Mimicat(PoseTransferMethod):
    """The full MimiCAT reference.

    Args:
        checkpoint: folder of weights (see the module docstring); None for MIMICAT_CHECKPOINT or
            the bundled one.
        arap: refine the LBS result by ARAP (off by default).
        batch_size: requests run through the networks at once.
    """

    metadata = MethodMetadata(name="mimicat", version="11", licence="MIT", needs_training=True, citation=CITATION,
                              description="MimiCAT cascade: shape encoder, correspondence transformer G, "
                                          "pose-transfer transformer H, range model from shape, LBS (bundled checkpoint)")
    transfer_stage = "transfer"
    average = "eq4"
    init: str | None = None
    """H's initialisation (``structured`` or ``paper``); None: the transfer checkpoint's ``transfer.init``."""
    m_decode: str | None = None
    """How H's initialisation reads G's M (``soft``, ``hungarian`` or ``hungarian_sym``, see
    :func:`mimicbench.baselines.mimicat.transfer.decode_correspondence`); None: the transfer checkpoint's
    ``transfer.m_decode`` (``soft`` for a config without the key)."""
    use_h = True
    """False: the initialisation is the answer (H's correction left out)."""
    interpolate = True
    """True: the target bones G's decoded M matches to no source bone share the turn between their
    matched neighbours (:func:`mimicbench.baselines.mimicat.range_model.interpolate_free`) instead
    of keeping their parent's rotation."""
    use_range = True
    """True: each target bone's local rotation is projected into the range predicted from the
    target's shape (:mod:`mimicbench.baselines.mimicat.range_model`, the ``range`` file of the
    checkpoint folder, else the bundled one) before skinning."""
    anchor_source = True
    """True: the source keypoints are re-placed where the mesh does not determine a parent before
    the initialisation reads translations from them
    (:func:`mimicbench.baselines.mimicat.source_anchor.anchor_source_keypoints`)."""
    determined_only = False
    """True: G's decoded M pairs a bone the mesh determines only with a bone the mesh determines,
    and a bone it does not determine only with one it does not
    (:func:`mimicbench.baselines.mimicat.transfer.determined_pairs`); off by default."""
    range_exclude_self = False
    """True: the range model leaves the target's own character id out of its neighbours
    (leave-one-out checks on the zoo the range model was fitted on; never for a benchmark run)."""

    def __init__(self, checkpoint: str | os.PathLike | None = None, arap: bool = False, batch_size: int = 16):
        self.checkpoint = Path(checkpoint or os.environ.get("MIMICAT_CHECKPOINT") or BUNDLED)
        self.arap = arap
        self._range = None
        self._predicted: dict = {}
        self.batch_size = batch_size
        self._modules = None
        self._chars: dict = {}
        self._m_cache: dict = {}
        self._det: dict = {}
        self._refiner = None

    def weights_fingerprint(self) -> str:
        """Fingerprint of the shape, corr and transfer weights this instance loads, and of the range
        model when it reads one."""
        from mimicbench.schemas.fingerprint import files_fingerprint

        stages = ("shape", "corr", self.transfer_stage)
        files = {s: checkpoint_path(self.checkpoint, s) for s in stages}
        if self.use_range:
            files["range"] = range_path(self.checkpoint)
        return files_fingerprint(files)

    def setup(self, device: str = "cpu") -> None:
        import torch

        from mimicbench.baselines.mimicat.transfer_training import section
        from mimicbench.training.checkpoint import load_module
        from mimicbench.training.registry import trainable
        from mimicbench.training.stage import StageContext

        self.device = torch.device(device)
        model = trainable("mimicat")
        ctx = StageContext(self.checkpoint, self.device, {})
        mods = {}
        for key, stage in (("shape", "shape"), ("corr", "corr"), ("transfer", self.transfer_stage)):
            mods[key] = load_module(checkpoint_path(self.checkpoint, stage),
                                    lambda cfg, s=model.stage(stage): s.build(cfg, ctx), self.device)
        mods["transfer"].average = self.average
        if self.init is not None:
            mods["transfer"].init = self.init
        transfer_config = section(_header_config(checkpoint_path(self.checkpoint, self.transfer_stage)), "transfer")
        self.points = int(transfer_config["points"])
        self.m_temperature = float(transfer_config["m_temperature"])
        self.decode = self.m_decode or transfer_config["m_decode"]
        self._modules = mods
        if self.use_range:
            from mimicbench.baselines.mimicat.range_model import RangeModel

            self._range = RangeModel.load(range_path(self.checkpoint))
        if self.arap:
            from mimicbench.baselines.mimicat.arap import ArapRefiner

            self._refiner = ArapRefiner()

    def _character(self, rig):
        from mimicbench.baselines.mimicat.transfer_data import CharacterTensors

        key = (rig.character_id, len(rig.vertices), len(rig.parents))
        if key not in self._chars:
            self._chars[key] = CharacterTensors.of_rig(rig, self.points, self.device)
        return self._chars[key]

    def transfer(self, requests):
        if self._modules is None:
            self.setup("cpu")
        out = []
        for i in range(0, len(requests), self.batch_size):
            out.extend(self._batch(requests[i:i + self.batch_size]))
        return out

    def _batch(self, requests) -> list[np.ndarray]:
        import torch

        from mimicbench.baselines.mimicat.transfer import pose_mesh, transfer_batch

        src = [self._character(r.source) for r in requests]
        tgt = [self._character(r.target) for r in requests]
        q_s, t_s = [], []
        for r in requests:
            q, t = self._source_pose(r)
            q_s.append(torch.as_tensor(q, dtype=torch.float32, device=self.device))
            t_s.append(torch.as_tensor(t, dtype=torch.float32, device=self.device))
        posed = [torch.tensor(np.asarray(r.source_posed, np.float32), device=self.device) for r in requests]
        m = self._modules
        with torch.no_grad():
            ms = self._correspondences(requests, src, tgt)
            if self.use_h:
                result, _, _ = transfer_batch(m["shape"], m["corr"], m["transfer"], src, q_s, t_s, posed, tgt, ms)
            else:
                result = [m["transfer"].initialise(*args)[:2] for args in zip(src, q_s, t_s, tgt, ms)]
            if self.interpolate or self._range is not None:
                result = [self._refine(r.target, q, p, mm) for r, (q, p), mm in zip(requests, result, ms)]
            verts = [pose_mesh(t, q, p).cpu().numpy().astype(np.float32) for t, (q, p) in zip(tgt, result)]
        if self._refiner is not None:
            verts = [self._refiner.refine(r.target.character_id, r.target.vertices, r.target.faces,
                                          r.target.weights.values, v) for r, v in zip(requests, verts)]
        return verts

    def _determined(self, rig) -> np.ndarray:
        """(K,) bool, the bones of ``rig`` its posed mesh determines (skin weight spread in two
        directions, :func:`mimicbench.geometry.transform_estimation.weight_support`), cached per character."""
        from mimicbench.geometry.transform_estimation import weight_support

        key = (rig.character_id, len(rig.vertices), len(rig.parents))
        if key not in self._det:
            self._det[key] = np.asarray(weight_support(rig.vertices, rig.weights), bool)
        return self._det[key]

    def _source_pose(self, request) -> tuple[np.ndarray, np.ndarray]:
        """The source's global rotations (Ks, 4) and keypoints (Ks, 3): the shared read-off
        (:func:`mimicbench.geometry.pose_readoff.read_rig_pose`, as
        :func:`mimicbench.baselines.posing.source_pose`), its keypoints re-placed where the mesh
        does not determine a parent (:func:`mimicbench.baselines.mimicat.source_anchor.anchor_source_keypoints`)."""
        from mimicbench.baselines.mimicat.source_anchor import anchor_source_keypoints
        from mimicbench.geometry.kinematics import subtree_sums
        from mimicbench.geometry.pose_readoff import read_rig_pose
        from mimicbench.schemas.weights import as_dense

        pose = read_rig_pose(request.source, request.source_posed)
        if not self.anchor_source or pose.supported.all():
            return pose.rotations, pose.positions
        rig = request.source
        weight_below = subtree_sums(as_dense(rig.weights, len(rig.parents)).sum(axis=0), rig.parents)
        return pose.rotations, anchor_source_keypoints(pose.rotations, pose.positions, rig.keypoints, rig.parents,
                                                       pose.supported, weight_below)

    def _refine(self, rig, q, p, m):
        """H's answer q (Kt, 4), p (Kt, 3) (tensors) refined for ``rig`` with the decoded M (Ks, Kt):
        the target bones M matches to no source bone share the turn between their matched
        neighbours (``interpolate``, :func:`mimicbench.baselines.mimicat.range_model.interpolate_free`),
        and, with the range model (``use_range``), bones are moved into the ranges it predicts for
        ``rig``: the unmatched ones (scope ``free``, :func:`mimicbench.baselines.mimicat.range_model.refine_free`),
        every bone (scope ``all``, :func:`mimicbench.baselines.mimicat.range_model.project_pose`) or
        the first and then the second (scope ``both``)."""
        import torch

        from mimicbench.baselines.mimicat.range_model import project_pose, refine_free

        rng = self._range
        predicted = None
        if rng is not None:
            key = (rig.character_id, len(rig.vertices), len(rig.parents))
            if key not in self._predicted:
                self._predicted[key] = rng.predict(rig, rig.character_id if self.range_exclude_self else None)
            predicted = self._predicted[key]
        qn, pn = q.detach().cpu().numpy(), p.detach().cpu().numpy()
        if self.interpolate:
            matched = m.detach().cpu().numpy().sum(axis=0) > 0
            free_ranges = predicted if rng is not None and rng.scope in ("free", "both") else None
            qn, pn = refine_free(qn, pn, rig.parents, matched, free_ranges, rng.slack_deg if rng else 0.0,
                                 rng.parts if rng else "both")
        if rng is not None and rng.scope in ("all", "both"):
            qn, pn = project_pose(qn, pn, rig.parents, predicted, rng.slack_deg, rng.parts, rng.keep, rng.max_deg)
        return torch.as_tensor(qn, dtype=q.dtype, device=q.device), torch.as_tensor(pn, dtype=p.dtype, device=p.device)

    def _correspondences(self, requests, src, tgt) -> list:
        """G's correspondence M (Ks, Kt) of each request's characters (prepared ``src``, ``tgt``),
        the soft M cached per pair, decoded as ``self.decode``; a diagnostic subclass may supply
        other matches (benchmarks/mimicat_decomposition.py)."""
        from mimicbench.baselines.mimicat.transfer import (NEEDS_REVERSE, correspondences, decode_correspondence,
                                                           determined_pairs)

        m = self._modules
        forward = correspondences(m["shape"], m["corr"], src, tgt, self._m_cache, self.m_temperature)
        reverse = (correspondences(m["shape"], m["corr"], tgt, src, self._m_cache, self.m_temperature)
                   if self.decode in NEEDS_REVERSE else [None] * len(forward))
        if not self.determined_only:
            return [decode_correspondence(mm, self.decode, r) for mm, r in zip(forward, reverse)]
        allowed = [determined_pairs(self._determined(r.source), self._determined(r.target)) for r in requests]
        return [decode_correspondence(mm, self.decode, r, None if a.all() else a)
                for mm, r, a in zip(forward, reverse, allowed)]


def range_path(folder: Path) -> Path:
    """The range model of a checkpoint folder: ``range.safetensors`` in it (bundled layout) or
    ``range/model.safetensors`` (run layout), else the bundled one."""
    for candidate in (folder / "range.safetensors", folder / "range" / "model.safetensors"):
        if candidate.is_file():
            return candidate
    return BUNDLED / "range.safetensors"


def _header_config(path: Path) -> dict:
    from mimicbench.training.checkpoint import read_header

    return read_header(path).get("config", {})


class MimicatNaiveAvg(Mimicat):
    metadata = MethodMetadata(name="mimicat_naive_avg", version="11", licence="MIT", needs_training=True,
                              citation=CITATION,
                              description="MimiCAT ablation A1: plain weighted quaternion sum instead of Eq. 4")
    average = "naive"


class MimicatNoPrior(Mimicat):
    metadata = MethodMetadata(name="mimicat_no_prior", version="11", licence="MIT", needs_training=True,
                              citation=CITATION, description="MimiCAT ablation A2: H trained without the prior L_reg, "
                                                              "no range model")
    transfer_stage = "transfer_no_prior"
    use_range = False


class MimicatInitOnly(Mimicat):
    metadata = MethodMetadata(name="mimicat_init_only", version="11", licence="MIT", needs_training=True,
                              citation=CITATION,
                              description="MimiCAT without H: G's correspondences of both directions decoded as "
                                          "one one-to-one assignment and the structured initialisation, LBS")
    init = "structured"
    m_decode = "hungarian_sym"
    use_h = False
    interpolate = False
    use_range = False
