"""The physics set-up of one character (body pieces and chains) and one clip simulated with it."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mimicbench.datagen.apparel.body_shapes import BodyPiece, body_pieces
from mimicbench.datagen.apparel.chain_spec import ChainSpec
from mimicbench.datagen.apparel.chains import build_chains
from mimicbench.datagen.apparel.params import ApparelParams
from mimicbench.datagen.apparel.quality import clip_quality
from mimicbench.datagen.apparel.selection import dominant_bone
from mimicbench.datagen.apparel.simulate import SimulatedClip, simulate_clip
from mimicbench.datagen.apparel.world import ApparelWorld
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.motion import SIM_SUFFIX, MotionRecord

SIM_VERSION = "15"  # recorded in each simulated clip; CHANGELOG.md says what each version changed


@dataclass
class CharacterPhysics:
    """What the simulation of a character needs: body pieces, chains, masks (bone and vertex)."""

    pieces: list[BodyPiece]
    chains: list[ChainSpec]
    apparel_bones: np.ndarray
    apparel_vertices: np.ndarray


def character_physics(record: CharacterRecord, apparel_bones: np.ndarray, apparel_vertices: np.ndarray,
                      params: ApparelParams) -> CharacterPhysics:
    """Body pieces of the non-apparel bones and the chains of ``apparel_bones`` (K,) bool."""
    owner = dominant_bone(record.weights, record.num_joints)
    height = float(record.height or np.ptp(np.asarray(record.vertices)[:, 1]))
    pieces = body_pieces(record.vertices, record.keypoints, owner, ~np.asarray(apparel_bones, bool))
    chains = build_chains(record.keypoints, record.parents, record.bone_names, record.bone_roles, record.vertices,
                          owner, apparel_bones, params, height)
    return CharacterPhysics(pieces, chains, np.asarray(apparel_bones, bool), np.asarray(apparel_vertices, bool))


def substeps_for(physics_fps: float, clip_fps: float) -> int:
    """Physics steps per clip frame: ``physics_fps / clip_fps`` rounded up, at least 1."""
    return max(1, math.ceil(physics_fps / clip_fps - 1e-9))


def physics_step(physics_fps: float, clip_fps: float) -> float:
    """The physics step (s) of a clip at ``clip_fps``: a frame split into :func:`substeps_for` steps."""
    return 1.0 / (clip_fps * substeps_for(physics_fps, clip_fps))


def simulate_motion(record: CharacterRecord, physics: CharacterPhysics, motion: MotionRecord, params: ApparelParams,
                    physics_fps: float, relax: int, world: ApparelWorld | None = None) -> tuple[MotionRecord, dict]:
    """The simulated clip of ``motion`` as a new motion ``<clip>@sim``, and its quality.

    ``world``: a world of ``physics`` with step :func:`physics_step`, as built or reset
    (:mod:`mimicbench.datagen.apparel.world_cache`); None builds one for this clip.

    Raises:
        mimicbench.datagen.apparel.simulate.SimulationExploded: the simulation blew up (past
            ``params.simulation.max_resettles`` re-settles).
    """
    steps, limit = substeps_for(physics_fps, motion.fps), params.simulation.max_resettles
    if world is None:
        with ApparelWorld(record.keypoints, physics.pieces, physics.chains, params.simulation,
                          physics_step(physics_fps, motion.fps)) as world:
            simulated = simulate_clip(world, motion.transforms, steps, relax, limit)
    else:
        simulated = simulate_clip(world, motion.transforms, steps, relax, limit)
    return simulated_record(record, physics, motion, simulated, f"apparel:pybullet@{SIM_VERSION}", {
        "substeps": steps, "relax_frames": int(relax), "links": sum(len(c.links) for c in physics.chains),
        "chains": len(physics.chains)})


def simulated_record(record: CharacterRecord, physics: CharacterPhysics, motion: MotionRecord, clip: SimulatedClip,
                     source: str, counts: dict) -> tuple[MotionRecord, dict]:
    """``clip`` (its transforms (F, K, 7)), the clip of ``motion`` from the physics ``source``, as the
    motion ``<clip>@sim`` and its quality (:func:`~mimicbench.datagen.apparel.quality.clip_quality`, then
    ``counts``, then ``resettles`` and ``resettled_frames``)."""
    height = float(record.height or np.ptp(np.asarray(record.vertices)[:, 1]))
    simulated = clip.transforms
    quality = clip_quality(record.vertices, record.faces, record.keypoints, record.weights, physics.apparel_vertices,
                           physics.pieces, simulated, motion.transforms, motion.fps, height)
    quality.update(counts)
    quality.update(resettles=len(clip.resettled_frames), resettled_frames=[int(f) for f in clip.resettled_frames])
    sim = MotionRecord(motion_id=motion.motion_id + SIM_SUFFIX, character_id=motion.character_id,
                       name=motion.name + SIM_SUFFIX, split=motion.split, fps=motion.fps, num_frames=motion.num_frames,
                       num_joints=motion.num_joints, transforms=simulated, source=f"{source} from {motion.motion_id}")
    return sim, quality
