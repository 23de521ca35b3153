"""SFPT's training stages for the shared trainer (``mimicbench train sfpt DATASET --out RUN``).

Two stages: ``sfpt`` (every network, the eight published terms; below) and ``decoder`` (the pose decoder
alone on the centred reconstruction, the other networks frozen: :mod:`mimicbench.baselines.sfpt.decoder_stage`).
Stage ``sfpt``: each example has three characters, every vertex of each, in its own unit-height rest
frame: a source A posed by a frame of its clips, a target B with the ground truth of that pose (a
same-skeleton pair, share ``cross_share``, else A itself: :class:`mimicbench.baselines.pose_pairs.PosePool`), and a
third character C of any category (another character than B, unpaired). With the model's handle weights
W of each rest mesh:

- ``rec``: A's pose onto B (A's pose code, B's shape code, A's Kabsch fit), against B's ground truth; the
  mean of the L1 of the deformed B and of the deformed B with the ground-truth handle translations;
- ``cross``: B's ground-truth pose onto C, against C deformed by B's Kabsch fit (as ``rec``, two L1s);
- ``cycle``: the pose of that answer on C back onto B, against B's ground truth (as ``rec``);
- ``trans``: both predictions for B against B's own Kabsch fit (rest onto ground truth);
- ``arap``: :func:`mimicbench.baselines.sfpt.losses.arap_edges` of the three deformed meshes against their rest meshes;
- ``fps``: Chamfer of B's and C's handle centres to ``fps_per_handle`` x H farthest-point samples;
- ``skin``: :func:`mimicbench.baselines.sfpt.losses.skinning_contrast` of B's and C's weights against their rigs';
- ``aug``: KL of the weights of B scaled per axis (up to ``aug_scale``) against B's plain weights.

The rigs' skin weights are read in training only; the method reads none.
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.baselines.cgt.sampling import farthest_points
from mimicbench.baselines.pose_pairs import PosePool
from mimicbench.baselines.sfpt.config import CONFIGS
from mimicbench.baselines.sfpt.handles import (deform, handle_centres, kabsch_transforms, transform_matrices,
                                                with_translations)
from mimicbench.baselines.sfpt.losses import arap_edges, chamfer, kl, l1, skinning_contrast, transformation_loss
from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals
from mimicbench.baselines.sfpt.decoder_stage import batches_decoder, build_decoder, loss_decoder
from mimicbench.baselines.sfpt.frame import unit_frame
from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer, build_sfpt
from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage


def _item(pool: PosePool, source: str, target: str, third: str, config: dict, rng: np.random.Generator) -> dict:
    ex = pool.example(source, target, rng)
    c = pool.records[third]
    c_rest = unit_frame(c.vertices, c.vertices)
    b_rest = unit_frame(ex.target_rest, ex.target_rest)
    n_fps = int(config["fps_per_handle"]) * int(config["handles"])
    scale = 1.0 + rng.uniform(-config["aug_scale"], config["aug_scale"], 3)
    return {"a_rest": unit_frame(ex.source_rest, ex.source_rest), "a_posed": unit_frame(ex.source_posed, ex.source_rest),
            "a_faces": np.asarray(pool.records[source].faces, np.int64),
            "a_edges": mesh_edges(pool.records[source].faces, len(ex.source_rest)),
            "b_rest": b_rest, "b_truth": unit_frame(ex.target_posed, ex.target_rest),
            "b_aug": (b_rest * scale).astype(np.float32),
            "b_faces": np.asarray(pool.records[target].faces, np.int64),
            "b_edges": mesh_edges(pool.records[target].faces, len(b_rest)), "b_rig": ex.target_weights,
            "b_fps": b_rest[farthest_points(b_rest, n_fps)],
            "c_rest": c_rest, "c_faces": np.asarray(c.faces, np.int64), "c_edges": mesh_edges(c.faces, len(c_rest)),
            "c_rig": pool.weights(third), "c_fps": c_rest[farthest_points(c_rest, n_fps)],
            "seed": np.int64(rng.integers(2**31 - 1))}


def batches_sfpt(config: dict, context: StageContext, rng: np.random.Generator):
    """This rank's batches: lists of examples (vertex counts differ between characters)."""
    pool = PosePool.load(context.dataset, config.get("split", "all"))
    if len(pool.ids) < 2:
        raise ValueError(f"{context.dataset}: SFPT trains on at least two characters with a mesh and clips")
    n = config["batches_per_epoch"] * config["batch_size"]
    cross = (rng.random(n) < config["cross_share"]) & bool(pool.pairs)
    pair_picks = rng.integers(0, max(1, len(pool.pairs)), size=n)
    self_picks = rng.integers(0, len(pool.ids), size=n)
    third_picks = rng.integers(0, len(pool.ids) - 1, size=n)
    seeds = rng.integers(0, 2**31 - 1, size=n)
    for idx in rank_batches(n, config["batch_size"], rng, context.rank, context.world_size):
        items = []
        for i in idx:
            s, t = pool.pairs[int(pair_picks[i])] if cross[i] else (pool.ids[int(self_picks[i])],) * 2
            others = [c for c in pool.ids if c != t]
            items.append(_item(pool, s, t, others[int(third_picks[i]) % len(others)], config,
                               np.random.default_rng(int(seeds[i]))))
        yield {"items": items}


