"""Body deformation f_s (MMDMC Sec. 4.2): skinning weights from the vertex-joint relation with
geodesic attention, then linear blend skinning.

For vertex i and body joint k the pair feature is an MLP of (v_i - c_k, |v_i - c_k|, G_ik, B_ik),
B_ik the distance from v_i to bone k's segments (:mod:`mimicbench.baselines.mmdmc.bone_distance`); the
geodesic attention ``M = softmax_k(f_m(G))`` pools the pair features into a vertex context; a
PointNet over (v_i, context_i) adds local and global shape features; the head scores every pair
from (pair feature, context, PointNet features, G_ik), the head's score over tau is added to a
prior -B_ik / tau (tau learnt) and ``W = softmax_k(scores)``. With ``prior="piece"`` (the shipped
f_s's) the vertices of a mesh piece that wraps one bone are scored by the piece
prior of :mod:`mimicbench.baselines.mmdmc.piece_prior` instead, wherever the caller hands it in (the pipeline
at inference); the learnt scores serve every other vertex, and training (which hands in no piece
prior) shapes them.

Positions and G are in the character's unit-height frame. The posed mesh is LBS of the rest mesh
(metres) with W over the body joints and the body joints' transforms (K, 7); a request's
transforms already carry the character's own bone lengths (t_k is joint k's posed position), which
is what MMDMC's "translations scaled by the bone lengths" gives when the motion comes from another
skeleton.

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.baselines.mmdmc.nn import mlp
from mimicbench.geometry.skinning_torch import linear_blend_skinning_torch

PRIOR_TAU = 0.01
"""Initial temperature of the bone-distance prior on the skinning scores (fraction of the height)."""

PRIORS = ("bone", "piece")
"""Priors on the skinning scores: ``bone`` (-B / tau everywhere; a config without ``body_prior``) or
``piece`` (:mod:`mimicbench.baselines.mmdmc.piece_prior` where a mesh piece wraps a bone, -B / tau elsewhere)."""


class BodySkinning(nn.Module):
    """f_s: rest positions (B, N, 3), joints (B, K, 3), G (B, N, K), bone distances (B, N, K) -> weights W (B, N, K).

    Args:
        hidden: width of the pair features.
        chunk: vertices scored at once (bounds memory to chunk * K * hidden on big meshes).
        prior: one of :data:`PRIORS`; with ``piece`` :meth:`forward` scores the vertices given a
            piece prior by that prior alone.
    """

    def __init__(self, hidden: int = 32, chunk: int = 2048, prior: str = "bone"):
        super().__init__()
        if prior not in PRIORS:
            raise ValueError(f"body prior: expected one of {PRIORS}, got {prior!r}")
        self.prior = prior
        self.chunk = chunk
        self.pair = mlp([6, hidden, hidden])
        self.f_m = mlp([1, 16, 1], last_act=False)
        self.local = mlp([3 + hidden, 2 * hidden, 2 * hidden])
        self.globl = mlp([2 * hidden, 2 * hidden])
        # the head scores a pair from [pair feature, per-vertex features, G_ik]; its first layer is
        # split so the per-vertex part is computed once per vertex, not once per (vertex, joint)
        self.head_pair = nn.Linear(hidden + 1, 2 * hidden)
        self.head_vertex = nn.Linear(hidden + 4 * hidden, 2 * hidden, bias=False)
        self.head_out = nn.Sequential(nn.ReLU(), nn.Linear(2 * hidden, 1))
        # the head's last layer starts at zero: an untrained f_s is the bone-distance prior alone
        # (on the training zoo 0.2 cm body error at 1.70 m), and training corrects it from there
        nn.init.zeros_(self.head_out[-1].weight)
        nn.init.zeros_(self.head_out[-1].bias)
        # bone-distance prior on the scores: -B / tau (tau learnt, unit-height frame); an untrained
        # head then skins each vertex to its nearest bones instead of to all alike
        self.log_tau = nn.Parameter(torch.tensor(float(np.log(PRIOR_TAU))))

    def _pairs(self, points, joints, geo, bone):
        rel = points[:, :, None, :] - joints[:, None, :, :]  # (B, n, K, 3)
        x = torch.cat([rel, rel.norm(dim=-1, keepdim=True), geo[..., None], bone[..., None]], dim=-1)
        return self.pair(x)  # (B, n, K, h)

    def attention(self, geo: torch.Tensor, joint_mask: torch.Tensor | None = None) -> torch.Tensor:
        """M = softmax_k(f_m(G)): (B, N, K) from G (B, N, K); masked joints get 0."""
        logits = self.f_m(geo[..., None])[..., 0]
        if joint_mask is not None:
            logits = logits.masked_fill(~joint_mask[:, None, :], float("-inf"))
        return torch.softmax(logits, dim=-1)

    def forward(self, points: torch.Tensor, joints: torch.Tensor, geo: torch.Tensor, bone: torch.Tensor,
                joint_mask: torch.Tensor | None = None, piece: torch.Tensor | None = None) -> torch.Tensor:
        """Skinning weights (B, N, K), rows summing to 1 over the unmasked joints.

        Args:
            points: (B, N, 3) rest positions, unit-height frame.
            joints: (B, K, 3) rest body joints, same frame.
            geo: (B, N, K) geodesic distances, divided by the rest height.
            bone: (B, N, K) distances to the body bones' segments, divided by the rest height.
            joint_mask: optional (B, K) bool, False for padding joints.
            piece: optional (B, N, K) piece prior scores, NaN rows where no piece wraps a bone
                (:func:`mimicbench.baselines.mmdmc.piece_prior.piece_prior`); only the ``piece`` prior reads it.
        """
        b, n, _ = points.shape
        if piece is not None and piece.shape != bone.shape:
            raise ValueError(f"piece prior scores: expected the bone distances' shape {tuple(bone.shape)}, "
                             f"got {tuple(piece.shape)}")
        if joints.ndim != 3 or geo.shape != (b, n, joints.shape[1]) or bone.shape != geo.shape:
            raise ValueError(f"joints (B, K, 3), geo and bone (B, N, K) expected; got {tuple(joints.shape)}, "
                             f"{tuple(geo.shape)} and {tuple(bone.shape)} for points {tuple(points.shape)}")
        spans = [slice(s, min(s + self.chunk, n)) for s in range(0, n, self.chunk)]
        context, kept = [], []
        for s in spans:
            e = self._pairs(points[:, s], joints, geo[:, s], bone[:, s])
            m = self.attention(geo[:, s], joint_mask)
            context.append((m[..., None] * e).sum(dim=2))
            if len(spans) == 1:  # one chunk (training subsamples): reuse its pair features below
                kept.append(e)
        context = torch.cat(context, dim=1)  # (B, N, h)
        local = self.local(torch.cat([points, context], dim=-1))
        g = self.globl(local).max(dim=1).values  # (B, 2h)
        scores = []
        for i, s in enumerate(spans):
            e = kept[i] if kept else self._pairs(points[:, s], joints, geo[:, s], bone[:, s])
            per_vertex = torch.cat([context[:, s], local[:, s], g[:, None].expand(-1, e.shape[1], -1)], dim=-1)
            h = self.head_pair(torch.cat([e, geo[:, s, :, None]], dim=-1)) + self.head_vertex(per_vertex)[:, :, None]
            # the head corrects the bone distance (unit-height frame) before the prior's temperature,
            # so a correction of a few centimetres already moves the softmax as far as the prior does
            learnt = -(bone[:, s] + self.head_out(h)[..., 0]) / self.log_tau.exp()
            if self.prior == "piece" and piece is not None:
                learnt = torch.where(torch.isnan(piece[:, s]), learnt, piece[:, s])
            scores.append(learnt)
        scores = torch.cat(scores, dim=1)
        if joint_mask is not None:
            scores = scores.masked_fill(~joint_mask[:, None, :], float("-inf"))
        return torch.softmax(scores, dim=-1)


def skin(rest_vertices: torch.Tensor, rest_joints: torch.Tensor, weights: torch.Tensor,
         transforms: torch.Tensor) -> torch.Tensor:
    """LBS (..., N, 3) of rest vertices (N, 3) with dense weights (N, K) and transforms (..., K, 7), metres."""
    return linear_blend_skinning_torch(rest_vertices, rest_joints, weights, transforms)
