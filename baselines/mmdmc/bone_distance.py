"""Vertex-bone distances: how far each vertex is from each body bone's segment (our addition to
MMDMC's vertex-joint relation, Sec. 4.2; see :mod:`mimicbench.baselines.mmdmc.body`).

A joint position alone does not say which way its bone runs: a vertex halfway down the upper arm
is as near the elbow joint as the shoulder joint, yet belongs to the upper arm. Bone k's segments
run from joint k to each of its body children (a leaf bone is its joint's point); the distance of
a vertex to bone k is the smallest over those segments. Distances use the rig's parents, which a
request always carries, never its skin weights.

A child joint far outside the mesh ends no segment (``box``, :func:`mesh_box`): rigs carry helper
joints that steer physics or IK and are no part of the shape, such as MMD's weight bones (錘). Gene's
front cloak bone has one 7.5 m below it (the model is 1.6 m tall): a segment to it runs down through
the legs, which then read as lying on the cloak, and f_c labelled 1,537 leg and shoe vertices
apparel, carried by the cloak's anchor.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.segments import point_segment_distance
from mimicbench.geometry.validation import check_shape


BOX_MARGIN = 0.1  # share of the mesh's largest extent by which :func:`mesh_box` grows its box


def mesh_box(vertices: np.ndarray) -> np.ndarray:
    """(2, 3) float64 low and high corners of the bounding box of ``vertices`` (N, 3), grown on every
    side by :data:`BOX_MARGIN` of its largest extent (a joint at a fingertip or a tail's tip is in)."""
    v = np.asarray(check_shape(vertices, (None, 3), "vertices"), np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    grow = BOX_MARGIN * float((hi - lo).max())
    return np.stack([lo - grow, hi + grow])


def bone_distances(vertices: np.ndarray, keypoints: np.ndarray, parents: np.ndarray, body: np.ndarray,
                   box: np.ndarray | None = None) -> np.ndarray:
    """(N, Kb) float32 distance, metres, from every vertex (N, 3) to the segments of every body bone.

    Args:
        keypoints: (K, 3) rest joints; parents: (K,) int, -1 for a root; body: (K,) bool body bones
            (their order gives the columns).
        box: (2, 3) low and high corners (:func:`mesh_box` of the rest mesh); a child joint outside
            it ends no segment (a bone left with none is its joint's point). None: every child does.
    """
    v = np.asarray(check_shape(vertices, (None, 3), "vertices"), np.float64)
    kp = np.asarray(check_shape(keypoints, (None, 3), "keypoints"), np.float64)
    parents = np.asarray(parents, np.int64)
    body = np.asarray(body, bool)
    if parents.shape != (len(kp),) or body.shape != (len(kp),):
        raise ValueError(f"parents {parents.shape} and body {body.shape}: expected ({len(kp)},) each, one per joint")
    inside = np.ones(len(kp), bool) if box is None else np.all((kp >= box[0]) & (kp <= box[1]), axis=1)
    bones = np.flatnonzero(body)
    out = np.empty((len(v), len(bones)), np.float64)
    for i, k in enumerate(bones):
        children = np.flatnonzero((parents == k) & body & inside)
        if not len(children):
            out[:, i] = np.linalg.norm(v - kp[k], axis=1)
            continue
        heads = np.repeat(kp[k][None], len(children), 0)
        out[:, i] = point_segment_distance(v, heads, kp[children]).min(axis=1)
    return out.astype(np.float32)
