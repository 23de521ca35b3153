"""Apparel segmentation f_c (MMDMC Sec. 4.1): a PointNet-style encoder on the rest vertex
positions and an MLP decoder to a per-vertex apparel logit (probability after a sigmoid).

Input positions are in the character's unit-height frame (centre of the rest bounding box,
divided by the rest height; :func:`baselines.mmdmc.data.normalise`).
"""
from __future__ import annotations

import torch
from torch import nn


def mlp(sizes: list[int], last_act: bool = True) -> nn.Sequential:
    """Linear layers of ``sizes`` with ReLU between (and after the last when ``last_act``)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if last_act or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ApparelSegmenter(nn.Module):
    """f_c: (B, N, 3) normalised rest positions -> (B, N) apparel logits."""

    def __init__(self, hidden: int = 64):
        super().__init__()
        self.local = mlp([3, hidden, 2 * hidden])
        self.globl = mlp([2 * hidden, 4 * hidden])
        self.decoder = mlp([6 * hidden, 2 * hidden, hidden, 1], last_act=False)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"points: expected (B, N, 3), got {tuple(points.shape)}")
        local = self.local(points)
        g = self.globl(local).max(dim=1).values  # (B, 4h)
        feat = torch.cat([local, g[:, None].expand(-1, points.shape[1], -1)], dim=-1)
        return self.decoder(feat)[..., 0]
