"""The physics set-up of one character (body pieces and chains) and one clip simulated with it."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from datagen.apparel.body_shapes import BodyPiece, body_pieces
from datagen.apparel.chain_spec import ChainSpec
from datagen.apparel.chains import build_chains
from datagen.apparel.params import ApparelParams
from datagen.apparel.quality import clip_quality
from datagen.apparel.selection import dominant_bone
from datagen.apparel.simulate import SimulatedClip, simulate_clip
from datagen.apparel.world import ApparelWorld
from schemas.character import CharacterRecord
from schemas.motion import SIM_SUFFIX, MotionRecord

SIM_VERSION = "14"  # 2: gravity 9.8 m/s^2; 3: root capsules moved clear of the body at rest;
# 4: links collide as their vertices' hulls, contact ERP 0.5, joint speed bound; 5: joint limits
# projected every step, constraint ERP 0.8; 6: springs as implicit torques from numpy instead of
# Bullet's joint motors; 7: springs solved per tree of links (a merged multibody's chains
# apart), which rounds differently; 8: the per-step joint arithmetic compiled (joint_kernel),
# its sums in a fixed order (numpy's einsum summed in SIMD lanes), which rounds differently;
# 9: a link's axial inertia as large as its transverse one but for skirt strips (contacts no
# longer spin thin hair links past the twist limit and into the body, issue 33); 10: skirt
# strips' root links touch the body through a critically damped contact spring of 150 rad/s
# (a thigh, placed anew each step, started it up to 55 mm inside a rigid root contact, which threw
# the strip out in one step: tips at +-5-10 m/s alternating step by step), and skirt strips take
# axial inertia 1 like the other kinds (their 0.1 rad twist limit, projected, spun them otherwise);
# 11: chains that escape the speed bound are re-settled at rest on their anchors, up to
# SimParams.max_resettles frames a clip, instead of failing the clip (clips without an escape: the
# same bytes as 10); the quality gains resettles and resettled_frames; 12: the springs' implicit step
# takes each tree's mass matrix at the joints' present rotations (at rest it overshot a folded
# chain's light modes), every link below a chain's root but a skirt strip's touches the body
# through the critically damped contact spring of 150 rad/s with a 3 mm shell (a hair strand in
# the crevice of neck, shoulder and back took rigid impulses of 150-400 N and whipped its tip),
# and the spring damping of capes, coat tails, skirts and the default kind is 0.6 (issue 33); 13: body
# pieces carry their limb's speed (SimParams.piece_velocity: each starts a step where the last one ended
# with the speed that takes it to its pose), so a contact spring's damping acts on a link's speed against
# the limb, not in the world: an arm sweeping round in a spin struck the cape it carried (seed-711
# dynamic zoo: spins above 3x their kinematic peak 16 of 40 -> 0, their worst frame 2.40 -> 1.08 % of
# apparel vertices inside; jumps 1 -> 3, skirt strips struck by the thighs at landing, as high at 4x
# the physics rate); 14: a skirt strip's or coat tail's root link collides only with the part of its hull beyond 30 %
# of its length from the hip pivot (ChainParams.root_hull_from: a thigh pressing next to the pivot,
# where no turn clears it, fought the twist limit and whipped the strip: seed 0's random poses 117.7 ->
# 14.3 m/s^2), and chains and body pieces collide only when each one's group is in the other's mask
# (collide_body false used to have no effect)


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
    (:mod:`datagen.apparel.world_cache`); None builds one for this clip.

    Raises:
        datagen.apparel.simulate.SimulationExploded: the simulation blew up (past
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
    motion ``<clip>@sim`` and its quality (:func:`~datagen.apparel.quality.clip_quality`, then
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
