"""CGT's training stage for the shared trainer (``mimicbench train cgt DATASET --out RUN``).

One stage, ``cgt``, on NPT's batches (:func:`mimicbench.baselines.npt.training.pair_batches`: same-skeleton pairs
and self-transfers, centred as :mod:`mimicbench.baselines.npt.placement` says) with NPT's loss; attention runs
over at most ``cap`` points of each example's posed source (:func:`capped_rows`), as at inference; the
cross-category cycle term (``cycle_batch`` > 0, :mod:`mimicbench.baselines.npt.cycle`) calls the model through
:func:`capped_answer`.
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.baselines.cgt.config import CONFIGS
from mimicbench.baselines.cgt.model import Cgt
from mimicbench.baselines.cgt.sampling import farthest_points
from mimicbench.baselines.npt.cycle import add_cycle
from mimicbench.baselines.npt.losses import npt_loss
from mimicbench.baselines.npt.training import pair_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage


def build_cgt(config: dict, context: StageContext | None = None) -> Cgt:
    return Cgt(config["widths"], config.get("residual", False))


def capped_rows(pose: np.ndarray, identity: np.ndarray, cap: int) -> dict:
    """What :meth:`Cgt.forward` needs for every identity point (N_t, 3) to attend over ``cap`` points of
    the posed source (N_s, 3): ``{"pose_rows"}``; {} when ``cap`` is 0 (dense)."""
    if cap <= 0:
        return {}
    return {"pose_rows": farthest_points(pose, cap)}


def batches_cgt(config: dict, context: StageContext, rng: np.random.Generator):
    for batch in pair_batches(config, context, rng):
        batch["capped"] = [capped_rows(p, i, int(config["cap"])) for p, i in zip(batch["pose"], batch["identity"])]
        yield batch


def answer_with_rows(module, pose: torch.Tensor, identity: torch.Tensor, capped: list[dict]) -> torch.Tensor:
    """``module``'s answers (B, Nt, 3) for posed sources (B, Ns, 3) and identities (B, Nt, 3), example b
    attending over the rows ``capped[b]`` (:func:`capped_rows`)."""
    preds = []
    for b, rows in enumerate(capped):
        rows = {k: torch.as_tensor(v, device=pose.device) for k, v in rows.items()}
        preds.append(module(pose[b:b + 1], identity[b:b + 1], **rows))
    return torch.cat(preds)


def capped_answer(module, cap: int):
    """The model call of :func:`mimicbench.baselines.npt.cycle.cycle_terms` for ``module``: each example of the batch
    attends over ``cap`` farthest points of its own posed source (drawn from it, detached), as at inference."""

    def answer(pose: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        capped = [capped_rows(p.detach().cpu().numpy(), i.detach().cpu().numpy(), cap) for p, i in zip(pose, identity)]
        return answer_with_rows(module, pose, identity, capped)

    return answer


def loss_cgt(module, batch, context) -> dict:
    pred = answer_with_rows(module, batch["pose"], batch["identity"], batch["capped"])
    terms = npt_loss(pred, batch["truth"], batch["edges"], float(context.config["w_edge"]))
    return add_cycle(terms, capped_answer(module, int(context.config["cap"])), batch, context.config)


STAGES = [TrainStage("cgt", build_cgt, batches_cgt, loss_cgt)]

TRAINABLE = make_trainable("cgt", STAGES, CONFIGS)
