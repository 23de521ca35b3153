"""Apparel segmentation f_c (MMDMC Sec. 4.1): a PointNet-style encoder on the rest vertex
positions and an MLP decoder to a per-vertex apparel logit (probability after a sigmoid).

Input positions are in the character's unit-height frame (centre of the rest bounding box,
divided by the rest height; :func:`mimicbench.baselines.mmdmc.data.normalise`).

``seg_inputs="bones"`` (ours, config) adds two per-vertex channels from the rig a request carries
(never its weights): the distance to the nearest body bone and to the nearest apparel bone (unit
height, clipped at 1; :func:`segmenter_inputs`).

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.baselines.mmdmc.chain_attachment import prepared_attachment
from mimicbench.baselines.mmdmc.nn import mlp

SEG_INPUTS = {"positions": 3, "bones": 5}
"""Input channels of f_c per ``seg_inputs`` setting."""


def segmenter_inputs(prep, channels: int) -> np.ndarray:
    """(N, channels) float32 input of f_c for a :class:`~mimicbench.baselines.mmdmc.data.Prepared` character:
    unit-height rest positions (3 channels), then (5 channels) the distances to the nearest body bone
    and to the nearest apparel bone, divided by the height and clipped at 1."""
    if channels not in SEG_INPUTS.values():
        raise ValueError(f"f_c input channels: expected one of {sorted(SEG_INPUTS.values())}, got {channels}")
    x = prep.rest_norm
    if channels == 3:
        return x
    body = prep.bone.min(axis=1)
    apparel = prepared_attachment(prep)[1]
    return np.concatenate([x, np.minimum(np.stack([body, apparel], 1), 1.0)], 1).astype(np.float32)


class ApparelSegmenter(nn.Module):
    """f_c: (B, N, C) inputs (:func:`segmenter_inputs`: normalised rest positions first) -> (B, N) apparel logits."""

    def __init__(self, hidden: int = 64, channels: int = 3):
        super().__init__()
        self.channels = channels
        self.local = mlp([channels, hidden, 2 * hidden])
        self.globl = mlp([2 * hidden, 4 * hidden])
        self.decoder = mlp([6 * hidden, 2 * hidden, hidden, 1], last_act=False)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != self.channels:
            raise ValueError(f"points: expected (B, N, {self.channels}), got {tuple(points.shape)}")
        local = self.local(points)
        g = self.globl(local).max(dim=1).values  # (B, 4h)
        feat = torch.cat([local, g[:, None].expand(-1, points.shape[1], -1)], dim=-1)
        return self.decoder(feat)[..., 0]
