"""Spatially adaptive instance normalisation (SPAdaIN, NPT Sec. 3.2) and its residual block.

SPAdaIN(x, m) = IN(x) * gamma(m) + beta(m): the features x (B, C, N) are instance-normalised per
channel over the N points (no affine parameters), then scaled and shifted point by point by two
1x1 convolutions of the identity mesh's vertices m (B, 3, N) (the same points, in the same order).

With ``normalise=False`` the instance norm is left out: x * gamma(m) + beta(m). The published
max-pool decoder's first residual block is built that way, so the pose code, which is the same at
every point, is not subtracted before the decoder has mixed it with the identity points.
"""
from __future__ import annotations

import torch
from torch import nn

EPS = 1e-5


class SPAdaIN(nn.Module):
    """SPAdaIN over ``channels`` feature channels conditioned on ``cond`` channels (3: xyz)."""

    def __init__(self, channels: int, cond: int = 3, normalise: bool = True):
        super().__init__()
        self.norm = nn.InstanceNorm1d(channels, affine=False, eps=EPS) if normalise else None
        self.gamma = nn.Conv1d(cond, channels, 1)
        self.beta = nn.Conv1d(cond, channels, 1)

    def forward(self, x: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        """x (B, C, N), identity (B, cond, N) -> (B, C, N)."""
        h = self.norm(x) if self.norm is not None else x
        return h * self.gamma(identity) + self.beta(identity)


class SPAdaINResBlock(nn.Module):
    """Two SPAdaIN -> ReLU -> 1x1 conv steps plus a SPAdaIN -> ReLU -> 1x1 conv shortcut, all
    ``channels`` wide (the published block keeps its width; the decoder's convs between blocks change it).

    Args:
        channels: feature width C; cond: identity channels; normalise: instance norm in every SPAdaIN.
    """

    def __init__(self, channels: int, cond: int = 3, normalise: bool = True):
        super().__init__()
        self.norm1, self.conv1 = SPAdaIN(channels, cond, normalise), nn.Conv1d(channels, channels, 1)
        self.norm2, self.conv2 = SPAdaIN(channels, cond, normalise), nn.Conv1d(channels, channels, 1)
        self.norm_s, self.conv_s = SPAdaIN(channels, cond, normalise), nn.Conv1d(channels, channels, 1)

    @property
    def normalised(self) -> bool:
        return self.norm1.norm is not None

    def forward(self, x: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        """x (B, C, N), identity (B, cond, N) -> (B, C, N)."""
        h = self.conv1(torch.relu(self.norm1(x, identity)))
        h = self.conv2(torch.relu(self.norm2(h, identity)))
        return h + self.conv_s(torch.relu(self.norm_s(x, identity)))
