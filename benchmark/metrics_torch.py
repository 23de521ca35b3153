"""Torch twins of :mod:`mimicbench.benchmark.metrics`, batched: tensors (B, N, 3), results (B,).

``target_rest_vertices`` is (B, N, 3) or (N, 3); ``by`` is ``height`` (Y extent) or ``extent``
(largest side of the bounding box), as in :mod:`mimicbench.benchmark.normalisation`.
"""
from __future__ import annotations

import torch

from mimicbench.benchmark.normalisation import NORMALISATIONS


def _scale(target_rest_vertices: torch.Tensor, by: str) -> torch.Tensor:
    """(B,) or () normalisation length of each rest mesh."""
    side = target_rest_vertices.amax(dim=-2) - target_rest_vertices.amin(dim=-2)  # (..., 3)
    if by == "height":
        return side[..., 1]
    if by == "extent":
        return side.amax(dim=-1)
    raise ValueError(f"by: expected one of {', '.join(NORMALISATIONS)}, got {by!r}")


def pmd_torch(pred: torch.Tensor, ref: torch.Tensor, target_rest_vertices: torch.Tensor,
              by: str = "height") -> torch.Tensor:
    """PMD x100 per batch item: pred, ref (B, N, 3)."""
    s = _scale(target_rest_vertices, by)
    return ((pred - ref).norm(dim=-1) / s[..., None]).mean(dim=-1) * 100.0


def pmd_aligned_torch(pred: torch.Tensor, ref: torch.Tensor, target_rest_vertices: torch.Tensor,
                      by: str = "height") -> torch.Tensor:
    """PMD x100 per batch item after centring pred and ref (B, N, 3) on their own centroids."""
    return pmd_torch(pred - pred.mean(dim=-2, keepdim=True), ref - ref.mean(dim=-2, keepdim=True),
                     target_rest_vertices, by)


def pmd_squared_torch(pred: torch.Tensor, ref: torch.Tensor, target_rest_vertices: torch.Tensor,
                      by: str = "height") -> torch.Tensor:
    """NPT-style squared PMD x100 per batch item."""
    s = _scale(target_rest_vertices, by)
    return ((pred - ref) / s[..., None, None]).pow(2).sum(dim=-1).mean(dim=-1) * 100.0


def els_torch(pred: torch.Tensor, ref: torch.Tensor, edges: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """ELS per batch item: pred, ref (B, N, 3); edges (E, 2) long."""
    e = edges.long()
    lp = (pred[..., e[:, 0], :] - pred[..., e[:, 1], :]).norm(dim=-1)
    lr = (ref[..., e[:, 0], :] - ref[..., e[:, 1], :]).norm(dim=-1)
    keep = lr > eps
    ratio = torch.where(keep, (lp / lr.clamp_min(eps) - 1.0).abs(), torch.zeros_like(lp))
    return 1.0 - ratio.sum(dim=-1) / keep.sum(dim=-1)
