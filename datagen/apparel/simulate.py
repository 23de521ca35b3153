"""Simulate one clip through a physics world: the body follows the clip, apparel comes from the physics.

One loop for every world (:class:`PhysicsWorld`: the zoo's kinematic chains,
:class:`datagen.apparel.world.ApparelWorld`, and an MMD file's own bodies,
:class:`datagen.apparel.file_physics.FileWorld`). Each clip frame is split into ``substeps``
physics steps; within a frame the body pose is interpolated (slerp, lerp) from the previous
frame. The relaxation frames (:mod:`datagen.apparel.relax`) run first and are dropped. After each
frame the world's simulated parts are read and checked; the world turns them into bones at the end.
"""
from __future__ import annotations

from typing import Iterator, Protocol

import numpy as np

from datagen.apparel.relax import relax_frames, substep_poses
from mimicbench.kinematics import rest_transforms

CHUNK_FRAMES = 64  # frames whose substep poses are computed at once (memory: frames x substeps x bones)


class SimulationExploded(RuntimeError):
    """The simulation produced NaN or a link faster than the speed bound."""


class PhysicsWorld(Protocol):
    """A character's pybullet world as the clip loop drives it."""

    keypoints: np.ndarray  # (K, 3) rest bone heads, metres
    driven_bones: np.ndarray  # (D,) the bones whose poses the world reads
    max_speed: float  # m/s: a faster link is an explosion

    def place_at(self, pose: np.ndarray) -> None:
        """Teleport the simulated parts rigidly with their anchors to ``pose`` (K, 7), before the first step."""

    def start(self) -> None:
        """Ready the first step from the present state."""

    def follow(self, poses: np.ndarray, per_frame: int) -> Iterator[int]:
        """Place the body at each of ``poses`` (S, K, 7) and step; yield the frame every ``per_frame`` steps."""

    def read(self) -> tuple[tuple[np.ndarray, ...], float]:
        """The simulated parts' state now (arrays, checked for NaN) and the fastest link's speed (m/s)."""

    def clip_out(self, transforms: np.ndarray, states: list[tuple[np.ndarray, ...]]) -> np.ndarray:
        """(F, K, 7) float32: the kinematic clip ``transforms`` with the bones of ``states`` (one a frame) replaced."""


def simulate_clip(world: PhysicsWorld, transforms: np.ndarray, substeps: int, relax: int) -> np.ndarray:
    """The clip with apparel bones simulated.

    Args:
        world: a new or reset world of the clip's character (at rest).
        transforms: (F, K, 7) kinematic clip. substeps: physics steps per clip frame (>= 1).
        relax: relaxation frames before frame 0 (simulated, dropped).

    Returns:
        (F, K, 7) float32: body rows equal to ``transforms``, apparel rows from the simulation.

    Raises:
        SimulationExploded: NaN in the world's state or a link faster than ``world.max_speed``.
    """
    clip = np.asarray(transforms, np.float64)
    lead = relax_frames(world.keypoints, clip[0], relax)
    poses = np.concatenate([lead, clip]) if len(lead) else clip
    previous = rest_transforms(world.keypoints).astype(np.float64) if len(lead) else clip[0]
    if not len(lead):
        world.place_at(clip[0])
    world.start()
    states, driven = [], world.driven_bones  # only bones the world reads
    for first in range(0, len(poses), CHUNK_FRAMES):
        chunk = poses[first:first + CHUNK_FRAMES, driven]
        steps = np.zeros((len(chunk) * substeps, len(world.keypoints), 7))
        steps[:, driven] = substep_poses(previous[driven], chunk, substeps)
        previous = poses[first + len(chunk) - 1]
        for f in world.follow(steps, substeps):
            f += first
            where = f"relaxation frame {f + 1} of {len(lead)}" if f < len(lead) else f"frame {f - len(lead)}"
            state, speed = world.read()
            if not (all(np.isfinite(a).all() for a in state) and np.isfinite(speed)):
                raise SimulationExploded(f"NaN in the simulation at {where}")
            if speed > world.max_speed:
                raise SimulationExploded(f"a link reached {speed:.1f} m/s at {where} (bound {world.max_speed:g} m/s)")
            if f >= len(lead):
                states.append(state)
    return world.clip_out(transforms, states)
