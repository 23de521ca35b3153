"""Small hand-built characters for tests that must not depend on the zoo."""
from __future__ import annotations

import numpy as np

from mimicbench.schemas.weights import SparseWeights


def make_tube(num_bones: int = 4, rings: int = 24, segments: int = 16, height: float = 1.0,
              radius: float = 0.08, branch: bool = True):
    """A closed vertical tube along +Y with a chain of bones, optionally a side branch bone.

    Returns a dict with ``vertices`` (N, 3) float32, ``faces`` (M, 3) int32, ``keypoints``
    (K, 3) float32, ``parents`` (K,) int32, ``weights`` :class:`SparseWeights` (smooth, linear
    blend between the two nearest joints along the tube) and ``bone_names``.
    """
    ys = np.linspace(0.0, height, rings)
    ang = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(ang), np.zeros_like(ang), radius * np.sin(ang)], 1)
    verts = np.concatenate([ring + [0.0, y, 0.0] for y in ys] + [[[0, 0, 0]], [[0, height, 0]]])
    faces = []
    for r in range(rings - 1):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            c, d = a + segments, b + segments
            faces += [[a, c, b], [b, c, d]]
    bottom, top = rings * segments, rings * segments + 1
    for s in range(segments):
        faces.append([bottom, s, (s + 1) % segments])
        t0 = (rings - 1) * segments
        faces.append([top, t0 + (s + 1) % segments, t0 + s])
    joints_y = np.linspace(0.0, height * (num_bones - 1) / num_bones, num_bones)
    keypoints = [[0.0, y, 0.0] for y in joints_y]
    parents = [-1] + list(range(num_bones - 1))
    names = [f"Bone{i}" for i in range(num_bones)]
    k = num_bones
    dense = np.zeros((len(verts), k + (1 if branch else 0)))
    seg = height / num_bones
    for i, v in enumerate(verts):
        t = np.clip(v[1] / seg - 0.5, 0, num_bones - 1)
        j0 = int(np.floor(t))
        j1 = min(j0 + 1, num_bones - 1)
        f = t - j0
        dense[i, j0] += 1 - f
        dense[i, j1] += f
    if branch:
        # a side bone at mid height that owns the +X half of one ring band
        mid = num_bones // 2
        keypoints.append([radius, joints_y[mid], 0.0])
        parents.append(mid)
        names.append("Side")
        band = (np.abs(verts[:, 1] - joints_y[mid]) < seg * 0.3) & (verts[:, 0] > radius * 0.5)
        dense[band] = 0.0
        dense[band, k] = 1.0
    weights = SparseWeights.from_dense(dense)
    return {
        "vertices": verts.astype(np.float32),
        "faces": np.asarray(faces, dtype=np.int32),
        "keypoints": np.asarray(keypoints, dtype=np.float32),
        "parents": np.asarray(parents, dtype=np.int32),
        "weights": weights,
        "bone_names": names,
    }
