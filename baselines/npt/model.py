"""The Neural Pose Transfer network (Wang et al., CVPR 2020, Fig. 2), max-pool variant, re-implemented
from the paper and the authors' public code (read, not copied).

- Pose encoder: PointNet-style 1x1 convolutions 3 -> c1 -> c2 -> c3 over the posed source's points,
  each followed by instance norm and ReLU; a max over the points gives the pose code (B, c3), so
  source and target vertex counts may differ.
- Decoder (``b = c3 + 3`` wide, 1027 in the paper): the code repeated at every target point and
  concatenated with the point's identity coordinates; then
  ``conv b->b, block 1 (b), conv b->b/2, block 2 (b/2), conv b/2->b/4, block 3 (b/4), conv -> xyz``,
  squashed by 2 tanh. Each block is a :class:`mimicbench.baselines.npt.spadain.SPAdaINResBlock` conditioned on
  the identity coordinates; **block 1 has no instance normalisation** (it would subtract the code,
  a per-channel constant over the points), blocks 2 and 3 normalise.

``residual`` (config key, ours, in the ``cpu`` preset only): the answer is the identity point plus the
2 tanh output, whose last conv starts at zero, so an untrained network answers the rest pose and
CPU-scale training spends its steps on the pose. Inputs and outputs are in the centred unit-size
frames of :mod:`mimicbench.baselines.npt.placement`.
"""
from __future__ import annotations

import torch
from torch import nn

from mimicbench.baselines.npt.spadain import SPAdaINResBlock


class PointFeatures(nn.Module):
    """Per-point features (B, c3, N) of points (B, 3, N): 1x1 convs with instance norm and ReLU."""

    def __init__(self, widths: tuple[int, int, int]):
        super().__init__()
        layers, c = [], 3
        for w in widths:
            layers += [nn.Conv1d(c, w, 1), nn.InstanceNorm1d(w), nn.ReLU()]
            c = w
        self.net = nn.Sequential(*layers)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.net(points)


class PoseEncoder(nn.Module):
    """Pose code (B, c3) of posed points (B, 3, N): a max over :class:`PointFeatures`."""

    def __init__(self, widths: tuple[int, int, int]):
        super().__init__()
        self.features = PointFeatures(widths)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.features(points).max(dim=2).values


class NptDecoder(nn.Module):
    """Posed target (B, 3, N) from the input (B, b, N) (code and identity coordinates) and identity (B, 3, N)."""

    def __init__(self, width: int, residual: bool = False):
        super().__init__()
        w = (width, width // 2, width // 4)
        self.convs = nn.ModuleList([nn.Conv1d(width, w[0], 1), nn.Conv1d(w[0], w[1], 1), nn.Conv1d(w[1], w[2], 1)])
        self.blocks = nn.ModuleList([SPAdaINResBlock(w[0], normalise=False), SPAdaINResBlock(w[1]),
                                     SPAdaINResBlock(w[2])])
        self.out = nn.Conv1d(w[2], 3, 1)
        self.residual = bool(residual)
        if self.residual:
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        for conv, block in zip(self.convs, self.blocks):
            x = block(conv(x), identity)
        out = 2.0 * torch.tanh(self.out(x))
        return identity + out if self.residual else out


class NeuralPoseTransfer(nn.Module):
    """NPT: pose encoder + SPAdaIN decoder.

    Args:
        widths: the pose encoder's (c1, c2, c3); the decoder is c3 + 3 wide.
        residual: the decoder answers offsets from the identity points (module docstring).
    """

    def __init__(self, widths=(64, 128, 1024), residual: bool = False):
        super().__init__()
        widths = tuple(int(w) for w in widths)
        self.encoder = PoseEncoder(widths)
        self.decoder = NptDecoder(widths[-1] + 3, residual)

    def forward(self, posed_source: torch.Tensor, identity: torch.Tensor,
                code: torch.Tensor | None = None) -> torch.Tensor:
        """posed_source (B, Ns, 3), identity (B, Nt, 3), centred unit-size frames -> (B, Nt, 3).

        ``code`` (B, c3), when given, stands in for the pose code of ``posed_source`` (the
        ``npt_constant_code`` ablation).
        """
        if code is None:
            code = self.encoder(posed_source.transpose(1, 2))
        ident = identity.transpose(1, 2)
        x = torch.cat([code[:, :, None].expand(-1, -1, ident.shape[2]), ident], dim=1)
        return self.decoder(x, ident).transpose(1, 2)
