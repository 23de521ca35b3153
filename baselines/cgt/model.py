"""The CGT network (Chen et al., AAAI 2022), re-implemented from the paper and the authors' public
code (read, not copied): NPT's SPAdaIN decoder with a geometry-contrastive attention block (CGPBlock)
before each of its residual blocks.

- One point encoder, shared by both meshes: :class:`mimicbench.baselines.npt.model.PointFeatures` (1x1 convs 3 ->
  c1 -> c2 -> c3, instance norm, ReLU) of the posed source, P (B, c3, Ns), and of the target rest
  mesh, I (B, c3, Nt). No max pool: the attention reads per-point features.
- Four stages at widths ``(w, w/2, w/2, w/4)`` (1024, 512, 512, 256 in the paper, ``w = c3``). Stage k:
  one 1x1 conv ``conv_k``, shared by the three streams, maps the decoder stream X (target rows), the
  pose features P and the identity features I to width w_k; then :class:`CGPBlock` adds to X the pose
  features gathered by attention; then a :class:`mimicbench.baselines.npt.spadain.SPAdaINResBlock` (with instance
  norm, as in the published CGT decoder) conditioned on the target's rest coordinates.
- Output: a 1x1 conv to xyz, 2 tanh (``residual``, ours, ``cpu`` preset: plus the rest points, the conv
  starting at zero, as NPT's).

X starts as the identity features I. The published code runs on meshes that share one vertex order
(SMPL, SMAL), so its stream is indexed by the pose mesh's vertices and is also the target's; the zoo's
meshes share no vertex order, so here the stream lives on the target's points and the attention is what
carries the pose onto them (docs/methods/published-deviations.md).

Attention rows: every target point, keys and values over the pose points in ``pose_rows`` (all points
when None: the paper's dense attention; :mod:`mimicbench.baselines.cgt.sampling` caps them on CPU).
"""
from __future__ import annotations

import torch
from torch import nn

from mimicbench.baselines.npt.model import PointFeatures
from mimicbench.baselines.npt.spadain import SPAdaINResBlock


class CGPBlock(nn.Module):
    """Single-head attention without normalisation, residual with a gain that starts at zero.

    ``energy[p, q] = query(P)[:, p] . key(I)[:, q]`` (query from the pose, key from the identity, no
    scaling); each target point q takes the softmax over the pose points p of its column and gathers
    ``value(P)``; the block returns ``X + gain * gathered``.

    Args:
        width: channels C of X, P and I.
    """

    def __init__(self, width: int):
        super().__init__()
        self.query = nn.Conv1d(width, width, 1)
        self.key = nn.Conv1d(width, width, 1)
        self.value = nn.Conv1d(width, width, 1)
        self.gain = nn.Parameter(torch.zeros(1))

    def attention(self, pose: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        """(B, Ns, Nt) weights, each column a softmax over the pose points: pose (B, C, Ns), identity (B, C, Nt)."""
        energy = torch.bmm(self.query(pose).transpose(1, 2), self.key(identity))
        return torch.softmax(energy, dim=1)

    def forward(self, stream: torch.Tensor, pose: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        """stream (B, C, Nt), pose (B, C, Ns), identity (B, C, Nt) -> (B, C, Nt)."""
        return stream + self.gain * torch.bmm(self.value(pose), self.attention(pose, identity))


def stage_widths(width: int) -> tuple[int, int, int, int]:
    """The four stages' widths of a decoder ``width`` wide: (w, w/2, w/2, w/4)."""
    return width, width // 2, width // 2, width // 4


class Cgt(nn.Module):
    """CGT: shared point encoder, four conv -> CGPBlock -> SPAdaIN stages, xyz head.

    Args:
        widths: the point encoder's (c1, c2, c3); the decoder starts c3 wide.
        attention: False removes every CGPBlock (the ``cgt_no_attention`` ablation's network).
        residual: the decoder answers offsets from the identity points.
    """

    def __init__(self, widths=(64, 128, 1024), residual: bool = False, attention: bool = True):
        super().__init__()
        widths = tuple(int(w) for w in widths)
        w = stage_widths(widths[-1])
        self.encoder = PointFeatures(widths)
        ins = (widths[-1],) + w[:-1]
        self.convs = nn.ModuleList([nn.Conv1d(a, b, 1) for a, b in zip(ins, w)])
        self.cgp = nn.ModuleList([CGPBlock(c) for c in w])
        self.blocks = nn.ModuleList([SPAdaINResBlock(c) for c in w])
        self.attention = bool(attention)
        self.out = nn.Conv1d(w[-1], 3, 1)
        self.residual = bool(residual)
        if self.residual:
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)

    def forward(self, posed_source: torch.Tensor, identity: torch.Tensor,
                pose_rows: torch.Tensor | None = None) -> torch.Tensor:
        """posed_source (B, Ns, 3), identity (B, Nt, 3) centred unit-size frames -> (B, Nt, 3).

        With ``pose_rows`` (Ms,) the attention reads those pose points only.
        """
        xyz = identity.transpose(1, 2)
        pose = self.encoder(posed_source.transpose(1, 2))  # (B, C, Ns)
        if pose_rows is not None:
            pose = pose[:, :, pose_rows]
        ident = self.encoder(xyz)  # (B, C, Nt)
        stream = ident
        for conv, cgp, block in zip(self.convs, self.cgp, self.blocks):
            stream, pose, ident = conv(stream), conv(pose), conv(ident)
            if self.attention:
                stream = cgp(stream, pose, ident)
            stream = block(stream, xyz)
        out = 2.0 * torch.tanh(self.out(stream))
        return (xyz + out).transpose(1, 2) if self.residual else out.transpose(1, 2)
