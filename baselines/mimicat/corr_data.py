"""Per-character inputs of the correspondence transformer G, and the ``pairs/`` reader G trains on.

A character enters G as its skeleton (one feature row a keypoint, :func:`keypoint_features`)
and its rest mesh (a fixed subset of vertices for the shape encoder E, :func:`point_indices`).
Everything is expressed in the character's own normalised frame: centred at the rest mesh's
bounding-box centre and divided by its largest extent (the benchmark's size), so a snake and a
giant give comparable numbers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.shards import read_records

KEYPOINT_FEATURES = 11
"""Width of :func:`keypoint_features`: position (3), offset from the parent (3), depth in the
tree (1), children (1), root (1), leaf (1), |x| distance from the mid-plane (1)."""


def rest_frame(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) of the rest mesh's bounding box and its largest side (metres)."""
    v = np.asarray(vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    return (lo + hi) / 2, float(max((hi - lo).max(), 1e-9))


def keypoint_features(keypoints: np.ndarray, parents: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Skeleton features (K, KEYPOINT_FEATURES) float32 in the character's normalised frame.

    Args:
        keypoints: (K, 3) rest joint heads, metres.
        parents: (K,) parents, -1 for roots, ``parents[k] < k``.
        vertices: (N, 3) rest vertices (for the frame).
    """
    centre, size = rest_frame(vertices)
    c = (np.asarray(keypoints, np.float64) - centre) / size
    parents = np.asarray(parents)
    k = len(parents)
    depth = np.zeros(k)
    offset = np.zeros((k, 3))
    children = np.zeros(k)
    for j, p in enumerate(parents):
        if p >= 0:
            depth[j] = depth[p] + 1
            offset[j] = c[j] - c[p]
            children[p] += 1
    feats = np.concatenate([c, offset * 4.0, (depth / max(depth.max(), 1.0))[:, None], np.minimum(children, 4)[:, None] / 4,
                            (parents < 0)[:, None], (children == 0)[:, None], np.abs(c[:, :1]) * 2], axis=1)
    return feats.astype(np.float32)


def point_indices(num_vertices: int, num_points: int, key: str) -> np.ndarray:
    """A fixed subset of ``num_points`` vertex indices (with repeats when the mesh has fewer),
    the same for a character at rest and posed, seeded by ``key`` (the character ID)."""
    import zlib

    rng = np.random.default_rng(zlib.crc32(key.encode()))
    return rng.choice(num_vertices, size=num_points, replace=num_vertices < num_points)


def normalised_points(vertices: np.ndarray, rest_vertices: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(P, 3) float32 points ``vertices[indices]`` in the frame of the rest mesh (centre, largest side)."""
    centre, size = rest_frame(rest_vertices)
    return ((np.asarray(vertices, np.float64)[indices] - centre) / size).astype(np.float32)


@dataclass
class PairTarget:
    """What G is trained to reproduce for one ordered pair: M_sink rows renormalised to sum to 1
    (Ks, Kt) and the Hungarian pairs (P, 2)."""

    source_id: str
    target_id: str
    m_sink: np.ndarray
    hungarian: np.ndarray


def read_pairs(dataset) -> list[PairTarget]:
    """Every row of the dataset's ``pairs/`` table as a :class:`PairTarget`.

    Raises:
        ValueError: the dataset has no pairs (run ``mimicbench datagen correspond`` first).
    """
    from mimicbench.schemas.shards import has_table

    if not has_table(dataset, "pairs"):
        raise ValueError(f"{dataset}: expected a pairs/ table (run `mimicbench datagen correspond {dataset}` first)")
    out = []
    for r in read_records(dataset, "pairs"):
        m = np.asarray(r.m_sink, np.float64).reshape(r.k1, r.k2)
        rows = m.sum(axis=1, keepdims=True)
        m = np.where(rows > 0, m / np.maximum(rows, 1e-12), 0.0)
        out.append(PairTarget(r.source_id, r.target_id, m.astype(np.float32),
                              np.asarray(r.hungarian, np.int64).reshape(-1, 2)))
    return out
