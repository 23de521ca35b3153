"""``body_only``: apparel vertices re-skinned to their nearest body bones (methods that know no
apparel bones).

For a motion request, every vertex's skin weight on bones outside ``request.body_bones`` moves to
the body bone nearest to the vertex at rest (distance to the bone's segment from its head to its
first child's head; a leaf bone is its head point); the mesh is then posed by linear blend
skinning with the body bones' transforms. Apparel thus moves rigidly with the body part under it.
"""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.weights import SparseWeights, as_dense


def nearest_body_bone(points: np.ndarray, keypoints: np.ndarray, parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(P,) index of the body bone nearest to each point (P, 3), by distance to the bone's segment."""
    keypoints = np.asarray(keypoints, np.float64)
    bones = np.nonzero(body)[0]
    heads = keypoints[bones]
    tails = heads.copy()
    for i, k in enumerate(bones):
        children = [c for c in range(len(parents)) if parents[c] == k and body[c]]
        if children:
            tails[i] = keypoints[children[0]]
    d = tails - heads  # (B, 3)
    length2 = np.maximum((d * d).sum(1), 1e-12)
    rel = np.asarray(points, np.float64)[:, None, :] - heads[None]  # (P, B, 3)
    s = np.clip((rel * d[None]).sum(-1) / length2, 0.0, 1.0)
    dist = np.linalg.norm(rel - s[..., None] * d[None], axis=-1)
    return bones[np.argmin(dist, axis=1)]


def body_weights(rig, body: np.ndarray) -> np.ndarray:
    """Dense (N, K) weights with every non-body bone's weight moved to the vertex's nearest body bone."""
    body = np.asarray(body, bool)
    dense = as_dense(rig.weights, len(rig.parents))
    moved = dense[:, ~body].sum(axis=1)
    out = dense * body[None, :]
    rows = np.nonzero(moved > 0)[0]
    if len(rows):
        target = nearest_body_bone(np.asarray(rig.vertices)[rows], rig.keypoints, rig.parents, body)
        np.add.at(out, (rows, target), moved[rows])
    return out


class BodyOnly(PoseTransferMethod):
    metadata = MethodMetadata(name="body_only", version="1", licence="MIT", protocols=("apparel",),
                              description="apparel re-skinned to the nearest body bones, posed by the body's motion")

    def transfer(self, requests):
        raise NotImplementedError("body_only answers motion requests only (the apparel protocol)")

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per request: LBS with apparel weight moved onto the nearest body bones."""
        out = []
        for r in requests:
            weights = SparseWeights.from_dense(body_weights(r.target, r.body_bones))
            out.append(linear_blend_skinning(r.target.vertices, r.target.keypoints, weights,
                                             np.asarray(r.transforms, np.float32)))
        return out
