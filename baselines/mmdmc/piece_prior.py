"""The piece prior on f_s's skinning scores (ours; config ``body_prior="piece"``, the shipped
f_s's).

Many characters are modelled in pieces: a separate head, hands, shoes, or (every zoo character)
one closed capsule per bone. A piece that wraps one bone is skinned, by artists and by the zoo
alike, to that bone and its neighbours in the skeleton, blended by distance. This prior says so:
for a vertex i of a piece that wraps bone a, the score of body bone k is

    -POWER * log(B_ik + SOFT * r + EPS) + log(OWN) [k = a]      where bone k is a or a neighbour of a,
    OUTSIDE                                                      for every other bone,

with B_ik the distance to bone k's segments (:mod:`mimicbench.baselines.mmdmc.bone_distance`, unit-height
frame) and r the piece's mean distance to a (its thickness, so a segment piercing the surface
grabs no sharp spot).

- **Anchor.** The body bone nearest on average over the piece's vertices; but a piece whose centre
  lies beyond a leaf child's joint (seen from that bone) hangs from the leaf (a head beyond the
  neck, a hand beyond the wrist).
- **A leaf anchor's segment.** A rig gives a leaf bone a joint and no tail, so its distance is to a
  point and a head's far side reads nearer the neck. For a piece anchored at a leaf, the leaf's
  distances are taken to the segment from its joint through the piece, to twice the piece's centre.
- **Which pieces.** A piece wraps its anchor when it has at least MIN_VERTICES vertices (fewer is a
  fragment: a flat-shaded mesh's split faces), its bounding box is at most WRAP_EXTENT of the
  height across, and at least WRAP_SHARE of its vertices have their nearest bone within WRAP_HOPS
  of the anchor. A piece that wraps no bone (a body modelled in one piece) gets no piece prior:
  f_s scores it with its bone-distance prior -B / tau, as before.

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from mimicbench.baselines.mmdmc.rig import attachment_bones
from mimicbench.geometry.mesh import mesh_pieces
from mimicbench.geometry.segments import point_segment_distance

POWER = 4.0        # inverse-distance power of the blend
SOFT = 0.5         # share of the piece's thickness added to every distance
OWN = 1.5          # the anchor bone's lead where distances tie
EPS = 1e-4         # unit-height frame: keeps the log finite on a bone's segment
OUTSIDE = -50.0    # score of a bone that is neither the anchor nor its neighbour (weight about e^-50 of theirs)
WRAP_SHARE = 0.5   # share of a piece's vertices whose nearest bone is within WRAP_HOPS of its anchor
WRAP_HOPS = 2
WRAP_EXTENT = 0.6  # largest bounding-box diagonal of a piece that wraps one bone, unit-height frame
MIN_VERTICES = 24  # fewer vertices make a fragment (a flat-shaded mesh's split faces), not a piece


def body_parents(parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(Kb,) int64 column of each body bone's nearest body ancestor (apparel bones between them
    skipped, :func:`mimicbench.baselines.mmdmc.rig.attachment_bones`), -1 for none.

    Args:
        parents: (K,) int, -1 for a root; body: (K,) bool body bones (their order gives the columns).
    """
    attach = attachment_bones(parents, body)  # checks the shapes
    parents = np.asarray(parents, np.int64)
    body = np.asarray(body, bool)
    column = np.full(len(body) + 1, -1)  # index -1 (no ancestor) reads the last entry, -1
    column[np.flatnonzero(body)] = np.arange(int(body.sum()))
    return column[np.where(parents >= 0, attach[np.maximum(parents, 0)], -1)[body]].astype(np.int64)


def links_hops(up: np.ndarray) -> np.ndarray:
    """(Kb, Kb) float64 links between body bones along the skeleton given each one's body parent
    column ``up`` (Kb,) (:func:`body_parents`); inf where none joins them."""
    n = len(up)
    child = np.flatnonzero(up >= 0)
    graph = coo_matrix((np.ones(len(child)), (child, up[child])), shape=(n, n)).tocsr()
    return shortest_path(graph, directed=False, unweighted=True)


