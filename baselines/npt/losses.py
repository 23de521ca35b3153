"""NPT's training loss (Sec. 3.3): per-coordinate mean squared vertex error plus an edge term.

The edge term compares squared edge lengths relatively, |l_pred^2 / l_truth^2 - 1| averaged over
edges (truth lengths floored at 1e-8), weighted 0.0005 as in the paper.
"""
from __future__ import annotations

import torch


def vertex_mse(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Mean over every coordinate of (pred - truth)^2, (..., N, 3) each."""
    return ((pred - truth) ** 2).mean()


def edge_ratio(pred: torch.Tensor, truth: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean of |l_pred^2 / l_truth^2 - 1| over edges (B, E, 2) (or (E, 2)) of (B, N, 3) positions."""
    if edges.numel() == 0:
        return pred.sum() * 0.0
    if edges.dim() == 2:
        edges = edges.expand(pred.shape[0], -1, -1)

    def sq_lengths(x):
        a = torch.gather(x, 1, edges[..., :1].expand(-1, -1, 3))
        b = torch.gather(x, 1, edges[..., 1:].expand(-1, -1, 3))
        return ((a - b) ** 2).sum(-1)

    return (sq_lengths(pred) / sq_lengths(truth).clamp_min(1e-8) - 1.0).abs().mean()


def npt_loss(pred: torch.Tensor, truth: torch.Tensor, edges: torch.Tensor, w_edge: float) -> dict:
    """``{"total", "mse", "edge"}`` for predictions and truths (B, N, 3), edges (B, E, 2)."""
    mse, edge = vertex_mse(pred, truth), edge_ratio(pred, truth, edges)
    return {"total": mse + w_edge * edge, "mse": mse, "edge": edge}
