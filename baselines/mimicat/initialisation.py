"""Correspondence-aware initialisation of the target pose (MimiCAT Eq. 3-4), in torch.

Given the source's pose (global rotations q_i and posed keypoints t_i), the rest skeletons and a
soft correspondence M (Ks, Kt), each target keypoint j gets

- a rotation: the M-weighted average of the source rotations (Eq. 4), the eigenvector of the
  largest eigenvalue of ``sum_i M_ij q_i q_i^T`` (as :func:`mimicbench.rotation_average.
  weighted_quaternion_average`), or, for the ``naive_avg`` ablation (A1), the normalised plain
  weighted sum of the quaternions (each first put on the w >= 0 hemisphere);
- a position: forward kinematics of the target's own bones under those rotations, the whole
  skeleton shifted so that every keypoint best follows its Eq. 3 displacement
  ``sum_i M_ij (t_i - cbar_i) / sum_i M_ij`` scaled by the size ratio (least squares: the mean of
  what the keypoints are missing).

This is exactly what ``text_soft`` does with the dataset's M_sink (the tests check it), written
with differentiable tensor operations so the pose-transfer transformer H can be trained through
it (the cycle's return leg starts from H's own output).
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.skinning_torch import quat_to_matrix_torch

AVERAGES = ("eq4", "naive")


def _identity_like(q: torch.Tensor) -> torch.Tensor:
    out = torch.zeros_like(q)
    out[..., 0] = 1
    return out


def quaternion_average(q: torch.Tensor, m: torch.Tensor, kind: str = "eq4") -> torch.Tensor:
    """M-weighted average rotations (Kt, 4), w >= 0; an all-zero column gives the identity.

    Args:
        q: (Ks, 4) unit quaternions (w, x, y, z).
        m: (Ks, Kt) non-negative weights.
        kind: ``eq4`` (largest eigenvector, Eq. 4) or ``naive`` (plain weighted sum, A1).
    """
    if kind not in AVERAGES:
        raise ValueError(f"kind: expected one of {AVERAGES}, got {kind!r}")
    q = q.to(torch.float64)
    m = m.to(torch.float64)
    if kind == "eq4":
        a = torch.einsum("ij,ia,ib->jab", m, q, q)  # (Kt, 4, 4)
        # a vanishing perturbation keeps eigh's backward finite where eigenvalues coincide
        a = a + torch.diag(torch.tensor([0.0, 1e-12, 2e-12, 3e-12], dtype=a.dtype, device=a.device))
        _, vecs = torch.linalg.eigh(a)
        avg = vecs[..., :, -1]
    else:
        hemi = torch.where(q[:, :1] < 0, -q, q)
        avg = m.T @ hemi
        avg = avg / avg.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    avg = torch.where(avg[..., :1] < 0, -avg, avg)
    empty = (m.sum(dim=0) <= 0)[:, None]
    return torch.where(empty, _identity_like(avg), avg)


def fk_matrices(parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tree bookkeeping for vectorised forward kinematics.

    Returns:
        path (K, K) float: ``path[k, a] = 1`` when a is k or an ancestor of k and not a root;
        root_of (K,) int: the root above each keypoint.
    """
    parents = np.asarray(parents)
    k = len(parents)
    path = np.zeros((k, k))
    root_of = np.zeros(k, dtype=np.int64)
    for j, p in enumerate(parents):
        if p < 0:
            root_of[j] = j
        else:
            path[j] = path[p]
            path[j, j] = 1
            root_of[j] = root_of[p]
    return path, root_of


def forward_kinematics_global(q: torch.Tensor, rest: torch.Tensor, parents: np.ndarray) -> torch.Tensor:
    """Posed keypoints (K, 3) of a skeleton whose bones take global rotations q (K, 4), roots
    kept at rest: ``t_k = t_p + R(q_p) (cbar_k - cbar_p)``."""
    parents = np.asarray(parents)
    path, root_of = fk_matrices(parents)
    par = torch.as_tensor(np.where(parents < 0, np.arange(len(parents)), parents), device=q.device)
    bone = rest - rest[par]  # zero for roots
    offsets = torch.einsum("kab,kb->ka", quat_to_matrix_torch(q[par]), bone)
    return rest[torch.as_tensor(root_of, device=q.device)] + torch.as_tensor(path, dtype=q.dtype, device=q.device) @ offsets


def initial_pose(q_src: torch.Tensor, t_src: torch.Tensor, rest_src: torch.Tensor, rest_tgt: torch.Tensor,
                 parents_tgt: np.ndarray, m: torch.Tensor, ratio: float, average: str = "eq4"):
    """The initial target transforms of Eq. 3-4.

    Args:
        q_src: (Ks, 4) source global rotations; t_src: (Ks, 3) posed source keypoints, metres.
        rest_src: (Ks, 3), rest_tgt: (Kt, 3) rest keypoints.
        parents_tgt: (Kt,) target parents.
        m: (Ks, Kt) soft correspondence.
        ratio: target size / source size.
        average: ``eq4`` or ``naive`` (see :func:`quaternion_average`).

    Returns:
        q_bar (Kt, 4) and t_bar (Kt, 3), float64.
    """
    q_src, t_src, rest_src, rest_tgt, m = (x.to(torch.float64) for x in (q_src, t_src, rest_src, rest_tgt, m))
    q = quaternion_average(q_src, m, average)
    mass = m.sum(dim=0)
    has = mass > 0
    fk = forward_kinematics_global(q, rest_tgt, parents_tgt)
    if bool(has.any()):
        wanted = (m[:, has] / mass[has]).T @ (t_src - rest_src) * ratio  # Eq. 3, (Kt', 3)
        disp = (wanted - (fk - rest_tgt)[has]).mean(dim=0)
    else:
        disp = torch.zeros(3, dtype=q.dtype, device=q.device)
    return q, fk + disp
