"""A cross-category self-supervised cycle term for NPT and CGT (ours).

NPT and CGT are supervised on same-skeleton pairs only: no cross-category pair has a ground truth,
so the transfers the ``cct`` protocol scores are never trained. This term is the analogue of
SFPT's cross-transfer term for them. For a character A posed and a character B at rest of
different kinds (a humanoid-like character on exactly one side, the ``cct`` protocol's pairs,
:func:`cross_category_pairs`), all in the centred unit-size frames of
:mod:`mimicbench.baselines.npt.placement`:

- forward leg ``B' = f(pose=A posed, identity=B rest)``;
- return leg ``A'' = f(pose=B' re-centred at its box centre, identity=A rest)``, as the ``cct``
  protocol's return leg sees the forward answer (:func:`mimicbench.baselines.npt.placement.centred`);
- ``cycle``: NPT's per-coordinate MSE of A'' against A posed;
- ``cycle_edge``: NPT's edge term (:func:`mimicbench.baselines.npt.losses.edge_ratio`) of B' against B's rest
  mesh over k-NN pairs of B's points, so that B' stays a near-isometric deformation of B and
  cannot degenerate into a code for A's pose (or into A itself).

The gradient flows through both legs. :func:`cycle_terms` takes the model as a callable, so
``npt`` and ``cgt`` (whose calls need capped attention rows) share it.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import torch

from mimicbench.baselines.npt.losses import edge_ratio, vertex_mse
from mimicbench.baselines.npt.placement import centred
from mimicbench.baselines.pose_pairs import PosePool, knn_pairs, subsample
from mimicbench.runtime.errors import UserError
from mimicbench.schemas.character import HUMANOID_LIKE

Answer = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]
"""A model call: posed source (B, Ns, 3) and identity (B, Nt, 3) -> answer (B, Nt, 3)."""


def cross_category_pairs(pool: PosePool) -> list[tuple[str, str]]:
    """Sorted ordered (A, B) character IDs of ``pool`` with a humanoid-like character on exactly one side."""
    human = {cid: pool.records[cid].category in HUMANOID_LIKE for cid in pool.ids}
    return [(a, b) for a in pool.ids for b in pool.ids if human[a] != human[b]]


def box_centred(points: torch.Tensor) -> torch.Tensor:
    """(B, N, 3) points minus their own axis-aligned box centre (per example; differentiable)."""
    return points - (points.amax(dim=1, keepdim=True) + points.amin(dim=1, keepdim=True)) / 2.0


def cycle_item(pool: PosePool, a: str, b: str, config: dict, rng: np.random.Generator) -> dict:
    """One cycle example's arrays, centred unit-size frames: ``cycle_pose`` (Pa, 3) A posed,
    ``cycle_mid`` (Pb, 3) B rest, ``cycle_back`` (Pa, 3) A rest at the same rows as ``cycle_pose``
    (which is also the cycle's target), ``cycle_edges`` (Pb*k, 2) k-NN pairs of ``cycle_mid``."""
    a_rest = np.asarray(pool.records[a].vertices, np.float32)
    b_rest = np.asarray(pool.records[b].vertices, np.float32)
    a_posed = pool.posed(a, pool.draw_pose(a, rng))
    ra = subsample(len(a_rest), config["points"], rng)
    rb = subsample(len(b_rest), config["points"], rng)
    pose = centred(a_posed, a_rest)[ra]
    mid = centred(b_rest, b_rest)[rb]
    return {"cycle_pose": pose, "cycle_mid": mid, "cycle_back": centred(a_rest, a_rest)[ra],
            "cycle_edges": knn_pairs(mid, config["knn"])}


def cycle_batch(pool: PosePool, pairs: list[tuple[str, str]], config: dict, rng: np.random.Generator) -> dict:
    """``config["cycle_batch"]`` cycle examples of random ``pairs``, stacked (equal point counts) or,
    with ``points`` <= 0, as lists of (1, N, 3) arrays: ``{"cycle_pose", ...}`` as :func:`cycle_item`."""
    if not pairs:
        raise UserError("the cycle term (cycle_batch > 0) needs characters of different kinds (a humanoid and a "
                        "non-humanoid with a mesh and clips); this dataset has none: set cycle_batch=0")
    picks = rng.integers(0, len(pairs), size=int(config["cycle_batch"]))
    items = [cycle_item(pool, *pairs[int(i)], config, np.random.default_rng(int(rng.integers(2**31 - 1))))
             for i in picks]
    if config["points"] <= 0:
        return {k: [it[k][None] for it in items] for k in items[0]}
    return {k: np.stack([it[k] for it in items]) for k in items[0]}


def cycle_terms(answer: Answer, pose: torch.Tensor, mid: torch.Tensor, back: torch.Tensor,
                edges: torch.Tensor, detach_forward: bool = False) -> dict:
    """``{"cycle", "cycle_edge", "forward"}`` of one cycle batch.

    Args:
        answer: the model call (:data:`Answer`).
        pose: (B, Na, 3) A posed (also the cycle's target); mid: (B, Nb, 3) B rest; back: (B, Na, 3) A
            rest at ``pose``'s rows; edges: (B, E, 2) or (E, 2) pairs of ``mid``'s rows.
        detach_forward: the return leg reads B' without a gradient into it, so the cycle trains only the
            return leg (B' -> A) and cannot teach the forward leg to hide A's pose in B'.
    Returns:
        ``cycle`` the MSE of A'' against ``pose``, ``cycle_edge`` the edge term of B' against ``mid``
        (scalars), ``forward`` B' (B, Nb, 3).
    """
    forward = answer(pose, mid)
    back_answer = answer(box_centred(forward.detach() if detach_forward else forward), back)
    return {"cycle": vertex_mse(back_answer, pose), "cycle_edge": edge_ratio(forward, mid, edges), "forward": forward}


def add_cycle(terms: dict, answer: Answer, batch: dict, config: dict) -> dict:
    """``terms`` (a loss dict with ``total``) plus the cycle terms of ``batch``'s ``cycle_*`` tensors, weighted
    ``w_cycle`` and ``w_cycle_edge`` into ``total``; ``terms`` unchanged when the batch has none."""
    if "cycle_pose" not in batch:
        return terms
    keys = ("cycle_pose", "cycle_mid", "cycle_back", "cycle_edges")
    detach = bool(config.get("cycle_detach", False))
    parts = [batch[k] for k in keys]
    if isinstance(parts[0], (list, tuple)):  # whole meshes: one example a call (the trainer moves no lists)
        device = batch["pose"].device
        outs = [cycle_terms(answer, *(torch.as_tensor(x, device=device) for x in one), detach_forward=detach)
                for one in zip(*parts)]
        cyc = {k: sum(o[k] for o in outs) / len(outs) for k in ("cycle", "cycle_edge")}
    else:
        cyc = cycle_terms(answer, *parts, detach_forward=detach)
    total = terms["total"] + float(config["w_cycle"]) * cyc["cycle"] + float(config["w_cycle_edge"]) * cyc["cycle_edge"]
    return {**terms, "total": total, "cycle": cyc["cycle"], "cycle_edge": cyc["cycle_edge"]}
