"""SFPT's training stage for the shared trainer (``mimicbench train sfpt DATASET --out RUN``).

One stage, ``sfpt``. Each example is either a same-skeleton pair (share ``cross_share``) or a self
example of any character, of any category (:class:`baselines.pose_pairs.PosePool`). Per example, on
``points`` vertices drawn per mesh: the skinning predictor gives the source's and the target's handle
weights, the pose predictor the source's handle transforms; the loss is
``w_rec`` reconstruction (the source deformed by its own handles against the posed source)
+ ``w_cross`` cross-transfer (the target deformed by the source's handles against the ground
truth, pair examples only) + ``w_skin`` skinning (both meshes, against their rigs' weights)
+ ``w_edge`` edge (the deformed target's neighbour lengths against its rest), see
:mod:`baselines.sfpt.losses`. The ground-truth skin weights are read in training only; the method
reads none.
"""
from __future__ import annotations

import numpy as np
import torch

from baselines.pose_pairs import PosePool, knn_pairs, neighbours, subsample
from baselines.sfpt.config import CONFIGS
from baselines.sfpt.handles import deform
from baselines.sfpt.losses import co_skinning, rigid_edges, vertex_distance
from baselines.sfpt.model import SkeletonFreePoseTransfer
from mimicbench.mesh import unit_height_frame
from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage


def build_sfpt(config: dict, context: StageContext | None = None) -> SkeletonFreePoseTransfer:
    return SkeletonFreePoseTransfer(config["hidden"], config["handles"])


def unit_frame(vertices: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(N, 3) float32 ``vertices`` in the unit-height frame of ``rest`` (its box centre, its height)."""
    centre, height = unit_height_frame(rest)
    return ((np.asarray(vertices, np.float64) - centre) / height).astype(np.float32)


def _item(pool: PosePool, source: str, target: str, config: dict, rng: np.random.Generator) -> dict:
    ex = pool.example(source, target, rng)
    rs = subsample(len(ex.source_rest), config["points"], rng)
    rt = rs if source == target else subsample(len(ex.target_rest), config["points"], rng)
    s_rest, t_rest = unit_frame(ex.source_rest, ex.source_rest)[rs], unit_frame(ex.target_rest, ex.target_rest)[rt]
    skin_s = np.sort(rng.choice(len(rs), size=min(config["skin_points"], len(rs)), replace=False))
    skin_t = np.sort(rng.choice(len(rt), size=min(config["skin_points"], len(rt)), replace=False))
    return {"source_rest": s_rest, "source_posed": unit_frame(ex.source_posed, ex.source_rest)[rs],
            "source_nb": neighbours(s_rest, config["knn"]), "target_rest": t_rest,
            "target_posed": unit_frame(ex.target_posed, ex.target_rest)[rt], "target_nb": neighbours(t_rest, config["knn"]),
            "target_edges": knn_pairs(t_rest, 6), "source_skin_rows": skin_s, "target_skin_rows": skin_t,
            "source_rig": ex.source_weights[rs][skin_s], "target_rig": ex.target_weights[rt][skin_t],
            "cross": np.float32(source != target)}


def batches_sfpt(config: dict, context: StageContext, rng: np.random.Generator):
    """This rank's batches: lists of examples (vertex and bone counts differ between characters)."""
    pool = PosePool.load(context.dataset, config.get("split", "all"))
    n = config["batches_per_epoch"] * config["batch_size"]
    cross = (rng.random(n) < config["cross_share"]) & bool(pool.pairs)
    pair_picks = rng.integers(0, max(1, len(pool.pairs)), size=n)
    self_picks = rng.integers(0, len(pool.ids), size=n)
    seeds = rng.integers(0, 2**31 - 1, size=n)
    for idx in rank_batches(n, config["batch_size"], rng, context.rank, context.world_size):
        items = []
        for i in idx:
            s, t = pool.pairs[int(pair_picks[i])] if cross[i] else (pool.ids[int(self_picks[i])],) * 2
            items.append(_item(pool, s, t, config, np.random.default_rng(int(seeds[i]))))
        yield {"items": items}


def example_losses(module: SkeletonFreePoseTransfer, it: dict) -> dict:
    """The four terms of one example (tensors as :func:`_item` makes them)."""
    w_s = module.skinning(it["source_rest"][None], it["source_nb"])
    w_t = w_s if not bool(it["cross"]) else module.skinning(it["target_rest"][None], it["target_nb"])
    r, t = module.pose(it["source_rest"][None], it["source_posed"][None], w_s, it["source_nb"])
    rec = vertex_distance(deform(it["source_rest"][None], w_s, r, t), it["source_posed"][None])
    out_t = deform(it["target_rest"][None], w_t, r, t)[0]
    cross = vertex_distance(out_t, it["target_posed"]) if bool(it["cross"]) else rec * 0.0
    skin = 0.5 * (co_skinning(w_s[0][it["source_skin_rows"]], it["source_rig"])
                  + co_skinning(w_t[0][it["target_skin_rows"]], it["target_rig"]))
    edge = rigid_edges(out_t, it["target_rest"], it["target_edges"])
    return {"rec": rec, "cross": cross, "skin": skin, "edge": edge}


def loss_sfpt(module, batch, context) -> dict:
    cfg = context.config
    device = next(module.parameters()).device
    terms: dict = {}
    items = batch["items"]
    for it in items:
        it = {k: torch.as_tensor(v, device=device) for k, v in it.items()}
        for k, v in example_losses(module, it).items():
            terms[k] = terms.get(k, 0.0) + v / len(items)
    n_cross = sum(float(it["cross"]) for it in items)
    if n_cross:
        terms["cross"] = terms["cross"] * len(items) / n_cross  # a mean over the pair examples
    total = sum(cfg[f"w_{k}"] * v for k, v in terms.items())
    return {"total": total, **terms}


STAGES = [TrainStage("sfpt", build_sfpt, batches_sfpt, loss_sfpt)]

TRAINABLE = make_trainable("sfpt", STAGES, CONFIGS)
