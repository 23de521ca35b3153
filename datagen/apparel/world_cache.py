"""One pybullet world per character, reused across its clips within a process.

Building a character's world (its chains' URDFs and hulls, body pieces, the rest-pose collision
exclusions) costs as much as simulating a short clip, and the stage simulates a character's clips
one after another. This keeps the last character's physics and world and hands them out again,
reset (:meth:`mimicbench.datagen.apparel.world.ApparelWorld.reset`), when the next clip is of the same
character with the same masks, parameters and physics step; a reset world gives the same bytes as
a new one, so the output does not depend on the order clips come in.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from mimicbench.datagen.apparel.params import ApparelParams
from mimicbench.datagen.apparel.setup import CharacterPhysics, character_physics
from mimicbench.datagen.apparel.world import ApparelWorld
from mimicbench.schemas.character import CharacterRecord

_cached: dict = {"key": None, "physics": None, "world": None}


def _key(record: CharacterRecord, bones: np.ndarray, vertices: np.ndarray, params: ApparelParams,
         dt: float) -> str:
    """Digest of everything a character's world is built from."""
    h = hashlib.blake2b(digest_size=16)
    h.update(record.character_id.encode())
    for a in (record.vertices, record.keypoints, record.parents, record.weight_indices, record.weight_values,
              bones, vertices):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.tobytes())
    h.update(json.dumps([record.bone_names, record.bone_roles, record.height, params.to_json(), float(dt)],
                        sort_keys=True, default=str).encode())
    return h.hexdigest()


def character_world(record: CharacterRecord, bones: np.ndarray, vertices: np.ndarray, params: ApparelParams,
                    dt: float) -> tuple[CharacterPhysics, ApparelWorld]:
    """The physics and a reset world of ``record`` with apparel ``bones`` (K,) and ``vertices`` (N,)
    bool, for physics step ``dt`` (s): the cached ones when the last call asked for the same."""
    key = _key(record, bones, vertices, params, dt)
    if _cached["key"] != key:
        close_cached_world()
        physics = character_physics(record, bones, vertices, params)
        world = ApparelWorld(record.keypoints, physics.pieces, physics.chains, params.simulation, dt)
        _cached.update(key=key, physics=physics, world=world)
    _cached["world"].reset()
    return _cached["physics"], _cached["world"]


def close_cached_world() -> None:
    """Disconnect the cached world, if any."""
    if _cached["world"] is not None:
        _cached["world"].close()
    _cached.update(key=None, physics=None, world=None)
