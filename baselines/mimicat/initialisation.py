"""Correspondence-aware initialisation of the target pose (MimiCAT Eq. 3-4), in torch.

Given the source's pose (global rotations q_i and posed keypoints t_i), the rest skeletons and a
soft correspondence M (Ks, Kt), each target keypoint j gets a rotation, the M-weighted average of
the source rotations (Eq. 4), the eigenvector of the largest eigenvalue of
``sum_i M_ij q_i q_i^T`` (as :func:`mimicbench.geometry.rotation_average.weighted_quaternion_average`), or,
for the ``naive_avg`` ablation (A1), the normalised plain weighted sum of the quaternions (each
first put on the w >= 0 hemisphere). Positions come from one of two constructions
(config ``transfer.init``):

- ``structured`` (:func:`structured_pose`, the default of the presets): a root moves like the
  source's root (displacement from rest scaled by the size ratio); every other bone carries over
  its matches' local translations (relative to the parent, in the parent's rest-relative frame,
  as the h2h ground truth does, :func:`mimicbench.benchmark.protocols.h2h.local_translations`) scaled by the
  size ratio, each match counted when the bone's parent is matched to that source bone's parent
  (the soft form of ``nearest_joint``'s rule); a bone whose column of M is empty takes its
  parent's rotation; positions by forward kinematics. With a one-hot M this is ``nearest_joint``'s
  construction from those matches.
- ``paper`` (:func:`initial_pose`, Eq. 3 as published): forward kinematics of the target's own
  bones under the rotations, the whole skeleton shifted so that every keypoint best follows its
  Eq. 3 displacement ``sum_i M_ij (t_i - cbar_i) / sum_i M_ij`` scaled by the size ratio (least
  squares: the mean of what the keypoints are missing); an empty column keeps the identity. This
  is exactly what ``text_soft`` does with the dataset's M_sink (the tests check it).

Both are written with differentiable tensor operations so the pose-transfer transformer H can be
trained through them (the cycle's return leg starts from H's own output).
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.geometry.skinning_torch import quat_to_matrix_torch

AVERAGES = ("eq4", "naive")
INITS = ("structured", "paper")


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


def _parent_index(parents: np.ndarray, device) -> torch.Tensor:
    """(K,) long: each keypoint's parent, a root itself."""
    parents = np.asarray(parents)
    return torch.as_tensor(np.where(parents < 0, np.arange(len(parents)), parents), device=device)


def forward_kinematics_global(q: torch.Tensor, rest: torch.Tensor, parents: np.ndarray,
                              moved: torch.Tensor | None = None) -> torch.Tensor:
    """Posed keypoints (K, 3) of a skeleton whose bones take global rotations q (K, 4):
    ``t_k = t_p + R(q_p) (cbar_k - cbar_p + moved_k)``, a root at ``cbar_k + moved_k``.

    Args:
        q: (K, 4) global rotations; rest: (K, 3) rest keypoints; parents: (K,).
        moved: (K, 3) local translations beyond the rest offsets, in the parent's rest-relative
            frame (a root's: its displacement), as :func:`local_translations_torch` gives; None
            for none (roots kept at rest).
    """
    path, root_of = fk_matrices(parents)
    par = _parent_index(parents, q.device)
    bone = rest - rest[par]  # zero for roots
    roots = torch.as_tensor(root_of, device=q.device)
    base = rest[roots]
    if moved is not None:
        bone = bone + moved
        base = base + moved[roots]
    offsets = torch.einsum("kab,kb->ka", quat_to_matrix_torch(q[par]), bone)
    return base + torch.as_tensor(path, dtype=q.dtype, device=q.device) @ offsets


def local_translations_torch(q: torch.Tensor, t: torch.Tensor, rest: torch.Tensor, parents: np.ndarray) -> torch.Tensor:
    """Each bone's translation (K, 3) relative to its parent beyond its rest offset, in the
    parent's rest-relative frame, ``R(q_p)^T (t_k - t_p) - (cbar_k - cbar_p)``; a root's
    displacement ``t_k - cbar_k`` (the torch twin of
    :func:`mimicbench.benchmark.protocols.h2h.local_translations`).

    Args:
        q: (K, 4) global rotations; t: (K, 3) posed keypoints; rest: (K, 3); parents: (K,).
    """
    par = _parent_index(parents, q.device)
    rel = torch.einsum("kba,kb->ka", quat_to_matrix_torch(q[par]), t - t[par]) - (rest - rest[par])
    is_root = torch.as_tensor(np.asarray(parents) < 0, device=q.device)[:, None]
    return torch.where(is_root, t - rest, rel)


