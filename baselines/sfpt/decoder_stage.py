"""SFPT's second training stage, ``decoder``: the pose decoder alone, on the target's pose with placement removed.

The first stage (``sfpt``, :mod:`mimicbench.baselines.sfpt.training`) trains every network jointly on the
eight published terms; a short joint run leaves the residual decoder's correction near zero. This stage
starts from the trained ``sfpt`` weights, freezes the skinning predictor and the shape encoder, and trains
only the pose decoder to pose the target like its ground truth, in a way that cannot learn where the target
stands (the benchmark's h2h ranks by PMD after centring both meshes on their vertex means, so placement is
not what a transfer is scored on):

- the decoder's **translations are the source handles' Kabsch translations** (:func:`~mimicbench.baselines.sfpt.handles.with_translations`):
  it learns only each handle's rotation; the last layer's translation rows are zero at build and receive no
  gradient, so the trained decoder answers the Kabsch translation itself at test time too;
- ``rec``: the mean Euclidean vertex distance between the deformed target and its ground truth, **both
  centred on their vertex means** (the benchmark's ``pmd_aligned`` / 100); as published, the mean of the
  plain deformation's and of the one with the ground-truth handle translations;
- ``arap``: the published ARAP edge term of the deformed target (weight ``w_arap``, 100);
- ``trans``: the published transform supervision by the target's own Kabsch fit, rotation part only
  (the translations are fixed), weight ``w_trans`` (0 in the ``cpu`` preset; published 1).

A translation of the target's ground truth changes none of the terms (tested).

Because the frozen networks do not change, the stage draws ``examples`` training examples once per process
(a same-skeleton pair with probability ``pair_share``, else a self example), encodes them with the frozen
networks (the source's pose code (H, code), the target's shape code (H, code), the source's Kabsch fit (H, 7),
the target's handle weights (Nt, H)) and draws each epoch's batches from that set.

Settings, ``config["decoder"]`` (else the top level for the loop's keys): ``epochs``, ``lr``,
``weight_decay``, ``grad_clip``; ``examples``, ``pair_share``, ``pool_seed``, ``batch_size``,
``batches_per_epoch``, ``w_rec``, ``w_arap``, ``w_trans``. With ``epochs`` 0 (the ``paper`` preset, which
trains the decoder jointly) the stage writes the ``sfpt`` weights unchanged.
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.baselines.pose_pairs import PosePool
from mimicbench.baselines.sfpt.frame import unit_frame
from mimicbench.baselines.sfpt.handles import (deform, handle_centres, kabsch_transforms, transform_matrices,
                                                with_translations)
from mimicbench.baselines.sfpt.losses import arap_edges, quaternion_loss
from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals
from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer, build_sfpt
from mimicbench.training.batching import rank_batches
from mimicbench.training.stage import StageContext

_POOLS: dict = {}


def decoder_settings(config: dict) -> dict:
    """The decoder stage's settings: ``config["decoder"]`` (a dict; required)."""
    sub = config.get("decoder")
    if not isinstance(sub, dict):
        raise ValueError("SFPT's decoder stage reads its settings from config['decoder'] (a dict with "
                         "'examples', 'batch_size', 'batches_per_epoch', 'w_rec', 'w_arap', 'w_trans', ...); "
                         f"got {sub!r}")
    return sub


def build_decoder(config: dict, context: StageContext) -> SkeletonFreePoseTransfer:
    """The whole SFPT network with the trained ``sfpt`` stage's weights; only the pose decoder trains, and
    its translation outputs are zeroed (a residual decoder then answers the Kabsch translation)."""
    if context is None or "sfpt" not in context.frozen:
        raise ValueError("SFPT's decoder stage starts from the trained 'sfpt' stage: train it first "
                         "(`mimicbench train sfpt DATASET --out RUN` trains both)")
    module = build_sfpt(config, context)
    module.load_state_dict(context.frozen["sfpt"].state_dict())
    for part in (module.skinning, module.encoder):
        for p in part.parameters():
            p.requires_grad_(False)
    if int(decoder_settings(config).get("epochs", 0)) > 0:
        if not module.decoder.residual:
            raise ValueError("SFPT's decoder stage learns a rotation residual on the Kabsch fit: it needs "
                             "config['residual'] = True (the cpu preset's); got False")
        with torch.no_grad():
            module.decoder.net[-1].weight[:3] = 0.0
            module.decoder.net[-1].bias[:3] = 0.0
    return module


