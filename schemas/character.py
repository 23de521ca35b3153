"""A character at rest: mesh, skeleton, skin weights, names (table ``characters``)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mimicbench.schemas.columns import Column
from mimicbench.schemas.weights import MAX_INFLUENCES, SparseWeights

TABLE = "characters"

CATEGORIES = ("humanoid", "quadruped", "bird", "fish", "reptile", "insect", "apparel", "unknown")
HUMANOID_LIKE = ("humanoid", "apparel")
"""Categories that count as humanoid (an ``apparel`` character is a humanoid wearing apparel)."""


@dataclass
class CharacterRecord:
    """One rigged character at rest, in the dataset frame (metres, Y up, +Z forward).

    Arrays: ``vertices`` (N, 3) float32, ``faces`` (M, 3) int32, ``keypoints`` (K, 3) float32
    joint heads, ``parents`` (K,) int32 (-1 roots, ``parents[k] < k``), ``bone_names`` K strings
    as authored, ``weight_indices`` / ``weight_values`` (N, 8) skin weights (rows sum to 1),
    ``apparel_vertex_mask`` (N,) bool, ``apparel_bone_mask`` (K,) bool, ``bone_roles`` K hidden
    semantic roles (ground truth for correspondences, never a method input) or None.
    A skeleton-only source (a BVH file) has N = M = 0.
    """

    character_id: str
    category: str
    source: str
    split: str
    vertices: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray
    parents: np.ndarray
    bone_names: list[str]
    weight_indices: np.ndarray
    weight_values: np.ndarray
    apparel_vertex_mask: np.ndarray
    apparel_bone_mask: np.ndarray
    bone_roles: list[str] | None = None
    skeleton_id: str | None = None
    height: float | None = None
    meta: dict | None = field(default=None)

    COLUMNS = (
        Column("character_id", "scalar", "string", doc="stable ID derived from the source, e.g. `zoo/quadruped-0007`, `assets/Fox`"),
        Column("category", "scalar", "string", doc="one of " + ", ".join(CATEGORIES)),
        Column("source", "scalar", "string", doc="where it came from: `zoo:<template>@<version>` or the asset path"),
        Column("split", "scalar", "string", doc="`train`, `val` or `test`"),
        Column("vertices", "rows", "float32", 3, doc="(N, 3) rest vertices, metres, Y up, +Z forward"),
        Column("faces", "rows", "int32", 3, doc="(M, 3) triangles, counter-clockwise seen from outside"),
        Column("keypoints", "rows", "float32", 3, doc="(K, 3) joint head positions at rest, metres"),
        Column("parents", "list", "int32", doc="(K,) parent index, -1 for roots, parents[k] < k"),
        Column("bone_names", "strings", doc="(K,) bone names as authored"),
        Column("weight_indices", "rows", "int32", MAX_INFLUENCES, doc="(N, 8) keypoint index of each influence; unused slots 0"),
        Column("weight_values", "rows", "float32", MAX_INFLUENCES, doc="(N, 8) skin weight of each influence; unused slots 0; rows sum to 1"),
        Column("apparel_vertex_mask", "list", "bool", doc="(N,) true for vertices driven by apparel bones"),
        Column("apparel_bone_mask", "list", "bool", doc="(K,) true for apparel bones (skirt, hair, cape chains)"),
        Column("bone_roles", "strings", nullable=True, doc="(K,) hidden semantic role per bone, e.g. `left/upper_arm`, `tail/3`, or a class such as `left/forelimb` (docs/roles.md); `\"\"` for a bone without a role; ground truth only, never a method input; null when no bone has one (ingested characters get roles from `datagen roles`)"),
        Column("skeleton_id", "scalar", "string", nullable=True, doc="characters with equal skeleton_id share bone names and parents exactly (the H2H family)"),
        Column("height", "scalar", "float32", nullable=True, doc="Y extent of the rest mesh, metres"),
        Column("meta", "json", nullable=True, doc="JSON object: provenance and per-stage reports (e.g. `resample`: faces in/out, Hausdorff %, transfer error %, `weld` when the resampled mesh had near-zero edges or zero-area faces to weld away, and `own_piece_vertices` when some resampled vertices lay closest to another mesh piece than the one they came from and took their weights from their own)"),
    )

    @property
    def weights(self) -> SparseWeights:
        """Skin weights as :class:`~mimicbench.schemas.weights.SparseWeights`."""
        return SparseWeights(np.asarray(self.weight_indices, np.int32), np.asarray(self.weight_values, np.float32),
                             int(len(self.parents)))

    @property
    def num_joints(self) -> int:
        return int(len(self.parents))
