"""What a method receives: rigs at rest, and the posed source vertices."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from benchmark.normalisation import largest_extent
from mimicbench.weights import SparseWeights


@dataclass(frozen=True)
class Rig:
    """A character at rest with its skeleton (dataset frame: metres, Y up, +Z forward).

    Attributes:
        character_id: stable ID.
        category: e.g. ``humanoid``, ``bird``.
        vertices: (N, 3) float32 rest vertices.
        faces: (M, 3) int32 triangles.
        keypoints: (K, 3) float32 joint heads at rest.
        parents: (K,) int32, -1 for roots, ``parents[k] < k``.
        weights: skin weights, :class:`SparseWeights` of N rows over K keypoints.
        bone_names: K names as authored.
    """

    character_id: str
    category: str
    vertices: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray
    parents: np.ndarray
    weights: SparseWeights
    bone_names: tuple[str, ...]

    @property
    def height(self) -> float:
        """Y extent of the rest mesh, metres."""
        return float(self.vertices[:, 1].max() - self.vertices[:, 1].min())

    @property
    def size(self) -> float:
        """Largest side of the rest mesh's bounding box, metres: the size the benchmark scales
        translations by between two characters (:func:`benchmark.normalisation.size_ratio`)."""
        return largest_extent(self.vertices)


@dataclass(frozen=True)
class TransferRequest:
    """Pose the target like the posed source.

    Attributes:
        source: the source rig at rest.
        source_posed: (Ns, 3) float32 posed source vertices (a method that needs transforms
            estimates them, so the cycle's return leg is the same problem as the forward leg).
        target: the target rig at rest.
        case_id: the case this request serves (for logging; methods must not parse it).
        extras: optional precomputed data keyed by name, e.g. ``"m_sink"``: (Ks, Kt) soft
            correspondence from the dataset's ``pairs/`` table.
    """

    source: Rig
    source_posed: np.ndarray
    target: Rig
    case_id: str = ""
    extras: dict = field(default_factory=dict)