def centred_distance(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean over vertices of |a - b| after centring each of a, b (N, 3) on its own vertex mean."""
    return ((a - a.mean(-2, keepdim=True)) - (b - b.mean(-2, keepdim=True))).norm(dim=-1).mean()


def encode_example(frozen: SkeletonFreePoseTransfer, pool: PosePool, source: str, target: str,
                   rng: np.random.Generator, cache: dict) -> dict:
    """One example as the decoder sees it, float32 numpy arrays in unit-height rest frames:
    ``pose`` (H, code) the source's pose code, ``code`` (H, code) the target's shape code at rest,
    ``kabsch`` (H, 7) the source handles' Kabsch fit, ``fit`` (H, 7) the target's own Kabsch fit (rest onto
    its ground truth), ``rest`` and ``truth`` (Nt, 3) the target at rest and posed, ``weights`` (Nt, H) its
    handle weights, ``edges`` (E, 2) int64 its mesh edges. ``cache`` holds each character's rest tensors."""
    device = next(frozen.parameters()).device

    def rest_of(cid):
        if cid not in cache:
            r = pool.records[cid]
            rest = torch.as_tensor(unit_frame(r.vertices, r.vertices), device=device)
            faces = torch.as_tensor(np.asarray(r.faces, np.int64), device=device)
            edges = torch.as_tensor(mesh_edges(r.faces, len(rest)), device=device)
            normals = vertex_normals(rest, faces)
            weights = frozen.skinning(rest, normals, edges)
            cache[cid] = {"rest": rest, "faces": faces, "edges": edges, "normals": normals, "weights": weights,
                          "code": frozen.encoder(rest, normals, weights, edges)}
        return cache[cid]

    with torch.no_grad():
        ex = pool.example(source, target, rng)
        s, t = rest_of(source), rest_of(target)
        posed = torch.as_tensor(unit_frame(ex.source_posed, ex.source_rest), device=device)
        truth = torch.as_tensor(unit_frame(ex.target_posed, ex.target_rest), device=device)
        pose = frozen.pose_code(s["rest"], posed, (s["normals"], vertex_normals(posed, s["faces"])), s["weights"],
                                s["edges"])
        out = {"pose": pose, "code": t["code"], "kabsch": kabsch_transforms(s["rest"], posed, s["weights"]),
               "fit": kabsch_transforms(t["rest"], truth, t["weights"]), "rest": t["rest"], "truth": truth,
               "weights": t["weights"], "edges": t["edges"]}
        return {k: v.cpu().numpy() for k, v in out.items()}


def example_pool(config: dict, context: StageContext) -> list[dict]:
    """The stage's fixed set of encoded examples (:func:`encode_example`), drawn once per process."""
    cfg = decoder_settings(config)
    frozen = context.frozen["sfpt"]
    key = (str(context.dataset), config.get("split", "all"), int(cfg["examples"]), float(cfg["pair_share"]),
           int(cfg["pool_seed"]), id(frozen))
    if key not in _POOLS:
        pool = PosePool.load(context.dataset, config.get("split", "all"))
        rng = np.random.default_rng(int(cfg["pool_seed"]))
        cache: dict = {}
        examples = []
        for _ in range(int(cfg["examples"])):
            if pool.pairs and rng.random() < float(cfg["pair_share"]):
                s, t = pool.pairs[int(rng.integers(len(pool.pairs)))]
            else:
                s = t = pool.ids[int(rng.integers(len(pool.ids)))]
            examples.append(encode_example(frozen, pool, s, t, rng, cache))
        _POOLS.clear()
        _POOLS[key] = examples
    return _POOLS[key]


def batches_decoder(config: dict, context: StageContext, rng: np.random.Generator):
    """This rank's batches: ``{"items": [example, ...]}``, examples drawn from :func:`example_pool`."""
    cfg = decoder_settings(config)
    examples = example_pool(config, context)
    n = int(cfg["batches_per_epoch"]) * int(cfg["batch_size"])
    picks = rng.integers(0, len(examples), size=n)
    for idx in rank_batches(n, int(cfg["batch_size"]), rng, context.rank, context.world_size):
        yield {"items": [examples[int(picks[i])] for i in idx]}


def decoder_terms(module: SkeletonFreePoseTransfer, it: dict) -> dict:
    """``rec``, ``arap`` and ``trans`` of one example (tensors as :func:`encode_example` makes them)."""
    pred = with_translations(module.decoder(it["pose"], it["code"], it["kabsch"]), it["kabsch"][:, :3])
    rest, truth, weights = it["rest"], it["truth"], it["weights"]
    moved = deform(rest, weights, *transform_matrices(pred))
    shift = handle_centres(truth, weights) - handle_centres(rest, weights)
    with_shift = deform(rest, weights, *transform_matrices(with_translations(pred, shift)))
    return {"rec": 0.5 * (centred_distance(moved, truth) + centred_distance(with_shift, truth)),
            "arap": arap_edges(rest, moved, it["edges"]),
            "trans": 0.5 * quaternion_loss(pred[:, 3:], it["fit"][:, 3:])}


def loss_decoder(module, batch, context) -> dict:
    cfg = decoder_settings(context.config)
    device = next(module.parameters()).device
    items = batch["items"]
    terms: dict = {}
    for it in items:
        it = {k: torch.as_tensor(v, device=device) for k, v in it.items()}
        for k, v in decoder_terms(module, it).items():
            terms[k] = terms.get(k, 0.0) + v / len(items)
    total = sum(float(cfg[f"w_{k}"]) * v for k, v in terms.items())
    return {"total": total, **terms}
