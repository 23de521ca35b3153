"""BVH export of a clip, in the dataset frame (Y up, +Z forward, metres).

BVH joints have no rest orientation: a joint's OFFSET is its rest head minus its parent's, and
its rotation channels are its rotation relative to its parent, which is exactly the zoo's local
rest-relative rotation ``l_k = q_parent^-1 q_k``. Channels: the root has position then
``Zrotation Xrotation Yrotation`` (degrees, R = Rz Rx Ry), the others the three rotations. Leaf
joints end in an ``End Site`` at the bone tail. Blender's importer (defaults forward ``-Z``,
up ``Y``) maps a file point (x, y, z) to Blender (x, -z, y). BVH names are single tokens, so
spaces in bone names become ``_`` (see :func:`bvh_name`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mimicbench.geometry.kinematics import array_to_transforms, local_from_global
from mimicbench.geometry.quaternion import quat_to_matrix


def bvh_name(name: str) -> str:
    """A bone name as one BVH token (whitespace replaced by ``_``)."""
    return "_".join(name.split())


def matrix_to_euler_zxy(m: np.ndarray) -> np.ndarray:
    """Angles (..., 3) in radians (z, x, y) with ``m = Rz(z) Rx(x) Ry(y)`` for rotation matrices (..., 3, 3)."""
    x = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    z = np.arctan2(-m[..., 0, 1], m[..., 1, 1])
    y = np.arctan2(-m[..., 2, 0], m[..., 2, 2])
    return np.stack([z, x, y], axis=-1)


def euler_zxy_to_matrix(angles: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) ``Rz Rx Ry`` from angles (..., 3) (z, x, y) in radians."""
    z, x, y = np.moveaxis(np.asarray(angles, float), -1, 0)
    cz, sz, cx, sx, cy, sy = np.cos(z), np.sin(z), np.cos(x), np.sin(x), np.cos(y), np.sin(y)
    one, zero = np.ones_like(z), np.zeros_like(z)
    rz = np.stack([np.stack([cz, -sz, zero], -1), np.stack([sz, cz, zero], -1), np.stack([zero, zero, one], -1)], -2)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cx, -sx], -1), np.stack([zero, sx, cx], -1)], -2)
    ry = np.stack([np.stack([cy, zero, sy], -1), np.stack([zero, one, zero], -1), np.stack([-sy, zero, cy], -1)], -2)
    return rz @ rx @ ry


def write_bvh(path, names: list[str], parents: np.ndarray, rest_keypoints: np.ndarray, end_sites: np.ndarray,
              transforms: np.ndarray, fps: float) -> Path:
    """Write a clip as BVH.

    Args:
        names: K bone names (spaces become ``_``).
        parents: (K,) int, one root (-1 at index 0), ``parents[k] < k``.
        rest_keypoints: (K, 3) rest joint heads, metres.
        end_sites: (K, 3) bone tails, used for the End Site of leaf joints.
        transforms: (F, K, 7) stored transforms of the clip.
        fps: frames per second.
    """
    parents = np.asarray(parents)
    if (parents < 0).sum() != 1 or parents[0] != -1:
        raise ValueError(f"parents: BVH needs one root at index 0, got roots at {np.nonzero(parents < 0)[0].tolist()}")
    rest = np.asarray(rest_keypoints, np.float64)
    q, t = array_to_transforms(transforms)
    local = local_from_global(q, parents)
    euler = np.degrees(matrix_to_euler_zxy(quat_to_matrix(local)))  # (F, K, 3) z, x, y
    children: list[list[int]] = [[] for _ in parents]
    for k, p in enumerate(parents):
        if p >= 0:
            children[p].append(k)
    lines = ["HIERARCHY"]
    order: list[int] = []

    def emit(k: int, depth: int) -> None:
        ind = "  " * depth
        off = rest[k] - (rest[parents[k]] if parents[k] >= 0 else 0.0)
        lines.append(f"{ind}{'ROOT' if parents[k] < 0 else 'JOINT'} {bvh_name(names[k])}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}")
        if parents[k] < 0:
            lines.append(f"{ind}  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation")
        else:
            lines.append(f"{ind}  CHANNELS 3 Zrotation Xrotation Yrotation")
        order.append(k)
        for c in children[k]:
            emit(c, depth + 1)
        if not children[k]:
            e = np.asarray(end_sites[k], float) - rest[k]
            lines.extend([f"{ind}  End Site", f"{ind}  {{", f"{ind}    OFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}", f"{ind}  }}"])
        lines.append(f"{ind}}}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {len(euler)}", f"Frame Time: {1.0 / fps:.8f}"]
    for f in range(len(euler)):
        vals = list(t[f, 0])
        for k in order:
            vals += list(euler[f, k])
        lines.append(" ".join(f"{v:.6f}" for v in vals))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path
