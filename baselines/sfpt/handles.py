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


def matrix_to_quat_torch(m: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions (w, x, y, z), w >= 0, of rotation matrices (..., 3, 3) (Shepperd's method:
    the branch of the largest of w^2, x^2, y^2, z^2, so no division by a small number)."""
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    sq = torch.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    cands = torch.stack([
        torch.stack([sq[..., 0], m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
        torch.stack([m[..., 2, 1] - m[..., 1, 2], sq[..., 1], m[..., 1, 0] + m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0]], -1),
        torch.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] + m[..., 0, 1], sq[..., 2], m[..., 2, 1] + m[..., 1, 2]], -1),
        torch.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] + m[..., 1, 2], sq[..., 3]], -1),
    ], -2)  # (..., 4 branches, 4)
    best = sq.argmax(-1)
    q = torch.gather(cands, -2, best[..., None, None].expand(*best.shape, 1, 4))[..., 0, :]
    q = q / (2.0 * torch.sqrt(torch.gather(sq, -1, best[..., None]).clamp_min(1e-12)))
    q = torch.nn.functional.normalize(q, dim=-1)
    return torch.where(q[..., :1] < 0, -q, q)


def kabsch_transforms(rest: torch.Tensor, posed: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """(H, 7) each handle's weighted Kabsch fit of a mesh, no gradient: translation (the handle centre's
    displacement, posed minus rest) and quaternion (w, x, y, z) of :func:`fitted_rotations`;
    rest, posed (N, 3), weights (N, H)."""
    with torch.no_grad():
        r = fitted_rotations(rest[None], posed[None], weights[None])[0]
        t = handle_centres(posed, weights) - handle_centres(rest, weights)
        return torch.cat([t, matrix_to_quat_torch(r)], -1)


def transform_matrices(transforms: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rotations (..., H, 3, 3) and translations (..., H, 3) of (..., H, 7) transforms (translation,
    quaternion wxyz; the quaternion is normalised)."""
    from mimicbench.geometry.skinning_torch import quat_to_matrix_torch

    q = torch.nn.functional.normalize(transforms[..., 3:], dim=-1, eps=1e-12)
    return quat_to_matrix_torch(q), transforms[..., :3]


def with_translations(transforms: torch.Tensor, translations: torch.Tensor) -> torch.Tensor:
    """(..., H, 7) ``transforms`` (translation, then quaternion) with their translations replaced by
    ``translations`` (..., H, 3)."""
    return torch.cat([translations, transforms[..., 3:]], -1)
