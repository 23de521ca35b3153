"""Torch twins of :mod:`benchmark.metrics`, batched: tensors (B, N, 3), results (B,)."""
from __future__ import annotations

import torch


def _height(target_rest_vertices: torch.Tensor) -> torch.Tensor:
    y = target_rest_vertices[..., 1]
    return (y.max(dim=-1).values - y.min(dim=-1).values)


def pmd_torch(pred: torch.Tensor, ref: torch.Tensor, target_rest_vertices: torch.Tensor) -> torch.Tensor:
    """PMD x100 per batch item: pred, ref (B, N, 3); target_rest_vertices (B, N, 3) or (N, 3)."""
    h = _height(target_rest_vertices)
    d = (pred - ref).norm(dim=-1) / h[..., None]
    return d.mean(dim=-1) * 100.0


def pmd_squared_torch(pred: torch.Tensor, ref: torch.Tensor, target_rest_vertices: torch.Tensor) -> torch.Tensor:
    """NPT-style squared PMD x100 per batch item."""
    h = _height(target_rest_vertices)
    d2 = ((pred - ref) / h[..., None, None]).pow(2).sum(dim=-1)
    return d2.mean(dim=-1) * 100.0


def els_torch(pred: torch.Tensor, ref: torch.Tensor, edges: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """ELS per batch item: pred, ref (B, N, 3); edges (E, 2) long."""
    e = edges.long()
    lp = (pred[..., e[:, 0], :] - pred[..., e[:, 1], :]).norm(dim=-1)
    lr = (ref[..., e[:, 0], :] - ref[..., e[:, 1], :]).norm(dim=-1)
    keep = lr > eps
    ratio = torch.where(keep, (lp / lr.clamp_min(eps) - 1.0).abs(), torch.zeros_like(lp))
    return 1.0 - ratio.sum(dim=-1) / keep.sum(dim=-1)