def skeleton_hops(parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(Kb, Kb) float64 links between body bones along the skeleton (inf where none joins them)."""
    return links_hops(body_parents(parents, body))


def leaves(up: np.ndarray) -> np.ndarray:
    """(Kb,) bool: body bones no body bone hangs from, given ``up`` (:func:`body_parents`)."""
    return np.bincount(up[up >= 0], minlength=len(up)) == 0


def piece_means(label: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(P, C) mean over each piece of ``values`` (N, C), pieces labelled 0..P-1 by ``label`` (N,)."""
    count = np.bincount(label).astype(np.float64)
    return np.stack([np.bincount(label, values[:, c], minlength=len(count)) for c in range(values.shape[1])],
                    1) / count[:, None]


def anchors(bone: np.ndarray, label: np.ndarray, centre: np.ndarray, joints: np.ndarray,
            up: np.ndarray) -> np.ndarray:
    """(P,) column of each piece's anchor: its nearest bone on average, or a leaf child of that bone
    whose joint the piece's centre (P, 3) lies beyond.

    Args:
        bone: (N, Kb) distances; label: (N,) piece of each vertex; joints: (Kb, 3) body joints;
            up: (Kb,) :func:`body_parents`.
    """
    out = piece_means(label, bone).argmin(axis=1)
    leaf = leaves(up)
    for p, a in enumerate(out.copy()):
        for c in np.flatnonzero((up == a) & leaf):
            d = joints[c] - joints[a]
            if float((centre[p] - joints[a]) @ d) > float(d @ d):
                out[p] = c
    return out


def piece_prior(vertices: np.ndarray, faces: np.ndarray, bone: np.ndarray, joints: np.ndarray,
                parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(N, Kb) float32 prior scores; rows of vertices whose piece wraps no bone are NaN.

    Args:
        vertices: (N, 3) rest positions, unit-height frame.
        faces: (M, 3) int triangles.
        bone: (N, Kb) distances from every vertex to every body bone's segments, unit-height frame.
        joints: (Kb, 3) rest body joints, unit-height frame.
        parents: (K,) int; body: (K,) bool (Kb of them true, in ``bone``'s column order).
    """
    b = np.array(bone, np.float64)
    v = np.asarray(vertices, np.float64)
    joints = np.asarray(joints, np.float64)
    n, kb = b.shape
    up = body_parents(parents, body)
    if len(up) != kb or joints.shape != (kb, 3) or v.shape != (n, 3):
        raise ValueError(f"expected vertices (N, 3), bone distances (N, Kb) and joints (Kb, 3) for the rig's {len(up)} "
                         f"body bones; got {v.shape}, {b.shape} and {joints.shape}")
    hops = links_hops(up)
    label = mesh_pieces(faces, n)
    count = np.bincount(label)
    centre = piece_means(label, v)
    piece_anchor = anchors(b, label, centre, joints, up)
    leaf = leaves(up)
    order = np.argsort(label, kind="stable")
    start = np.r_[0, np.cumsum(count)]
    for p in np.flatnonzero(leaf[piece_anchor] & (count >= MIN_VERTICES)):  # a leaf's segment runs through its piece
        a, rows = piece_anchor[p], order[start[p]:start[p + 1]]
        b[rows, a] = point_segment_distance(v[rows], joints[a][None], (2 * centre[p] - joints[a])[None])[:, 0]
    anchor = piece_anchor[label]  # (N,)
    near = hops[anchor] <= 1  # (N, Kb) the anchor and its skeleton neighbours
    share = np.bincount(label, hops[anchor, b.argmin(axis=1)] <= WRAP_HOPS, minlength=len(count)) / count
    lo = np.full((len(count), 3), np.inf)
    hi = np.full((len(count), 3), -np.inf)
    np.minimum.at(lo, label, v)
    np.maximum.at(hi, label, v)
    extent = np.linalg.norm(hi - lo, axis=1)
    wraps = ((share >= WRAP_SHARE) & (extent <= WRAP_EXTENT) & (count >= MIN_VERTICES))[label]
    thickness = piece_means(label, b[np.arange(n), anchor][:, None])[label, 0]
    scores = -POWER * np.log(b + SOFT * thickness[:, None] + EPS)
    scores[np.arange(n), anchor] += np.log(OWN)
    scores = np.where(near, scores, OUTSIDE)
    scores[~wraps] = np.nan
    return scores.astype(np.float32)
