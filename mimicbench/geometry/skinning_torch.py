"""Torch twins of the skinning and quaternion functions the benchmark runs on tensors.

Shapes and conventions match :mod:`mimicbench.geometry.skinning` and :mod:`mimicbench.geometry.quaternion`;
tensors may live on any device.
"""
from __future__ import annotations

import torch


def quat_to_matrix_torch(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) in (w, x, y, z) order."""
    if q.shape[-1] != 4:
        raise ValueError(f"q: expected shape (..., 4), got {tuple(q.shape)}")
    q = q / q.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    w, x, y, z = q.unbind(-1)
    m = torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def linear_blend_skinning_torch(
    rest_vertices: torch.Tensor,
    rest_keypoints: torch.Tensor,
    weights: torch.Tensor,
    transforms: torch.Tensor,
    weight_indices: torch.Tensor | None = None,
    scale: torch.Tensor | None = None,
) -> torch.Tensor:
    """Pose a mesh by linear blend skinning (MimiCAT Eq. 1).

    Args:
        rest_vertices: FloatTensor (N, 3).
        rest_keypoints: FloatTensor (K, 3).
        weights: dense FloatTensor (N, K), or sparse values (N, J) when ``weight_indices`` is given.
        transforms: FloatTensor (..., K, 7): quaternion (w, x, y, z) then translation.
        weight_indices: optional LongTensor (N, J) of keypoint indices for sparse weights.
        scale: optional FloatTensor (..., K, 6) symmetric stretch per keypoint
            (``s_xx, s_yy, s_zz, s_xy, s_xz, s_yz``); the map becomes ``R U (v - c) + t``.

    Returns:
        FloatTensor (..., N, 3) posed vertices, dtype of ``transforms``.
    """
    if transforms.shape[-1] != 7:
        raise ValueError(f"transforms: expected shape (..., K, 7), got {tuple(transforms.shape)}")
    r = quat_to_matrix_torch(transforms[..., :4])
    if scale is not None:
        if scale.shape[-1] != 6 or scale.shape[:-1] != transforms.shape[:-1]:
            raise ValueError(f"scale: expected shape {tuple(transforms.shape[:-1]) + (6,)}, got {tuple(scale.shape)}")
        xx, yy, zz, xy, xz, yz = scale.to(transforms.dtype).unbind(-1)
        u = torch.stack([torch.stack([xx, xy, xz], -1), torch.stack([xy, yy, yz], -1),
                         torch.stack([xz, yz, zz], -1)], -2)
        r = r @ u
    t = transforms[..., 4:]
    rest_k = rest_keypoints.to(transforms.dtype)
    offset = t - torch.einsum("...kij,kj->...ki", r, rest_k)
    a = torch.cat([r, offset[..., None]], dim=-1)  # (..., K, 3, 4)
    verts = rest_vertices.to(transforms.dtype)
    homo = torch.cat([verts, torch.ones_like(verts[:, :1])], dim=1)
    w = weights.to(transforms.dtype)
    if weight_indices is not None:
        blended = torch.einsum("nj,...njab->...nab", w, a[..., weight_indices.long(), :, :])
    else:
        blended = torch.einsum("nk,...kab->...nab", w, a)
    return torch.einsum("...nab,nb->...na", blended, homo)
