"""The Skeleton-free Pose Transfer networks (Liao et al., ECCV 2022, Sec. 3), written from the paper.

- :class:`MeshEncoder`: EdgeConv layers (MMDMC's :class:`baselines.mmdmc.apparel.EdgeConv`, a gather
  over each vertex's k nearest rest neighbours and a max) whose outputs are concatenated with a
  global max-pooled feature: per-vertex features of a mesh.
- :class:`SkinningPredictor`: handle weights W (N, H), a softmax over H handles of per-vertex logits
  from the encoder on the rest mesh (each row sums to 1). Ours, for CPU-scale training: the logits
  add a spatial prior, ``-|x - a_k|^2 / (2 s^2)`` with learned anchors a_k (drawn in the unit-height
  box) and a learned width s, so the handles start as soft regions of the mesh rather than one
  uniform blend, and the network learns the rest.
- :class:`PosePredictor`: per-handle transforms from the rest and posed source: per-vertex features of
  (rest, posed, posed - rest) pooled per handle with the source's W, with the handle's rest and posed
  centres, decoded to a quaternion and a translation. Ours, for CPU-scale training: both are
  residuals, the quaternion on the handle's weighted Kabsch rotation (rest onto posed under W,
  :func:`baselines.sfpt.handles.fitted_rotations`, no gradient), the translation on the handle
  centre's displacement, so the network starts from the handles' own fitted motion.

All positions are in the mesh's unit-height rest frame (rest box centre, divided by the rest height);
the posed source in its own rest frame, so handle translations carry the global motion.
"""
from __future__ import annotations

import torch
from torch import nn

from baselines.mmdmc.apparel import EdgeConv
from baselines.mmdmc.segmentation import mlp
from baselines.sfpt.handles import fitted_rotations, handle_centres
from mimicbench.skinning_torch import quat_to_matrix_torch


class MeshEncoder(nn.Module):
    """Per-vertex features (B, N, 3 hidden + glob) of inputs (B, N, c_in) over neighbours (N, k)."""

    def __init__(self, c_in: int, hidden: int, glob: int):
        super().__init__()
        self.convs = nn.ModuleList([EdgeConv(c_in, hidden), EdgeConv(hidden, hidden), EdgeConv(hidden, hidden)])
        self.glob = mlp([3 * hidden, glob])

    @property
    def width(self) -> int:
        return 3 * self.convs[0].mlp[-2].out_features + self.glob[0].out_features

    def forward(self, x: torch.Tensor, neighbours: torch.Tensor) -> torch.Tensor:
        feats = []
        for conv in self.convs:
            x = conv(x, neighbours)
            feats.append(x)
        local = torch.cat(feats, -1)
        g = self.glob(local).max(dim=1, keepdim=True).values.expand(-1, local.shape[1], -1)
        return torch.cat([local, g], -1)


class SkinningPredictor(nn.Module):
    """Handle weights (B, N, H) of rest vertices (B, N, 3), rows summing to 1."""

    def __init__(self, hidden: int, handles: int):
        super().__init__()
        self.encoder = MeshEncoder(3, hidden, 2 * hidden)
        self.head = mlp([self.encoder.width, 2 * hidden, hidden, handles], last_act=False)
        self.anchors = nn.Parameter(torch.rand(handles, 3) - 0.5)
        self.log_width = nn.Parameter(torch.tensor(-2.0))  # s = e^-2 = 0.14 of the height

    def forward(self, rest: torch.Tensor, neighbours: torch.Tensor) -> torch.Tensor:
        prior = -((rest[..., :, None, :] - self.anchors) ** 2).sum(-1) / (2 * torch.exp(2 * self.log_width))
        return torch.softmax(self.head(self.encoder(rest, neighbours)) + prior, dim=-1)


class PosePredictor(nn.Module):
    """Handle transforms of a posed source: rotations (B, H, 3, 3) and translations (B, H, 3)."""

    def __init__(self, hidden: int, handles: int):
        super().__init__()
        self.encoder = MeshEncoder(9, hidden, 2 * hidden)
        self.head = mlp([self.encoder.width + 6 + handles, 2 * hidden, hidden, 7], last_act=False)
        self.handles = handles

    def forward(self, rest: torch.Tensor, posed: torch.Tensor, weights: torch.Tensor,
                neighbours: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """rest, posed (B, N, 3), weights (B, N, H), neighbours (N, k)."""
        f = self.encoder(torch.cat([rest, posed, posed - rest], -1), neighbours)  # (B, N, C)
        pooled = handle_centres(f, weights)  # weight-averaged features (B, H, C)
        c_rest, c_posed = handle_centres(rest, weights), handle_centres(posed, weights)
        onehot = torch.eye(self.handles, dtype=f.dtype, device=f.device).expand(f.shape[0], -1, -1)
        out = self.head(torch.cat([pooled, c_rest, c_posed, onehot], -1))
        identity = out.new_tensor([1.0, 0.0, 0.0, 0.0])
        q = nn.functional.normalize(out[..., :4] + identity, dim=-1)
        return quat_to_matrix_torch(q) @ fitted_rotations(rest, posed, weights), out[..., 4:] + (c_posed - c_rest)


class SkeletonFreePoseTransfer(nn.Module):
    """SFPT: the skinning and pose predictors.

    Args:
        hidden: EdgeConv width.
        handles: H (the paper's 40).
    """

    def __init__(self, hidden: int = 64, handles: int = 40):
        super().__init__()
        self.skinning = SkinningPredictor(hidden, handles)
        self.pose = PosePredictor(hidden, handles)
