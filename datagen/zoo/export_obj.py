"""Wavefront OBJ export of a rest mesh (dataset frame: metres, Y up, +Z forward)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def write_obj(path, vertices: np.ndarray, faces: np.ndarray, name: str = "character") -> Path:
    """Write vertices (N, 3) and triangles (M, 3) (0-based) to ``path``; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f"# mimicbench zoo character {name}", f"o {name.replace(' ', '_')}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in np.asarray(vertices, np.float64)]
    lines += [f"f {a} {b} {c}" for a, b, c in np.asarray(faces, np.int64) + 1]
    path.write_text("\n".join(lines) + "\n")
    return path
