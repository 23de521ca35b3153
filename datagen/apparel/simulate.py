"""Simulate one clip through a physics world: the body follows the clip, apparel comes from the physics.

One loop for every world (:class:`PhysicsWorld`: the zoo's kinematic chains,
:class:`mimicbench.datagen.apparel.world.ApparelWorld`, and an MMD file's own bodies,
:class:`mimicbench.datagen.apparel.file_physics.FileWorld`). Each clip frame is split into ``substeps``
physics steps; within a frame the body pose is interpolated (slerp, lerp) from the previous
frame. The relaxation frames run first and are dropped: either the body blends from the rest
pose into the clip's first pose (:mod:`mimicbench.datagen.apparel.relax`), or, with ``warmup``, the world is
reset at the clip's first pose (its chains placed there, stepped once, every velocity zeroed: MMD
players' reset) and the body holds that pose for the relaxation frames (their warm-up). After each
frame the world's simulated parts are read and checked; the world turns them into bones at the end.

Re-settling: when after a frame some chain has a link faster than the world's speed bound (or a
non-finite state), the world puts only those chains back at rest on their anchors at the frame's
body pose (:meth:`PhysicsWorld.resettle`), the state is read again and the clip goes on; each such
frame is one re-settle. Past ``max_resettles`` re-settles, or when the state is still bad right
after one, the clip raises :class:`SimulationExploded`. A clip without an escape runs exactly as
without re-settling.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Protocol

import numpy as np

from mimicbench.datagen.apparel.params import SimParams
from mimicbench.datagen.apparel.relax import relax_frames, substep_poses
from mimicbench.geometry.kinematics import rest_transforms

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

    def reset(self, pose: np.ndarray) -> None:
        """Only for ``warmup``: place the simulated parts at ``pose`` (K, 7) at rest on their anchors,
        step once and zero every velocity."""

    def resettle(self, pose: np.ndarray) -> int:
        """Put each chain with a link faster than ``max_speed`` or a non-finite state back at rest on its
        anchor at body pose ``pose`` (K, 7) (rest joint angles, every velocity zero); the count of chains."""

    def clip_out(self, transforms: np.ndarray, states: list[tuple[np.ndarray, ...]]) -> np.ndarray:
        """(F, K, 7) float32: the kinematic clip ``transforms`` with the bones of ``states`` (one a frame) replaced."""


@dataclass
class SimulatedClip:
    """A clip simulated by :func:`simulate_clip`: its transforms and the frames where chains were re-settled."""

    transforms: np.ndarray  # (F, K, 7) float32
    resettled_frames: list[int]  # clip frame indices, ascending; relaxation frames negative (-1 the last)


def _sound(state: tuple[np.ndarray, ...], speed: float, bound: float) -> bool:
    """Whether a read state is finite and its fastest link (m/s) within ``bound`` (m/s)."""
    return all(np.isfinite(a).all() for a in state) and np.isfinite(speed) and speed <= bound


def _escape(state: tuple[np.ndarray, ...], speed: float, bound: float, where: str) -> str:
    """What went wrong at ``where``: NaN in ``state`` or a link faster than ``bound`` (m/s)."""
    if not (all(np.isfinite(a).all() for a in state) and np.isfinite(speed)):
        return f"NaN in the simulation at {where}"
    return f"a link reached {speed:.1f} m/s at {where} (bound {bound:g} m/s)"


def simulate_clip(world: PhysicsWorld, transforms: np.ndarray, substeps: int, relax: int,
                  max_resettles: int = SimParams.max_resettles, warmup: bool = False) -> SimulatedClip:
    """The clip with apparel bones simulated.

    Args:
        world: a new or reset world of the clip's character (at rest).
        transforms: (F, K, 7) kinematic clip. substeps: physics steps per clip frame (>= 1).
        relax: relaxation frames before frame 0 (simulated, dropped).
        max_resettles: frames whose escaped chains may be re-settled (module docstring); 0 raises at
            the first escape.
        warmup: reset the world at the clip's first pose and hold it for the ``relax`` frames,
            instead of blending from the rest pose (module docstring).

    Returns:
        The clip (F, K, 7) float32 (body rows equal to ``transforms``, apparel rows from the
        simulation) and the re-settled frames.

    Raises:
        SimulationExploded: NaN in the world's state or a link faster than ``world.max_speed``
            after ``max_resettles`` re-settles, or right after a re-settle.
    """
    clip = np.asarray(transforms, np.float64)
    if warmup:
        lead = np.repeat(clip[:1], int(relax), axis=0)
        world.reset(clip[0])
    else:
        lead = relax_frames(world.keypoints, clip[0], relax)
    poses = np.concatenate([lead, clip]) if len(lead) else clip
    previous = rest_transforms(world.keypoints).astype(np.float64) if len(lead) and not warmup else clip[0]
    if not len(lead) and not warmup:
        world.place_at(clip[0])
    world.start()
    states, resettled, driven = [], [], world.driven_bones  # only bones the world reads
    for first in range(0, len(poses), CHUNK_FRAMES):
        chunk = poses[first:first + CHUNK_FRAMES, driven]
        steps = np.zeros((len(chunk) * substeps, len(world.keypoints), 7))
        steps[:, driven] = substep_poses(previous[driven], chunk, substeps)
        previous = poses[first + len(chunk) - 1]
        for f in world.follow(steps, substeps):
            f += first
            where = f"relaxation frame {f + 1} of {len(lead)}" if f < len(lead) else f"frame {f - len(lead)}"
            state, speed = world.read()
            if not _sound(state, speed, world.max_speed):
                limit = f"(max_resettles {max_resettles})"
                if len(resettled) >= max_resettles:
                    raise SimulationExploded(_escape(state, speed, world.max_speed, where)
                                             + (f" after {len(resettled)} re-settles {limit}" if max_resettles else ""))
                world.resettle(poses[f])
                state, speed = world.read()
                if not _sound(state, speed, world.max_speed):
                    raise SimulationExploded(_escape(state, speed, world.max_speed, where) + f" right after "
                                             f"re-settling its chains, {len(resettled)} re-settles before {limit}")
                resettled.append(f - len(lead))
            if f >= len(lead):
                states.append(state)
    return SimulatedClip(world.clip_out(transforms, states), resettled)
