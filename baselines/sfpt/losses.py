"""SFPT's training terms (the published code's eight, read to learn), on one mesh at a time in unit-height
rest frames. Weights are the published ones (:mod:`mimicbench.baselines.sfpt.config`).

- :func:`l1`: mean absolute coordinate error (the published criterion, ``torch.nn.L1Loss``).
- :func:`arap_edges`: mean over mesh edges of |l_pred^2 - l_rest^2| (squared lengths), the published
  ``arap_loss`` (weight 100 each, on three deformed meshes).
- :func:`quaternion_loss`: mean absolute difference of quaternions, the sign that is closer.
- :func:`transformation_loss`: supervision of predicted handle transforms (H, 7) by the target's own Kabsch
  fit (rest onto its ground-truth pose): 0.5 quaternion + L1 translation.
- :func:`skinning_contrast`: the published skinning-weight term: vertices the prediction puts in one handle
  (its argmax) are paired at random; a pair whose two vertices the rig binds (weight > 0.9) to one bone has
  the KL divergence of their weight rows pulled down, a pair bound to two bones pushed up.
- :func:`kl`: ``torch.nn.functional.kl_div(log(a + eps), b + eps)`` (mean over elements), for the
  augmentation term (the weights of an augmented mesh against the plain one's).
- :func:`chamfer`: the squared-distance Chamfer distance between two point sets (farthest-point samples
  of the rest mesh against the handle centres, so the handles spread over the mesh).
"""
from __future__ import annotations

import numpy as np
import torch


def l1(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Mean of |pred - truth| over every coordinate of (..., N, 3)."""
    return (pred - truth).abs().mean()


def arap_edges(rest: torch.Tensor, pred: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean over edges (E, 2) of |squared length in ``pred`` - squared length in ``rest``|, (N, 3) each."""
    d_rest = (rest[edges[:, 0]] - rest[edges[:, 1]]).pow(2).sum(-1)
    d_pred = (pred[edges[:, 0]] - pred[edges[:, 1]]).pow(2).sum(-1)
    return (d_pred - d_rest).abs().mean()


def quaternion_loss(q1: torch.Tensor, q2: torch.Tensor) -> torch.Tensor:
    """Mean over quaternions (..., 4) of min(mean |q1 - q2|, mean |q1 + q2|)."""
    return torch.minimum((q1 - q2).abs().mean(-1), (q1 + q2).abs().mean(-1)).mean()


def transformation_loss(pred: torch.Tensor, fit: torch.Tensor) -> torch.Tensor:
    """0.5 :func:`quaternion_loss` + :func:`l1` of the translations, predicted (H, 7) against a fit (H, 7)."""
    return 0.5 * quaternion_loss(pred[..., 3:], fit[..., 3:]) + l1(pred[..., :3], fit[..., :3])


def kl(a: torch.Tensor, b: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    """``kl_div(log(a + eps), b + eps)``: mean over elements of (b + eps) (log(b + eps) - log(a + eps))."""
    return ((b + eps) * ((b + eps).log() - (a + eps).log())).mean()


def skinning_contrast(weights: torch.Tensor, rig_weights: np.ndarray, rng: np.random.Generator) -> torch.Tensor:
    """The contrastive skinning term of predicted weights (N, H) against the rig's dense weights (N, K).

    Returns 0 (a tensor) when no pair qualifies."""
    seg = weights.detach().argmax(-1).cpu().numpy()
    rig = np.asarray(rig_weights)
    bone, rigid = rig.argmax(-1), rig.max(-1) > 0.9
    p1, p2 = [], []
    for h in np.unique(seg):
        rows = rng.permutation(np.flatnonzero(seg == h))
        half = len(rows) // 2
        p1.append(rows[:half])
        p2.append(rows[half:2 * half])
    p1, p2 = np.concatenate(p1), np.concatenate(p2)
    keep = rigid[p1] & rigid[p2]
    p1, p2 = p1[keep], p2[keep]
    same = bone[p1] == bone[p2]
    w = weights + 1e-6
    out = weights.sum() * 0.0
    if same.any():
        out = out + kl(w[p1[same]], w[p2[same]], 0.0)
    if (~same).any():
        out = out - kl(w[p1[~same]], w[p2[~same]], 0.0)
    return out


def chamfer(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean over ``a`` (P, 3) of the squared distance to the nearest of ``b`` (Q, 3), plus the same of ``b``."""
    d = (a[:, None] - b[None]).pow(2).sum(-1)
    return d.min(1).values.mean() + d.min(0).values.mean()
