"""Simulate one clip: the body follows the clip, apparel bones come from the physics.

Each clip frame is split into ``substeps`` physics steps; within a frame the body pose is
interpolated (slerp, lerp) from the previous frame. The relaxation frames
(:mod:`datagen.apparel.relax`) run first and are dropped. After each frame the apparel bones'
transforms are read from the chains' link frames (their rest-relative world rotation and head
position); body bones keep the clip's transforms exactly.
"""
from __future__ import annotations

import numpy as np

from datagen.apparel.relax import relax_frames, substep_poses
from datagen.apparel.world import ApparelWorld
from mimicbench.kinematics import rest_transforms


CHUNK_FRAMES = 64  # frames whose substep poses are computed at once (memory: frames x substeps x bones)


class SimulationExploded(RuntimeError):
    """The simulation produced NaN or a link faster than the speed bound."""


def simulate_clip(world: ApparelWorld, transforms: np.ndarray, substeps: int, relax: int) -> np.ndarray:
    """The clip with apparel bones simulated.

    Args:
        world: a new or reset world of the clip's character (chains at rest).
        transforms: (F, K, 7) kinematic clip.
        substeps: physics steps per clip frame (>= 1).
        relax: relaxation frames before frame 0 (simulated, dropped).

    Returns:
        (F, K, 7) float32: body rows equal to ``transforms``, apparel rows from the simulation.

    Raises:
        SimulationExploded: NaN in a link state or a link faster than ``world.sim.max_speed``.
    """
    clip = np.asarray(transforms, np.float64)
    bones = np.array([b for c in world.chains for b in c.spec.bones], int)
    lead = relax_frames(world.keypoints, clip[0], relax)
    poses = np.concatenate([lead, clip]) if len(lead) else clip
    out = np.array(transforms, np.float32, copy=True)
    previous = rest_transforms(world.keypoints).astype(np.float64) if len(lead) else clip[0]
    if not len(lead):
        world.place_chains_at(clip[0])
    world.start()
    def where(f: int) -> str:
        return f"relaxation frame {f + 1} of {len(lead)}" if f < len(lead) else f"frame {f - len(lead)}"

    driven = world.driven_bones  # only bones the world reads
    rotations = np.zeros((len(poses), len(bones), 4))  # links' world orientations per frame (w, x, y, z)
    positions = np.zeros((len(poses), len(bones), 3))  # and their heads
    for first in range(0, len(poses), CHUNK_FRAMES):
        chunk = poses[first:first + CHUNK_FRAMES, driven]
        steps = np.zeros((len(chunk) * substeps, len(world.keypoints), 7))
        steps[:, driven] = substep_poses(previous[driven], chunk, substeps)
        previous = poses[first + len(chunk) - 1]
        for f in world.follow(steps, substeps):
            f += first
            rotations[f], positions[f], speed = world.link_states()
            if not (np.isfinite(rotations[f]).all() and np.isfinite(positions[f]).all() and np.isfinite(speed)):
                raise SimulationExploded(f"NaN in the simulation at {where(f)}")
            if speed > world.sim.max_speed:
                raise SimulationExploded(f"a link reached {speed:.1f} m/s at {where(f)} "
                                         f"(bound {world.sim.max_speed:g} m/s)")
    if len(bones):
        out[:, bones, :4] = world.rest_relative(rotations[len(lead):])
        out[:, bones, 4:] = positions[len(lead):]
    return out
