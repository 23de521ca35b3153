"""MMDMC's losses (Eq. 8-10 body, Eq. 14-15 apparel), on tensors in the
character's unit-height frame. Weights (``config.py``, the paper's): vertex 1.0, edge 100,
smoothness and regulariser 0.01.
"""
from __future__ import annotations

import torch


def vertex_l1(pred: torch.Tensor, truth: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over vertices of the L1 distance between (..., N, 3) positions (Eq. 8); ``mask`` (..., N) bool
    restricts to some vertices (none selected gives 0)."""
    d = (pred - truth).abs().sum(-1)
    if mask is None:
        return d.mean()
    m = mask.to(d.dtype).expand_as(d)
    return (d * m).sum() / m.sum().clamp_min(1.0)


def edge_length(pred: torch.Tensor, truth: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of edge lengths (Eq. 9): (..., N, 3) positions, (E, 2) edges."""
    if edges.numel() == 0:
        return pred.sum() * 0.0
    lp = (pred[..., edges[:, 0], :] - pred[..., edges[:, 1], :]).norm(dim=-1)
    lt = (truth[..., edges[:, 0], :] - truth[..., edges[:, 1], :]).norm(dim=-1)
    return ((lp - lt) ** 2).mean()


def edge_stretch(pred: torch.Tensor, truth: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean relative stretch |l_pred / l_truth - 1| over (E, 2) mesh edges of (..., N, 3) positions: the
    quantity ELS averages (ELS = 1 - this over all unique edges). Truth lengths are floored at 1e-8."""
    if edges.numel() == 0:
        return pred.sum() * 0.0
    lp = (pred[..., edges[:, 0], :] - pred[..., edges[:, 1], :]).norm(dim=-1)
    lt = (truth[..., edges[:, 0], :] - truth[..., edges[:, 1], :]).norm(dim=-1)
    return (lp / lt.clamp_min(1e-8) - 1.0).abs().mean()


def weight_smoothness(weights: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean over edges of the L1 difference of the two ends' skinning weights (Eq. 10): (..., N, K), (E, 2)."""
    if edges.numel() == 0:
        return weights.sum() * 0.0
    return (weights[..., edges[:, 0], :] - weights[..., edges[:, 1], :]).abs().sum(-1).mean()


def l2_regulariser(x: torch.Tensor) -> torch.Tensor:
    """Mean squared norm of displacements or corrections (..., N, 3)."""
    return (x ** 2).sum(-1).mean()


def weighted_total(terms: dict, config: dict) -> dict:
    """``terms`` (vertex/edge/smooth/reg) plus ``total``, their sum with the config's ``w_<name>``."""
    total = sum(config[f"w_{k}"] * v for k, v in terms.items())
    return {"total": total, **terms}
