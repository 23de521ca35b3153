"""Body deformation f_s (MMDMC Sec. 4.2): skinning weights from the vertex-joint relation with
geodesic attention, then linear blend skinning.

For vertex i and body joint k the pair feature is an MLP of (v_i - c_k, |v_i - c_k|, G_ik); the
geodesic attention ``M = softmax_k(f_m(G))`` pools the pair features into a vertex context; a
PointNet over (v_i, context_i) adds local and global shape features; the head scores every pair
from (pair feature, context, PointNet features), a geodesic prior -G_ik / tau (tau learnt) is added,
and ``W = softmax_k(scores)``.

Positions and G are in the character's unit-height frame. The posed mesh is LBS of the rest mesh
(metres) with W over the body joints and the body joints' transforms (K, 7); a request's
transforms already carry the character's own bone lengths (t_k is joint k's posed position), which
is what MMDMC's "translations scaled by the bone lengths" gives when the motion comes from another
skeleton.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from baselines.mmdmc.segmentation import mlp
from mimicbench.skinning_torch import linear_blend_skinning_torch

PRIOR_TAU = 0.03
"""Initial temperature of the geodesic prior on the skinning scores (fraction of the height)."""


class BodySkinning(nn.Module):
    """f_s: rest positions (B, N, 3), joints (B, K, 3), G (B, N, K) -> weights W (B, N, K).

    Args:
        hidden: width of the pair features.
        chunk: vertices scored at once (bounds memory to chunk * K * hidden on big meshes).
    """

    def __init__(self, hidden: int = 32, chunk: int = 2048):
        super().__init__()
        self.chunk = chunk
        self.pair = mlp([5, hidden, hidden])
        self.f_m = mlp([1, 16, 1], last_act=False)
        self.local = mlp([3 + hidden, 2 * hidden, 2 * hidden])
        self.globl = mlp([2 * hidden, 2 * hidden])
        self.head = mlp([hidden + hidden + 4 * hidden + 1, 2 * hidden, 1], last_act=False)
        # geodesic prior on the scores: -G / tau (tau learnt, unit-height frame); an untrained head
        # then skins each vertex to the joints nearest along the surface instead of to all alike
        self.log_tau = nn.Parameter(torch.tensor(float(np.log(PRIOR_TAU))))

    def _pairs(self, points, joints, geo):
        rel = points[:, :, None, :] - joints[:, None, :, :]  # (B, n, K, 3)
        x = torch.cat([rel, rel.norm(dim=-1, keepdim=True), geo[..., None]], dim=-1)
        return self.pair(x)  # (B, n, K, h)

    def attention(self, geo: torch.Tensor, joint_mask: torch.Tensor | None = None) -> torch.Tensor:
        """M = softmax_k(f_m(G)): (B, N, K) from G (B, N, K); masked joints get 0."""
        logits = self.f_m(geo[..., None])[..., 0]
        if joint_mask is not None:
            logits = logits.masked_fill(~joint_mask[:, None, :], float("-inf"))
        return torch.softmax(logits, dim=-1)

    def forward(self, points: torch.Tensor, joints: torch.Tensor, geo: torch.Tensor,
                joint_mask: torch.Tensor | None = None) -> torch.Tensor:
        """Skinning weights (B, N, K), rows summing to 1 over the unmasked joints.

        Args:
            points: (B, N, 3) rest positions, unit-height frame.
            joints: (B, K, 3) rest body joints, same frame.
            geo: (B, N, K) geodesic distances, divided by the rest height.
            joint_mask: optional (B, K) bool, False for padding joints.
        """
        b, n, _ = points.shape
        if joints.ndim != 3 or geo.shape != (b, n, joints.shape[1]):
            raise ValueError(f"joints (B, K, 3) and geo (B, N, K) expected; got {tuple(joints.shape)} "
                             f"and {tuple(geo.shape)} for points {tuple(points.shape)}")
        spans = [slice(s, min(s + self.chunk, n)) for s in range(0, n, self.chunk)]
        context = []
        for s in spans:
            e = self._pairs(points[:, s], joints, geo[:, s])
            m = self.attention(geo[:, s], joint_mask)
            context.append((m[..., None] * e).sum(dim=2))
        context = torch.cat(context, dim=1)  # (B, N, h)
        local = self.local(torch.cat([points, context], dim=-1))
        g = self.globl(local).max(dim=1).values  # (B, 2h)
        scores = []
        for s in spans:
            e = self._pairs(points[:, s], joints, geo[:, s])
            k = e.shape[2]
            per_vertex = torch.cat([context[:, s], local[:, s], g[:, None].expand(-1, e.shape[1], -1)], dim=-1)
            x = torch.cat([e, per_vertex[:, :, None].expand(-1, -1, k, -1), geo[:, s, :, None]], dim=-1)
            scores.append(self.head(x)[..., 0] - geo[:, s] / self.log_tau.exp())
        scores = torch.cat(scores, dim=1)
        if joint_mask is not None:
            scores = scores.masked_fill(~joint_mask[:, None, :], float("-inf"))
        return torch.softmax(scores, dim=-1)


def skin(rest_vertices: torch.Tensor, rest_joints: torch.Tensor, weights: torch.Tensor,
         transforms: torch.Tensor) -> torch.Tensor:
    """LBS (..., N, 3) of rest vertices (N, 3) with dense weights (N, K) and transforms (..., K, 7), metres."""
    return linear_blend_skinning_torch(rest_vertices, rest_joints, weights, transforms)
