"""The piece prior on f_s's skinning scores (ours; config ``body_prior="piece"``, the shipped f_s
since methods version 6).

Many characters are modelled in pieces: a separate head, hands, shoes, or (every zoo character)
one closed capsule per bone. A piece that wraps one bone is skinned, by artists and by the zoo
alike, to that bone and its neighbours in the skeleton, blended by distance. This prior says so:
for a vertex i of a piece that wraps bone a, the score of body bone k is

    -POWER * log(B_ik + SOFT * r + EPS) + log(OWN) [k = a]      where bone k is a or a neighbour of a,
    OUTSIDE                                                      for every other bone,

with B_ik the distance to bone k's segments (:mod:`baselines.mmdmc.bone_distance`, unit-height
frame) and r the piece's mean distance to a (its thickness, so a segment piercing the surface
grabs no sharp spot). The anchor a of a piece is the body bone nearest on average over its
vertices; the piece wraps it when at least WRAP_SHARE of its vertices have a or one of its
skeleton neighbours as their nearest bone. A piece that wraps no bone (a whole body modelled in
one piece) gets no piece prior: f_s scores it with its bone-distance prior -B / tau, as before.

Measured on the validation zoo (seed 303, 4 characters; LBS of the kinematic clips, every 4th
frame, with the prior's weights against the dataset's; body vertices and body edges): weight
error 0.235 of 2 (L1 per vertex) and mean body-edge stretch 0.30%, against 0.50 and 1.06% for the
shipped f_s of methods version 5 (bone-distance prior, trained 9 epochs, smoothed over 4% of the
height). Anchoring each vertex at its own nearest bone instead of its piece's gives 0.61 and 2.8%:
the anchor must not switch inside a piece. The constants are the zoo's own rule for its weights
(:mod:`datagen.zoo.skin_weights`), which is also what an artist's limb skinning looks like: its
bone leads, its neighbours blend in by distance, the rest of the skeleton is left out.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

POWER = 4.0        # inverse-distance power of the blend
SOFT = 0.5         # share of the piece's thickness added to every distance
OWN = 1.5          # the anchor bone's lead where distances tie
EPS = 1e-4         # unit-height frame: keeps the log finite on a bone's segment
OUTSIDE = -50.0    # score of a bone that is neither the anchor nor its neighbour (weight about e^-50 of theirs)
WRAP_SHARE = 0.5   # share of a piece's vertices whose nearest bone is within WRAP_HOPS of its anchor, for it to wrap the anchor
WRAP_HOPS = 2
WRAP_EXTENT = 0.6  # largest bounding-box diagonal of a piece that wraps one bone, unit-height frame
MIN_VERTICES = 24  # fewer vertices make a fragment (a flat-shaded mesh's split faces), not a piece that wraps a bone


def skeleton_hops(parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(Kb, Kb) float64 links between body bones along the skeleton (inf where none joins them).

    Each body bone links to its nearest body ancestor (apparel bones between them are skipped).

    Args:
        parents: (K,) int, -1 for a root; body: (K,) bool body bones (their order gives the rows).
    """
    parents = np.asarray(parents, np.int64)
    body = np.asarray(body, bool)
    if parents.shape != body.shape:
        raise ValueError(f"parents {parents.shape} and body {body.shape}: expected one entry per bone each")
    column = np.full(len(body), -1)
    column[body] = np.arange(int(body.sum()))
    rows, cols = [], []
    for k in np.flatnonzero(body):
        a, seen = int(parents[k]), 0
        while a >= 0 and not body[a] and seen <= len(parents):
            a, seen = int(parents[a]), seen + 1
        if a >= 0 and body[a]:
            rows.append(column[k])
            cols.append(column[a])
    n = int(body.sum())
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)).tocsr()
    return shortest_path(graph, directed=False, unweighted=True)


def mesh_pieces(faces: np.ndarray, n: int) -> np.ndarray:
    """(n,) int64 label of each of n vertices' piece: connected along face edges (a vertex in no face
    is its own). Vertices are not welded: the zoo's capsules touch at the joints but are pieces apart."""
    from baselines.mmdmc.apparel import apparel_components

    return apparel_components(np.asarray(faces, np.int64).reshape(-1, 3), np.ones(n, bool))


def piece_prior(vertices: np.ndarray, faces: np.ndarray, bone: np.ndarray, parents: np.ndarray,
                body: np.ndarray) -> np.ndarray:
    """(N, Kb) float32 prior scores; rows of vertices whose piece wraps no bone are NaN.

    Args:
        vertices: (N, 3) rest positions, unit-height frame.
        bone: (N, Kb) distances from every vertex to every body bone's segments, unit-height frame.
        faces: (M, 3) int triangles.
        parents: (K,) int; body: (K,) bool (Kb of them true, in ``bone``'s column order).
    """
    b = np.asarray(bone, np.float64)
    n, kb = b.shape
    hops = skeleton_hops(parents, body)
    if hops.shape != (kb, kb):
        raise ValueError(f"bone distances have {kb} columns; the rig has {len(hops)} body bones")
    v = np.asarray(vertices, np.float64)
    label = mesh_pieces(faces, n)
    count = np.bincount(label).astype(np.float64)
    mean = np.stack([np.bincount(label, b[:, k], minlength=len(count)) for k in range(kb)], 1) / count[:, None]
    anchor = mean.argmin(axis=1)[label]  # (N,) column of each vertex's piece anchor
    near = hops[anchor] <= 1  # (N, Kb) the anchor and its skeleton neighbours
    share = np.bincount(label, hops[anchor, b.argmin(axis=1)] <= WRAP_HOPS, minlength=len(count)) / count
    extent = np.zeros(len(count))
    for axis in range(3):
        hi = np.full(len(count), -np.inf)
        lo = np.full(len(count), np.inf)
        np.maximum.at(hi, label, v[:, axis])
        np.minimum.at(lo, label, v[:, axis])
        extent += (hi - lo) ** 2
    wraps = ((share >= WRAP_SHARE) & (np.sqrt(extent) <= WRAP_EXTENT) & (count >= MIN_VERTICES))[label]
    to_anchor = b[np.arange(n), anchor]
    thickness = (np.bincount(label, to_anchor, minlength=len(count)) / count)[label]
    scores = -POWER * np.log(b + SOFT * thickness[:, None] + EPS)
    scores[np.arange(n), anchor] += np.log(OWN)
    scores = np.where(near, scores, OUTSIDE)
    scores[~wraps] = np.nan
    return scores.astype(np.float32)
