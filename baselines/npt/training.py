"""NPT's training stage for the shared trainer (``mimicbench train npt DATASET --out RUN``).

One stage, ``npt``: examples are same-skeleton pairs of the dataset
(:class:`mimicbench.baselines.pose_pairs.PosePool`: the source posed by a frame of its clips, the target
posed by the h2h ground truth of that pose), plus a share ``self_share`` of self-transfers of any
character of the dataset, of every category (ours: the paper trains on SMPL pairs; a zoo's
same-skeleton pairs are all humanoids, and a self-transfer is supervised too); both
meshes are seen as :mod:`mimicbench.baselines.npt.placement` centres them, on ``points`` vertices drawn per
mesh. The loss is :func:`mimicbench.baselines.npt.losses.npt_loss`; with ``cycle_batch`` > 0 (ours, off in
the presets) each step also draws that many cross-category cycle examples, whose terms
:func:`mimicbench.baselines.npt.cycle.add_cycle` adds. CGT trains on the very same batches
(:func:`pair_batches`, :func:`loss_pairs`).
"""
from __future__ import annotations

import numpy as np

from mimicbench.baselines.npt.config import CONFIGS
from mimicbench.baselines.npt.cycle import add_cycle, cross_category_pairs, cycle_batch
from mimicbench.baselines.npt.losses import npt_loss
from mimicbench.baselines.npt.model import NeuralPoseTransfer
from mimicbench.baselines.npt.placement import centred
from mimicbench.baselines.pose_pairs import PosePool, knn_pairs, subsample
from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage


def build_npt(config: dict, context: StageContext | None = None) -> NeuralPoseTransfer:
    return NeuralPoseTransfer(config["widths"], config.get("residual", False))


def pair_item(pool: PosePool, source: str, target: str, config: dict, rng: np.random.Generator) -> dict:
    """One example's arrays: ``pose`` (Ps, 3), ``identity`` (Pt, 3), ``truth`` (Pt, 3), ``edges`` (Pt*k, 2)."""
    ex = pool.example(source, target, rng)
    rs = subsample(len(ex.source_rest), config["points"], rng)
    rt = subsample(len(ex.target_rest), config["points"], rng)
    identity = centred(ex.target_rest, ex.target_rest)[rt]
    return {"pose": centred(ex.source_posed, ex.source_rest)[rs], "identity": identity,
            "truth": centred(ex.target_posed, ex.target_rest)[rt], "edges": knn_pairs(identity, config["knn"])}


def pair_batches(config: dict, context: StageContext, rng: np.random.Generator):
    """This rank's batches of one epoch, each stacked from ``batch_size`` examples (equal point counts)."""
    pool = PosePool.load(context.dataset, config.get("split", "all"))
    pool.require_pairs(context.dataset)
    n = config["batches_per_epoch"] * config["batch_size"]
    picks = rng.integers(0, len(pool.pairs), size=n)
    selfs = rng.random(n) < config["self_share"]
    self_picks = rng.integers(0, len(pool.ids), size=n)
    seeds = rng.integers(0, 2**31 - 1, size=n)
    cycle = int(config.get("cycle_batch", 0)) > 0
    if cycle:  # drawn only when on, so a config without the term draws the same batches as before
        cycle_pairs, cycle_rng = cross_category_pairs(pool), np.random.default_rng(int(rng.integers(2**31 - 1)))
    for idx in rank_batches(n, config["batch_size"], rng, context.rank, context.world_size):
        items = []
        for i in idx:
            s, t = (pool.ids[int(self_picks[i])],) * 2 if selfs[i] else pool.pairs[int(picks[i])]
            items.append(pair_item(pool, s, t, config, np.random.default_rng(int(seeds[i]))))
        extra = cycle_batch(pool, cycle_pairs, config, cycle_rng) if cycle else {}
        if config["points"] <= 0:  # whole meshes differ in vertex count: one example a step
            for j, it in enumerate(items):
                yield {**{k: v[None] for k, v in it.items()}, **(extra if j == 0 else {})}
        else:
            yield {**{k: np.stack([it[k] for it in items]) for k in items[0]}, **extra}


def loss_pairs(module, batch, context) -> dict:
    pred = module(batch["pose"], batch["identity"])
    terms = npt_loss(pred, batch["truth"], batch["edges"], float(context.config["w_edge"]))
    return add_cycle(terms, module, batch, context.config)


STAGES = [TrainStage("npt", build_npt, pair_batches, loss_pairs)]

TRAINABLE = make_trainable("npt", STAGES, CONFIGS)
