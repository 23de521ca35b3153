"""Load a dataset's characters as :class:`Rig` objects, with the per-character data the
evaluator reuses across cases (unique edges).

Every array here is read-only (see :func:`mimicbench.benchmark.request.read_only`): the same rig serves many
cases and methods, so nothing may write into it.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mimicbench.benchmark.request import Rig, read_only
from mimicbench.geometry.mesh import unique_edges
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.dataset import Dataset


@dataclass
class CharacterData:
    """A character's rig plus derived data cached for scoring."""

    record: CharacterRecord

    @cached_property
    def rig(self) -> Rig:
        r = self.record
        return Rig(r.character_id, r.category, np.asarray(r.vertices, np.float32), np.asarray(r.faces, np.int32),
                   np.asarray(r.keypoints, np.float32), np.asarray(r.parents, np.int32), r.weights,
                   tuple(r.bone_names))

    @cached_property
    def edges(self) -> np.ndarray:
        """(E, 2) unique edges of the rest mesh (read-only)."""
        return read_only(unique_edges(self.record.faces))


def load_characters(dataset) -> dict[str, CharacterData]:
    """Every character with a mesh, by ID (skeleton-only sources such as BVH are left out)."""
    return {r.character_id: CharacterData(r) for r in Dataset.of(dataset).records("characters")
            if len(r.faces)}