def inherit_empty(q: torch.Tensor, empty: np.ndarray, parents: np.ndarray) -> torch.Tensor:
    """Rotations (K, 4) where a keypoint flagged ``empty`` (K,) takes the rotation of its nearest
    ancestor that is not (the identity when there is none)."""
    parents = np.asarray(parents)
    source = np.arange(len(parents))
    for j in range(len(parents)):
        a = j
        while a >= 0 and empty[a]:
            a = parents[a]
        source[j] = a
    ident = _identity_like(q)
    has = torch.as_tensor(source >= 0, device=q.device)[:, None]
    return torch.where(has, q[torch.as_tensor(np.maximum(source, 0), device=q.device)], ident)


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


def structured_pose(q_src: torch.Tensor, t_src: torch.Tensor, rest_src: torch.Tensor, parents_src: np.ndarray,
                    rest_tgt: torch.Tensor, parents_tgt: np.ndarray, m: torch.Tensor, ratio: float,
                    average: str = "eq4"):
    """The structured initial target transforms (``transfer.init=structured``, see the module docstring).

    With the column-normalised correspondence ``w_ij = M_ij / sum_i M_ij``:

    - rotation q_j: Eq. 4 over column j; an empty column takes the parent's rotation;
    - a root j moves by ``ratio * sum_r w_rj d_r / sum_r w_rj`` over the source roots r (d_r the
      root's displacement from rest), the source's first root when column j has no mass on a root;
    - another bone j carries ``ratio * sum_i w_ij w_{p(i) p(j)} l_i`` (l_i the source bone's local
      translation, :func:`local_translations_torch`; a source root's counts for no child bone);
    - positions by :func:`forward_kinematics_global` with those translations.

    Args:
        q_src: (Ks, 4) source global rotations; t_src: (Ks, 3) posed source keypoints, metres.
        rest_src: (Ks, 3), rest_tgt: (Kt, 3) rest keypoints; parents_src (Ks,), parents_tgt (Kt,).
        m: (Ks, Kt) non-negative soft correspondence.
        ratio: target size / source size.
        average: ``eq4`` or ``naive`` (see :func:`quaternion_average`).

    Returns:
        q (Kt, 4) and t (Kt, 3), float64.
    """
    q_src, t_src, rest_src, rest_tgt, m = (x.to(torch.float64) for x in (q_src, t_src, rest_src, rest_tgt, m))
    ps, pt = np.asarray(parents_src), np.asarray(parents_tgt)
    mass = m.sum(dim=0)
    empty = (mass <= 0).cpu().numpy()
    q = inherit_empty(quaternion_average(q_src, m, average), empty, pt)
    w = m / mass.clamp_min(1e-300)  # empty columns stay zero
    local = local_translations_torch(q_src, t_src, rest_src, ps) * ratio
    dev = m.device
    parent_w = w[_parent_index(ps, dev)][:, _parent_index(pt, dev)]
    parent_w = parent_w * torch.as_tensor((ps >= 0)[:, None] & (pt >= 0)[None, :], dtype=m.dtype, device=dev)
    moved = (w * parent_w).T @ local
    roots = np.flatnonzero(ps < 0)
    w_root = w[torch.as_tensor(roots, device=dev)]  # (R, Kt)
    first = torch.zeros_like(w_root)
    first[0] = 1
    root_mass = w_root.sum(dim=0, keepdim=True)
    w_root = torch.where(root_mass > 0, w_root / root_mass.clamp_min(1e-300), first)
    moved_root = w_root.T @ local[torch.as_tensor(roots, device=dev)]
    moved = torch.where(torch.as_tensor(pt < 0, device=dev)[:, None], moved_root, moved)
    return q, forward_kinematics_global(q, rest_tgt, pt, moved)


def initialise(kind: str, q_src: torch.Tensor, t_src: torch.Tensor, rest_src: torch.Tensor, parents_src: np.ndarray,
               rest_tgt: torch.Tensor, parents_tgt: np.ndarray, m: torch.Tensor, ratio: float,
               average: str = "eq4"):
    """The initial target transforms q (Kt, 4), t (Kt, 3) of construction ``kind`` (``structured``
    or ``paper``); arguments as :func:`structured_pose`."""
    if kind == "structured":
        return structured_pose(q_src, t_src, rest_src, parents_src, rest_tgt, parents_tgt, m, ratio, average)
    if kind == "paper":
        return initial_pose(q_src, t_src, rest_src, rest_tgt, parents_tgt, m, ratio, average)
    raise ValueError(f"transfer.init: expected one of {INITS}, got {kind!r}")
