"""Which length unit a BVH file is in, from its rest skeleton (``--bvh-scale auto``).

BVH has no unit field. Mocap files are in centimetres most often, but CMU's popular BVH
conversions use their own unit (0.056444 m: inches / 0.45), and some tools write metres,
millimetres or inches. ``auto`` reads the ``OFFSET`` lines of the HIERARCHY (joint heads and end
sites at rest), and takes the first unit of :data:`UNITS`, in that order, under which the rest
skeleton's height (Y extent, BVH is Y up) lies in :data:`PLAUSIBLE_HEIGHT_M`. When none does it falls
back to centimetres and says so. The choice and its evidence are recorded per character.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

# (name, metres per file unit), in the order they are tried
UNITS = (("centimetres", 0.01), ("metres", 1.0), ("CMU units (inches / 0.45)", 0.056444),
         ("inches", 0.0254), ("millimetres", 0.001))
PLAUSIBLE_HEIGHT_M = (0.3, 3.0)
MAX_HIERARCHY_BYTES = 1 << 20  # the HIERARCHY section of real files is a few kB


def bvh_rest_height(path: str | Path) -> float:
    """Y extent of a BVH file's rest skeleton (joint heads and end sites), in file units.

    Raises:
        ValueError: no ``HIERARCHY`` with ``OFFSET`` lines within the first MiB, braces that do not
            nest, or an ``OFFSET`` without three finite numbers.
    """
    with open(path, "rb") as f:
        head = f.read(MAX_HIERARCHY_BYTES).decode("latin-1")
    text = head.split("MOTION", 1)[0]
    if "HIERARCHY" not in text:
        raise ValueError(f"{path}: expected a BVH file starting with HIERARCHY")
    stack, pending, heights = [np.zeros(3)], np.zeros(3), []
    for line_no, line in enumerate(text.splitlines(), 1):
        words = line.split()
        if not words:
            continue
        if words[0] == "OFFSET":
            try:
                offset = np.array([float(x) for x in words[1:4]])
            except ValueError:
                offset = np.array([])
            if offset.shape != (3,) or not np.isfinite(offset).all():
                raise ValueError(f"{path}:{line_no}: expected OFFSET with three finite numbers, got {line.strip()!r}")
            pending = stack[-1] + offset
            heights.append(pending[1])
        elif words[0] == "{":
            stack.append(pending)
        elif words[0] == "}":
            if len(stack) == 1:
                raise ValueError(f"{path}:{line_no}: '}}' without a matching '{{'")
            pending = stack.pop()
    if not heights:
        raise ValueError(f"{path}: no OFFSET lines in the HIERARCHY")
    return float(max(heights) - min(heights))


def auto_bvh_scale(height_units: float) -> tuple[float, str, bool]:
    """``(metres per unit, unit name, plausible)`` for a rest skeleton ``height_units`` tall.

    The first of :data:`UNITS` giving a height within :data:`PLAUSIBLE_HEIGHT_M`; centimetres with
    ``plausible=False`` when none does (a flat or degenerate skeleton).
    """
    lo, hi = PLAUSIBLE_HEIGHT_M
    for name, scale in UNITS:
        if lo <= height_units * scale <= hi:
            return scale, name, True
    return UNITS[0][1], UNITS[0][0], False
