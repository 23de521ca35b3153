"""The unit-height frame SFPT's networks read every mesh in."""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.mesh import unit_height_frame


def unit_frame(vertices: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(N, 3) float32 ``vertices`` in the unit-height frame of ``rest`` (its box centre, its height)."""
    centre, height = unit_height_frame(rest)
    return ((np.asarray(vertices, np.float64) - centre) / height).astype(np.float32)
