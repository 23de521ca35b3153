"""How the benchmark normalises a mesh before measuring it, and how it compares two sizes.

Every metric is computed in the frame of one **rest mesh** (the target's for ground-truth
protocols, the source's for the cycle's return): centre at the centre of its axis-aligned
bounding box, divide by one length of that box. Two lengths are offered:

- ``height``: the box's Y extent. This is the convention of skeleton-free pose transfer (Liao et
  al., ECCV 2022) and MimiCAT, so PMD by height is comparable with their tables. It breaks down
  on flat or long characters: a snake a few centimetres tall turns a few centimetres of error
  into hundreds of percent.
- ``extent``: the box's largest side (height, width or length, whichever is largest). A
  humanoid's is about its height; a snake's is its length, a bird's its wing span. It keeps
  every kind of character on one scale, so cross-category views use it.

The **size** of a character (what the benchmark scales translations by when a pose moves from
one character to another) is its rest mesh's largest extent, for the same reason.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.geometry.validation import check_shape

NORMALISATIONS = ("height", "extent")


def largest_extent(rest_vertices: np.ndarray) -> float:
    """Largest side (metres) of the axis-aligned bounding box of rest vertices (N, 3)."""
    v = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
    if not extent > 0:
        raise ValueError(f"rest_vertices: expected a mesh with a positive extent, got {extent}")
    return extent


def size_ratio(source_rest_vertices: np.ndarray, target_rest_vertices: np.ndarray) -> float:
    """Target size / source size, sizes being the rest meshes' largest extents (see module doc)."""
    return largest_extent(target_rest_vertices) / largest_extent(source_rest_vertices)


@dataclass(frozen=True)
class RestFrame:
    """The normalised view of one rest mesh, derived once per case and shared by every metric.

    Attributes:
        centre: (3,) centre of the rest mesh's bounding box, metres.
        height: Y extent of the box, metres.
        extent: largest side of the box, metres.
        edges: (E, 2) unique edges of the rest mesh (for ELS), or None.
    """

    centre: np.ndarray
    height: float
    extent: float
    edges: np.ndarray | None = None

    @classmethod
    def of(cls, rest_vertices: np.ndarray, edges: np.ndarray | None = None) -> "RestFrame":
        """The frame of rest vertices (N, 3); ``edges`` (E, 2) are kept for ELS."""
        v = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
        if not len(v):
            raise ValueError("rest_vertices: expected at least one vertex, got an empty mesh")
        lo, hi = v.min(axis=0), v.max(axis=0)
        height = float(hi[1] - lo[1])
        if not height > 0:
            raise ValueError(f"rest_vertices: expected a positive Y extent, got {height}")
        return cls((lo + hi) / 2.0, height, float((hi - lo).max()), edges)

    def scale(self, by: str) -> float:
        """The length (metres) that ``by`` (``height`` or ``extent``) divides by."""
        if by == "height":
            return self.height
        if by == "extent":
            return self.extent
        raise ValueError(f"by: expected one of {', '.join(NORMALISATIONS)}, got {by!r}")

    def normalise(self, points: np.ndarray, by: str) -> np.ndarray:
        """Points (..., 3) in this frame: centred on the box centre, divided by :meth:`scale`."""
        return (np.asarray(points, np.float64) - self.centre) / self.scale(by)


def as_rest_frame(frame_or_vertices) -> RestFrame:
    """Accept a :class:`RestFrame` or rest vertices (N, 3)."""
    return frame_or_vertices if isinstance(frame_or_vertices, RestFrame) else RestFrame.of(frame_or_vertices)
