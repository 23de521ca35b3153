"""What one rendered picture shows: a mesh, its colour, its label, and which camera it shares.

A :class:`Panel` is one mesh in the dataset's frame (metres, Y up, +Z forward). Panels with the
same ``frame`` key are framed by one camera fitted to all of their vertices, so a prediction
drawn beside its ground truth keeps its offset and scale instead of being re-centred.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# One colour a role, everywhere (RGB in 0..1): what a panel is reads the same on every page.
ROLE_COLOURS = {
    "source": (0.33, 0.52, 0.80),        # posed source: blue
    "ground_truth": (0.36, 0.70, 0.42),  # target ground truth: green
    "prediction": (0.93, 0.58, 0.25),    # a method's output on the target: orange
    "returned": (0.62, 0.45, 0.78),      # cct: the cycle's return on the source: purple
    "rest": (0.72, 0.72, 0.72),          # a character at rest (contact sheet): grey
}


@dataclass
class Panel:
    """One mesh to render.

    Attributes:
        vertices: (N, 3) float32, metres, dataset frame (Y up, +Z forward).
        faces: (M, 3) int32 triangles.
        label: text drawn above the picture (newlines allowed).
        role: a key of :data:`ROLE_COLOURS`, or any name when ``colour`` is given.
        frame: panels with the same key share one camera (default: the panel's own).
        colour: (3,) RGB in 0..1; default the role's colour.
        reference: this panel sets its frame's centre and base size (default: the frame's first
            panel does).
    """

    vertices: np.ndarray
    faces: np.ndarray
    label: str = ""
    role: str = "rest"
    frame: str | None = None
    colour: tuple[float, float, float] | None = None
    reference: bool = False

    def __post_init__(self):
        self.vertices = np.asarray(self.vertices, np.float32)
        self.faces = np.asarray(self.faces, np.int32)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or len(self.vertices) == 0:
            raise ValueError(f"panel {self.label!r}: expected vertices of shape (N, 3) with N > 0, "
                             f"got {self.vertices.shape}")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0:
            raise ValueError(f"panel {self.label!r}: expected faces of shape (M, 3) with M > 0, got {self.faces.shape}")
        if self.faces.min() < 0 or self.faces.max() >= len(self.vertices):
            raise ValueError(f"panel {self.label!r}: face indices must lie in [0, {len(self.vertices)}), "
                             f"got [{self.faces.min()}, {self.faces.max()}]")
        if not np.isfinite(self.vertices).all():
            raise ValueError(f"panel {self.label!r}: vertices hold NaN or inf")
        if self.colour is None:
            if self.role not in ROLE_COLOURS:
                raise ValueError(f"panel {self.label!r}: unknown role {self.role!r} and no colour; expected one of "
                                 f"{', '.join(ROLE_COLOURS)}")
            self.colour = ROLE_COLOURS[self.role]
