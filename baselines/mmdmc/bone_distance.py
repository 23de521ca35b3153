"""Vertex-bone distances: how far each vertex is from each body bone's segment (our addition to
MMDMC's vertex-joint relation, Sec. 4.2; see :mod:`baselines.mmdmc.body`).

A joint position alone does not say which way its bone runs: a vertex halfway down the upper arm
is as near the elbow joint as the shoulder joint, yet belongs to the upper arm. Bone k's segments
run from joint k to each of its body children (a leaf bone is its joint's point); the distance of
a vertex to bone k is the smallest over those segments. Distances use the rig's parents, which a
request always carries, never its skin weights.
"""
from __future__ import annotations

import numpy as np

from datagen.zoo.skin_weights import point_segment_distance
from mimicbench.validation import check_shape


def bone_distances(vertices: np.ndarray, keypoints: np.ndarray, parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(N, Kb) float32 distance, metres, from every vertex (N, 3) to the segments of every body bone.

    Args:
        keypoints: (K, 3) rest joints; parents: (K,) int, -1 for a root; body: (K,) bool body bones
            (their order gives the columns).
    """
    v = np.asarray(check_shape(vertices, (None, 3), "vertices"), np.float64)
    kp = np.asarray(check_shape(keypoints, (None, 3), "keypoints"), np.float64)
    parents = np.asarray(parents, np.int64)
    body = np.asarray(body, bool)
    if parents.shape != (len(kp),) or body.shape != (len(kp),):
        raise ValueError(f"parents {parents.shape} and body {body.shape}: expected ({len(kp)},) each, one per joint")
    bones = np.flatnonzero(body)
    out = np.empty((len(v), len(bones)), np.float64)
    for i, k in enumerate(bones):
        children = np.flatnonzero((parents == k) & body)
        if not len(children):
            out[:, i] = np.linalg.norm(v - kp[k], axis=1)
            continue
        heads = np.repeat(kp[k][None], len(children), 0)
        out[:, i] = point_segment_distance(v, heads, kp[children]).min(axis=1)
    return out.astype(np.float32)
