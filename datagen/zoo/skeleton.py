"""A template skeleton: joints with roles, rest heads and tails, body radii and joint limits.

Templates add joints with :class:`SkeletonBuilder`; :meth:`SkeletonBuilder.build` returns a
:class:`Skeleton` of plain arrays. Positions are metres in the dataset frame (Y up, +Z forward,
the character's left is +X). A joint's *bone* runs from its head (the keypoint) to its tail;
the mesh builder wraps each bone in a tapered capsule of radii ``radius_head``/``radius_tail``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIDES = (("left", 1.0), ("right", -1.0))


@dataclass
class Skeleton:
    """Arrays of a template skeleton with K joints (topological order, ``parents[k] < k``).

    Attributes:
        roles: K hidden semantic roles, e.g. ``left/upper_arm``, ``tail/3``.
        parents: (K,) int32, -1 for the root.
        heads: (K, 3) float64 joint positions at rest (the keypoints), metres.
        tails: (K, 3) float64 bone ends at rest, metres (never equal to the head).
        radius_head, radius_tail: (K,) float64 capsule radii at the two ends, metres.
        aspect: (K, 2) float64 cross-section scale along the bone's side axis and its normal.
        side_ref: (K, 3) float64 direction the cross-section's first axis leans to.
        apparel: (K,) bool, apparel chain bones (skirt, hair, cape, coat tails).
        limits: (K,) float64 largest rest-relative rotation of the joint, radians.
    """

    roles: list[str]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    radius_head: np.ndarray
    radius_tail: np.ndarray
    aspect: np.ndarray
    side_ref: np.ndarray
    apparel: np.ndarray
    limits: np.ndarray

    @property
    def num_joints(self) -> int:
        return len(self.roles)

    def children(self) -> list[list[int]]:
        """Child indices of every joint."""
        out: list[list[int]] = [[] for _ in self.roles]
        for k, p in enumerate(self.parents):
            if p >= 0:
                out[p].append(k)
        return out

    def index(self, role: str) -> int:
        return self.roles.index(role)


class SkeletonBuilder:
    """Collects joints in topological order; ``add`` returns the new joint's index."""

    def __init__(self):
        self._joints: list[dict] = []

    def add(self, role: str, parent: int, head, tail, radius: float, radius_tail: float | None = None,
            aspect=(1.0, 1.0), side_ref=(1.0, 0.0, 0.0), apparel: bool = False, limit: float = 0.6) -> int:
        """Add one joint whose bone runs from ``head`` to ``tail``; returns its index."""
        if parent >= len(self._joints):
            raise ValueError(f"{role}: parent {parent} does not exist yet (joints so far: {len(self._joints)})")
        if any(j["role"] == role for j in self._joints):
            raise ValueError(f"{role}: role already used")
        head, tail = np.asarray(head, float), np.asarray(tail, float)
        if np.linalg.norm(tail - head) < 1e-4:
            raise ValueError(f"{role}: bone shorter than 0.1 mm (head {head}, tail {tail})")
        self._joints.append(dict(role=role, parent=parent, head=head, tail=tail, r0=float(radius),
                                 r1=float(radius if radius_tail is None else radius_tail),
                                 aspect=tuple(aspect), side_ref=tuple(side_ref), apparel=apparel,
                                 limit=float(limit)))
        return len(self._joints) - 1

    def chain(self, roles: list[str], parent: int, points, radii, **kw) -> list[int]:
        """Add joints ``roles[i]`` from ``points[i]`` to ``points[i+1]`` (len(points) = len(roles)+1).

        ``radii`` has len(points) values: joint i tapers from radii[i] to radii[i+1].
        """
        points = np.asarray(points, float)
        if len(points) != len(roles) + 1 or len(radii) != len(points):
            raise ValueError(f"chain {roles[:1]}: expected {len(roles) + 1} points and radii, "
                             f"got {len(points)} and {len(radii)}")
        out = []
        for i, role in enumerate(roles):
            parent = self.add(role, parent, points[i], points[i + 1], radii[i], radii[i + 1], **kw)
            out.append(parent)
        return out

    def build(self) -> Skeleton:
        j = self._joints
        return Skeleton(
            roles=[x["role"] for x in j],
            parents=np.array([x["parent"] for x in j], np.int32),
            heads=np.array([x["head"] for x in j], float),
            tails=np.array([x["tail"] for x in j], float),
            radius_head=np.array([x["r0"] for x in j], float),
            radius_tail=np.array([x["r1"] for x in j], float),
            aspect=np.array([x["aspect"] for x in j], float),
            side_ref=np.array([x["side_ref"] for x in j], float),
            apparel=np.array([x["apparel"] for x in j], bool),
            limits=np.array([x["limit"] for x in j], float),
        )


def lerp_points(a, b, n: int) -> np.ndarray:
    """``n + 1`` points evenly from ``a`` to ``b`` (n segments), shape (n+1, 3)."""
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    return (1 - t) * np.asarray(a, float) + t * np.asarray(b, float)


def arc_points(start, directions) -> np.ndarray:
    """Points (len(directions)+1, 3) from ``start`` adding each step vector of ``directions``."""
    steps = np.asarray(directions, float)
    return np.concatenate([np.asarray(start, float)[None], np.asarray(start, float) + np.cumsum(steps, 0)])
