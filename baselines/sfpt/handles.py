"""Deformation by linear blend skinning over learned handles (SFPT Sec. 3.1).

A mesh's handle weights W (N, H) (rows summing to 1) define H handle centres, the weight-averaged
rest vertices ``c_k = sum_i W_ik v_i / sum_i W_ik``. A handle transform is a rotation R_k and a
translation t_k about that centre; a vertex moves to ``v_i' = sum_k W_ik (R_k (v_i - c_k) + c_k + t_k)``.
The same H transforms pose any mesh whose weights index the same handles: that is how SFPT transfers
a pose without a skeleton.
"""
from __future__ import annotations

import torch


def handle_centres(vertices: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """(..., H, C) weight-averaged rows of vertices (..., N, C) under handle weights (..., N, H)."""
    mass = weights.sum(-2).clamp_min(1e-8)  # (..., H)
    return (weights.transpose(-1, -2) @ vertices) / mass[..., None]


def fitted_rotations(rest: torch.Tensor, posed: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """(B, H, 3, 3) rotations best mapping each handle's rest vertices onto its posed ones, weighted
    by the handle's weights (weighted Kabsch), with no gradient: rest, posed (B, N, 3), weights (B, N, H)."""
    with torch.no_grad():
        c, p = handle_centres(rest, weights), handle_centres(posed, weights)
        mass = weights.sum(-2)  # (B, H)
        cov = torch.einsum("bnh,bni,bnj->bhij", weights, rest, posed) - mass[..., None, None] * (
            c[..., :, None] * p[..., None, :])
        u, _, vh = torch.linalg.svd(cov.double())
        v = vh.transpose(-1, -2)
        d = torch.sign(torch.linalg.det(v @ u.transpose(-1, -2)))
        d = torch.where(d == 0, torch.ones_like(d), d)
        fix = torch.diag_embed(torch.stack([torch.ones_like(d), torch.ones_like(d), d], -1))
        return (v @ fix @ u.transpose(-1, -2)).to(rest.dtype)


def deform(vertices: torch.Tensor, weights: torch.Tensor, rotations: torch.Tensor,
           translations: torch.Tensor) -> torch.Tensor:
    """Vertices (..., N, 3) posed by handle weights (..., N, H), rotations (..., H, 3, 3) and
    translations (..., H, 3) about the handle centres -> (..., N, 3)."""
    c = handle_centres(vertices, weights)  # (..., H, 3)
    local = vertices[..., None, :, :] - c[..., :, None, :]  # (..., H, N, 3)
    moved = local @ rotations.transpose(-1, -2) + (c + translations)[..., :, None, :]  # (..., H, N, 3)
    return (weights.transpose(-1, -2)[..., None] * moved).sum(-3)