def _deformed(rest, weights, transforms):
    """The rest mesh (N, 3) deformed over handle weights (N, H) by (H, 7) ``transforms``."""
    r, t = transform_matrices(transforms)
    return deform(rest, weights, r, t)


def example_losses(module: SkeletonFreePoseTransfer, it: dict) -> dict:
    """The eight terms of one example (tensors as :func:`_item` makes them)."""
    rng = np.random.default_rng(int(it["seed"]))
    normals = {k: vertex_normals(it[f"{k}_rest"], it[f"{k}_faces"]) for k in "abc"}
    w = {k: module.skinning(it[f"{k}_rest"], normals[k], it[f"{k}_edges"]) for k in "abc"}
    w_aug = module.skinning(it["b_aug"], vertex_normals(it["b_aug"], it["b_faces"]), it["b_edges"])
    wd = {k: v.detach() for k, v in w.items()}
    code = {k: module.encoder(it[f"{k}_rest"], normals[k], wd[k], it[f"{k}_edges"]) for k in "bc"}
    b_rest, b_truth, c_rest = it["b_rest"], it["b_truth"], it["c_rest"]
    b_shift = (handle_centres(b_truth, wd["b"]) - handle_centres(b_rest, wd["b"])).detach()

    def on_b(pred):
        """The two deformed B meshes of a prediction and their L1 term against B's ground truth."""
        out = _deformed(b_rest, w["b"], pred)
        gtt = _deformed(b_rest, w["b"], with_translations(pred, b_shift))
        return out, 0.5 * (l1(out, b_truth) + l1(gtt, b_truth))

    a_normals = (normals["a"], vertex_normals(it["a_posed"], it["a_faces"]))
    pred1 = module.predict(it["a_rest"], it["a_posed"], a_normals, wd["a"], it["a_edges"], code["b"])
    pred_v, rec = on_b(pred1)
    fit_b = kabsch_transforms(b_rest, b_truth, wd["b"])
    b_normals = (normals["b"], vertex_normals(b_truth, it["b_faces"]))
    cross_pred = module.decoder(module.pose_code(b_rest, b_truth, b_normals, wd["b"], it["b_edges"]), code["c"], fit_b)
    cross_v = _deformed(c_rest, w["c"], cross_pred)
    superv = _deformed(c_rest, w["c"], fit_b).detach()
    c_shift = (handle_centres(superv, wd["c"]) - handle_centres(c_rest, wd["c"])).detach()
    cross_gtt = _deformed(c_rest, w["c"], with_translations(cross_pred, c_shift))
    cross = 0.5 * (l1(cross_v, superv) + l1(cross_gtt, superv))
    c_normals = (normals["c"], vertex_normals(cross_v.detach(), it["c_faces"]))
    pred2 = module.predict(c_rest, cross_v, c_normals, wd["c"], it["c_edges"], code["b"])
    pred_v2, cycle = on_b(pred2)
    trans = transformation_loss(pred1, fit_b) + transformation_loss(pred2, fit_b)
    arap = (arap_edges(b_rest, pred_v, it["b_edges"]) + arap_edges(c_rest, cross_v, it["c_edges"])
            + arap_edges(b_rest, pred_v2, it["b_edges"]))
    fps = chamfer(it["b_fps"], handle_centres(b_rest, w["b"])) + chamfer(it["c_fps"], handle_centres(c_rest, w["c"]))
    skin = (skinning_contrast(w["b"], it["b_rig"].cpu().numpy(), rng)
            + skinning_contrast(w["c"], it["c_rig"].cpu().numpy(), rng))
    return {"rec": rec, "cycle": cycle, "trans": trans, "cross": cross, "skin": skin, "aug": kl(w_aug, w["b"]),
            "fps": fps, "arap": arap}


def loss_sfpt(module, batch, context) -> dict:
    cfg = context.config
    device = next(module.parameters()).device
    terms: dict = {}
    items = batch["items"]
    for it in items:
        it = {k: torch.as_tensor(v, device=device) for k, v in it.items()}
        for k, v in example_losses(module, it).items():
            terms[k] = terms.get(k, 0.0) + v / len(items)
    total = sum(cfg[f"w_{k}"] * v for k, v in terms.items())
    return {"total": total, **terms}


STAGES = [TrainStage("sfpt", build_sfpt, batches_sfpt, loss_sfpt),
          TrainStage("decoder", build_decoder, batches_decoder, loss_decoder, needs=("sfpt",))]

TRAINABLE = make_trainable("sfpt", STAGES, CONFIGS)
