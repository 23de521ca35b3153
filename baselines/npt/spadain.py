"""Spatially adaptive instance normalisation (SPAdaIN, NPT Sec. 3.2) and its residual block.

SPAdaIN(x, m) = IN(x) * gamma(m) + beta(m): the features x (B, C, N) are instance-normalised per
channel over the N points (no affine parameters), then scaled and shifted point by point by two
1x1 convolutions of the identity mesh's vertices m (B, 3, N) (the same points, in the same order).

With ``code`` > 0 (ours, the decoders' ``pose_cond`` option) gamma and beta also take a global pose code
z (B, code): gamma = conv(m) + A z, beta = conv(m) + B z (AdaIN's per-sample modulation added to
SPAdaIN's per-point one). A code repeated at every point and fed into x is a per-channel constant
that the norm subtracts; in the modulation it scales and shifts features that vary point by point,
so the answer follows the pose.
"""
from __future__ import annotations

import torch
from torch import nn

EPS = 1e-5


class SPAdaIN(nn.Module):
    """SPAdaIN over ``channels`` feature channels conditioned on ``cond`` channels (3: xyz)."""

    def __init__(self, channels: int, cond: int = 3, code: int = 0):
        super().__init__()
        self.norm = nn.InstanceNorm1d(channels, affine=False, eps=EPS)
        self.gamma = nn.Conv1d(cond, channels, 1)
        self.beta = nn.Conv1d(cond, channels, 1)
        self.gamma_code = nn.Linear(code, channels, bias=False) if code else None
        self.beta_code = nn.Linear(code, channels, bias=False) if code else None

    def forward(self, x: torch.Tensor, identity: torch.Tensor, code: torch.Tensor | None = None) -> torch.Tensor:
        """x (B, C, N), identity (B, cond, N), code (B, code) when built with one -> (B, C, N)."""
        gamma, beta = self.gamma(identity), self.beta(identity)
        if self.gamma_code is not None:
            gamma = gamma + self.gamma_code(code)[:, :, None]
            beta = beta + self.beta_code(code)[:, :, None]
        return self.norm(x) * gamma + beta


class SPAdaINResBlock(nn.Module):
    """Two SPAdaIN -> ReLU -> 1x1 conv steps, plus a SPAdaIN -> ReLU -> 1x1 conv shortcut
    (the shortcut changes the width from ``c_in`` to ``c_out``)."""

    def __init__(self, c_in: int, c_out: int, cond: int = 3, code: int = 0):
        super().__init__()
        self.norm1, self.conv1 = SPAdaIN(c_in, cond, code), nn.Conv1d(c_in, c_in, 1)
        self.norm2, self.conv2 = SPAdaIN(c_in, cond, code), nn.Conv1d(c_in, c_out, 1)
        self.norm_s, self.conv_s = SPAdaIN(c_in, cond, code), nn.Conv1d(c_in, c_out, 1)

    def forward(self, x: torch.Tensor, identity: torch.Tensor, code: torch.Tensor | None = None) -> torch.Tensor:
        """x (B, c_in, N), identity (B, cond, N), code (B, code) or None -> (B, c_out, N)."""
        h = self.conv1(torch.relu(self.norm1(x, identity, code)))
        h = self.conv2(torch.relu(self.norm2(h, identity, code)))
        return h + self.conv_s(torch.relu(self.norm_s(x, identity, code)))
