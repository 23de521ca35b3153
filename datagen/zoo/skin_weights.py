"""Smooth skin weights from distances to bone segments.

A vertex of bone b's capsule is weighted over b's neighbourhood: b, its parent and its children
(apparel bones only for apparel capsules, so the body never follows a skirt). The weight of bone
k is ``(d_k + r_b / 2)^-power`` with d_k the distance to k's segment (head to tail) and r_b the
capsule's mean radius (so a segment piercing the capsule's surface does not grab a sharp spot), then the 8
largest are kept and the row normalised. Weights vary continuously over each capsule, blend
about half and half at a joint, and every vertex is weighted.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import Skeleton
from mimicbench.geometry.segments import point_segment_distance
from mimicbench.schemas.weights import MAX_INFLUENCES, SparseWeights


def neighbourhood(skel: Skeleton, k: int, children: list[list[int]]) -> list[int]:
    """Bones that may influence bone k's capsule: k, its parent, its children (apparel-consistent)."""
    out = [k]
    p = int(skel.parents[k])
    if p >= 0:
        out.append(p)
    for c in children[k]:
        if skel.apparel[c] == skel.apparel[k] or skel.apparel[k]:
            out.append(c)
    return out


def skin_weights(skel: Skeleton, vertices: np.ndarray, owner: np.ndarray, power: float = 4.0,
                 max_influences: int = MAX_INFLUENCES) -> SparseWeights:
    """Weights of ``vertices`` (N, 3) whose capsule bone is ``owner`` (N,) int.

    Returns:
        :class:`SparseWeights` with (N, 8) indices and values, rows summing to 1.
    """
    n = len(vertices)
    idx = np.zeros((n, max_influences), np.int32)
    val = np.zeros((n, max_influences), np.float32)
    children = skel.children()
    for k in range(skel.num_joints):
        rows = np.nonzero(owner == k)[0]
        if not len(rows):
            continue
        cand = np.array(neighbourhood(skel, k, children))
        d = point_segment_distance(vertices[rows], skel.heads[cand], skel.tails[cand])
        soft = 0.25 * (skel.radius_head[k] + skel.radius_tail[k]) * float(np.mean(skel.aspect[k]))
        w = (d + soft) ** (-power)
        w[:, 0] *= 1.5  # the capsule's own bone leads where distances tie
        order = np.argsort(-w, axis=1, kind="stable")[:, :max_influences]
        top = np.take_along_axis(w, order, axis=1)
        top /= top.sum(axis=1, keepdims=True)
        j = top.shape[1]
        idx[rows, :j] = cand[order]
        val[rows, :j] = top
    # renormalise in float32 so rows sum to 1 as stored
    val /= val.sum(axis=1, keepdims=True, dtype=np.float64).astype(np.float32)
    return SparseWeights(idx, val, skel.num_joints)
