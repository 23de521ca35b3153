"""Which body bone carries an apparel vertex: the body bone its nearest apparel chain hangs from.

The body module's target (:func:`mimicbench.baselines.mmdmc.data.body_target_weights`) carries each apparel
bone's weight on the body bone its chain hangs from, so apparel moves rigidly with the body part it
is attached to (a skirt with the hips, hair with the head) and the apparel module displaces it from
there. A request carries the rig (joints, parents, body-bone mask) but never its skin weights, so at
inference the vertex's chain is found geometrically: the apparel bone whose segments
(:func:`mimicbench.baselines.mmdmc.bone_distance.bone_distances` over the apparel bones) pass nearest the
vertex. Its attachment bone (:func:`mimicbench.baselines.mmdmc.rig.attachment_bones`) then gets the vertex's
whole weight. f_c's mask says which vertices are apparel; f_s skins the rest.

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np

from mimicbench.baselines.mmdmc.bone_distance import bone_distances, mesh_box
from mimicbench.baselines.mmdmc.rig import attachment_bones


def chain_attachment(vertices: np.ndarray, keypoints: np.ndarray, parents: np.ndarray,
                     body: np.ndarray, box: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For every vertex (N, 3): the column (0..Kb-1, in body-bone order) of the body bone its nearest
    apparel chain hangs from, (N,) int64, -1 when the rig has no apparel bone or that chain hangs from
    no body bone; and its distance to that nearest apparel bone, (N,) float32 metres (inf without
    apparel bones).

    Args:
        keypoints: (K, 3) rest joints, metres; parents: (K,) int, -1 for a root; body: (K,) bool body bones.
        box: (2, 3) the rest mesh's :func:`~mimicbench.baselines.mmdmc.bone_distance.mesh_box`: an apparel joint
            outside it (a physics helper) ends no apparel bone's segment. None: every joint does.
    """
    body = np.asarray(body, bool)
    apparel = ~body
    columns = np.full(len(vertices), -1, np.int64)
    if not apparel.any():
        return columns, np.full(len(vertices), np.inf, np.float32)
    attach = attachment_bones(parents, body)  # (K,) bone index, -1 when none
    column = np.full(len(body), -1, np.int64)
    column[body] = np.arange(int(body.sum()))
    d = bone_distances(vertices, keypoints, parents, apparel, box)  # (N, Ka)
    nearest = np.flatnonzero(apparel)[d.argmin(axis=1)]
    bone = attach[nearest]
    ok = bone >= 0
    columns[ok] = column[bone[ok]]
    return columns, d.min(axis=1)


def attached_weights(weights: np.ndarray, mask: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """(N, Kb) weights: ``weights`` (N, Kb) with every masked vertex (``mask`` (N,) bool) that has an
    attachment column (``columns`` (N,) from :func:`chain_attachment`, -1 none) moved wholly onto it."""
    w = np.array(weights, copy=True)
    rows = np.flatnonzero(np.asarray(mask, bool) & (np.asarray(columns) >= 0))
    w[rows] = 0
    w[rows, columns[rows]] = 1
    return w


def prepared_attachment(prep) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chain_attachment` of a :class:`~mimicbench.baselines.mmdmc.data.Prepared` character (cached on it):
    columns (N,) int64 and the distance to the nearest apparel bone (N,) float32 divided by the height."""
    if "attachment" not in prep.cache:
        columns, dist = chain_attachment(prep.rest, prep.keypoints, prep.parents, prep.body, mesh_box(prep.rest))
        prep.cache["attachment"] = (columns, (dist / prep.height).astype(np.float32))
    return prep.cache["attachment"]
