"""Closed meshes around a skeleton: one tapered, elliptic capsule (a surface of revolution) per bone.

Each capsule is a closed, consistently oriented triangle surface (outward normals) with a pole
vertex at each end, hemispherical-ish caps and a tapered middle. Capsules of neighbouring bones
overlap at the joints, so the character is "one or more closed surfaces" (one per bone).
Resolution adapts to the bone's size so the whole mesh reaches ``target_faces`` or more.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import Skeleton


def _frame(axis: np.ndarray, side_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (u, w) orthogonal to ``axis``, u leaning to ``side_ref`` (right-handed u, w, axis)."""
    u = side_ref - axis * np.dot(side_ref, axis)
    if np.linalg.norm(u) < 1e-6:
        for ref in ((1.0, 0, 0), (0, 0, 1.0), (0, 1.0, 0)):
            u = np.asarray(ref) - axis * np.dot(ref, axis)
            if np.linalg.norm(u) > 1e-3:
                break
    u = u / np.linalg.norm(u)
    w = np.cross(axis, u)
    return u, w


def capsule(head, tail, r0: float, r1: float, segments: int, body_rings: int, cap_rings: int,
            aspect=(1.0, 1.0), side_ref=(1.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed tapered capsule from ``head`` to ``tail``.

    Args:
        head, tail: (3,) bone ends, metres (distinct).
        r0, r1: radii at head and tail, metres (> 0).
        segments: vertices around each ring (>= 3).
        body_rings, cap_rings: rings along the middle and on each cap (>= 1).
        aspect: cross-section scales along (u, w), the side axis and its normal.

    Returns:
        vertices (V, 3) float64 and faces (F, 3) int64 (outward, counter-clockwise), with
        V = 2 + segments * R and F = 2 * segments * R, R = 2 * cap_rings + body_rings.
    """
    head, tail = np.asarray(head, float), np.asarray(tail, float)
    axis = tail - head
    length = float(np.linalg.norm(axis))
    axis /= length
    u, w = _frame(axis, np.asarray(side_ref, float))
    # profile (axial position, radius) of the interior rings, strictly increasing in position
    prof = [(-r0 * np.cos(x), r0 * np.sin(x)) for x in np.linspace(0, np.pi / 2, cap_rings + 1)[1:]]
    prof += [(length * s, r0 + (r1 - r0) * s) for s in np.linspace(0, 1, body_rings + 2)[1:-1]]
    prof += [(length + r1 * np.sin(x), r1 * np.cos(x)) for x in np.linspace(0, np.pi / 2, cap_rings + 1)[:-1]]
    ax = np.array([p[0] for p in prof])
    rad = np.array([p[1] for p in prof])
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    cu, cw = aspect[0] * np.cos(ang), aspect[1] * np.sin(ang)
    ring_pts = (head + ax[:, None, None] * axis
                + rad[:, None, None] * (cu[None, :, None] * u + cw[None, :, None] * w))  # (R, S, 3)
    south = head - r0 * axis
    north = tail + r1 * axis
    verts = np.concatenate([south[None], ring_pts.reshape(-1, 3), north[None]])
    R, S = len(prof), segments
    idx = 1 + np.arange(R * S).reshape(R, S)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(S, int), nxt[0], idx[0]], 1)]  # around the south pole
    a_, b_, c_, d_ = idx[:-1], nxt[:-1], idx[1:], nxt[1:]
    faces.append(np.stack([a_, b_, d_], -1).reshape(-1, 3))
    faces.append(np.stack([a_, d_, c_], -1).reshape(-1, 3))
    top = 1 + R * S
    faces.append(np.stack([np.full(S, top), idx[-1], nxt[-1]], 1))
    return verts, np.concatenate(faces)


def capsule_resolution(length: float, radius: float, aspect, edge: float) -> tuple[int, int, int]:
    """(segments, body_rings, cap_rings) giving edges near ``edge`` metres (with minimums)."""
    circ = 2 * np.pi * radius * max(aspect)
    segments = int(np.clip(np.ceil(circ / edge), 8, 48))
    body = int(np.clip(np.ceil(length / edge), 1, 48))
    cap = int(np.clip(np.ceil(0.5 * np.pi * radius / edge / 1.5), 2, 10))
    return segments, body, cap


def build_mesh(skel: Skeleton, target_faces: int = 8000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mesh every bone of ``skel``.

    Returns:
        vertices (N, 3) float64, faces (M, 3) int64, owner (N,) int64 bone index of each vertex.
    """
    lengths = np.linalg.norm(skel.tails - skel.heads, axis=1)
    rmean = 0.5 * (skel.radius_head + skel.radius_tail) * skel.aspect.mean(1)
    area = float(np.sum(2 * np.pi * rmean * lengths + 4 * np.pi * rmean ** 2))
    edge = np.sqrt(2.0 * area / target_faces)
    while True:
        parts = []
        for k in range(skel.num_joints):
            res = capsule_resolution(lengths[k], max(skel.radius_head[k], skel.radius_tail[k]), skel.aspect[k], edge)
            parts.append(res)
        faces_total = sum(2 * s * (2 * c + b) for s, b, c in parts)
        if faces_total >= target_faces:
            break
        edge *= 0.85
    verts, faces, owner = [], [], []
    offset = 0
    for k, (s, bdy, c) in enumerate(parts):
        v, f = capsule(skel.heads[k], skel.tails[k], skel.radius_head[k], skel.radius_tail[k], s, bdy, c,
                       skel.aspect[k], skel.side_ref[k])
        verts.append(v)
        faces.append(f + offset)
        owner.append(np.full(len(v), k))
        offset += len(v)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(owner)
