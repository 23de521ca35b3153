"""Known corruptions of a right transfer, for the validity probes.

Class maps (which source part drives a target part) and pose edits on the target's global
rotations (Kt, 4), quaternions (w, x, y, z), bones ordered parents first.
"""
from __future__ import annotations

import zlib

import numpy as np

from mimicbench.geometry.kinematics import forward_kinematics, local_from_global
from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_identity, quat_multiply, quat_slerp

LIMB_CLASSES = ("left/forelimb", "right/forelimb", "left/hindlimb", "right/hindlimb")
"""The classes :func:`frozen_part` picks from, in order."""


def swap_sides(cls: str) -> str:
    """``left/x`` <-> ``right/x``; an unsided class is itself."""
    side, _, base = cls.partition("/")
    return {"left": f"right/{base}", "right": f"left/{base}"}.get(side, cls) if base else cls


def swap_fore_hind(cls: str) -> str:
    """``[side/]forelimb`` <-> ``[side/]hindlimb``; any other class is itself."""
    head, _, base = cls.rpartition("/")
    other = {"forelimb": "hindlimb", "hindlimb": "forelimb"}.get(base)
    return cls if other is None else (f"{head}/{other}" if head else other)


def frozen_part(classes: list) -> str | None:
    """The limb class :func:`freeze` holds still: the first of :data:`LIMB_CLASSES` the skeleton has."""
    present = set(classes)
    return next((c for c in LIMB_CLASSES if c in present), None)


def _global_from_local(local: np.ndarray, parents: np.ndarray) -> np.ndarray:
    zeros = np.zeros((len(parents), 3))
    rotations, _ = forward_kinematics(local, zeros, parents, zeros)
    return rotations


def freeze(global_rotations: np.ndarray, parents, classes: list, part: str | None) -> np.ndarray:
    """Bones of class ``part`` keep their rest rotation relative to their parent (Kt, 4)."""
    parents = np.asarray(parents)
    local = local_from_global(global_rotations, parents)
    local[[c == part for c in classes]] = quat_identity()
    return _global_from_local(local, parents)


def rotation_noise(global_rotations: np.ndarray, parents, degrees: float, key: str) -> np.ndarray:
    """Every bone's rotation relative to its parent turned by ``degrees`` about a random axis (Kt, 4);
    the axes come from a generator seeded by ``key`` (e.g. the case ID), so a case is reproducible."""
    parents = np.asarray(parents)
    rng = np.random.default_rng(zlib.crc32(key.encode()))
    axes = rng.normal(size=(len(parents), 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    turn = quat_from_axis_angle(axes, np.full(len(parents), np.radians(degrees)))
    return _global_from_local(quat_multiply(local_from_global(global_rotations, parents), turn), parents)


def half_angle(global_rotations: np.ndarray, parents) -> np.ndarray:
    """Every bone's rotation relative to its parent halved (slerp halfway to rest) (Kt, 4)."""
    parents = np.asarray(parents)
    local = local_from_global(global_rotations, parents)
    return _global_from_local(quat_slerp(quat_identity(local.shape[:-1]), local, 0.5), parents)
