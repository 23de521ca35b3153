"""MMD's frame to the dataset's: MMD is left-handed, Y up, the model facing -Z, in MMD units;
the dataset is right-handed, Y up, +Z forward, metres. Mirroring z does both (the model then
faces +Z and its left side stays at +X), and one MMD unit is 0.08 m (mmd_tools' and Saba's scale;
override with ``scale``).

A rotation R in MMD's frame becomes M R M with M = diag(1, 1, -1): a quaternion (w, x, y, z)
becomes (w, -x, -y, z); Euler angles (rx, ry, rz) become (-rx, -ry, rz) in the same order; an
interval [lo, hi] of a negated coordinate or angle becomes [-hi, -lo].
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_multiply

MMD_UNIT_METRES = 0.08
MIRROR = np.array([1.0, 1.0, -1.0])
ANGLE_MIRROR = np.array([-1.0, -1.0, 1.0])


def point(p: np.ndarray, scale: float = MMD_UNIT_METRES) -> np.ndarray:
    """Positions (..., 3) in MMD units and frame -> metres in the dataset frame."""
    return np.asarray(p, np.float64) * MIRROR * scale


def direction(d: np.ndarray) -> np.ndarray:
    """Directions or axes (..., 3) (no scale)."""
    return np.asarray(d, np.float64) * MIRROR


def quat(q_wxyz: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) (w, x, y, z) in MMD's frame -> the dataset frame."""
    return np.asarray(q_wxyz, np.float64) * np.array([1.0, -1.0, -1.0, 1.0])


def euler(e: np.ndarray) -> np.ndarray:
    """MMD Euler angles (..., 3) radians -> the same order's angles in the dataset frame."""
    return np.asarray(e, np.float64) * ANGLE_MIRROR


def interval(lo: np.ndarray, hi: np.ndarray, flip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis limits [lo, hi] (3,) -> limits after multiplying axis i by ``flip[i]`` (+-1): a
    negated axis swaps and negates its bounds."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    neg = np.asarray(flip) < 0
    return np.where(neg, -hi, lo), np.where(neg, -lo, hi)


def euler_yxz_to_quat(e: np.ndarray) -> np.ndarray:
    """MMD's rigid-body/joint Euler angles (..., 3) (rx, ry, rz) radians -> quaternion (..., 4)
    (w, x, y, z) of R = Ry(ry) Rx(rx) Rz(rz), Z applied first, as MMD players build it (Saba's
    ``ry * rx * rz``). Valid in either frame (mirror the angles with :func:`euler` first)."""
    e = np.asarray(e, np.float64)
    ex = quat_from_axis_angle(np.broadcast_to([1.0, 0, 0], e.shape), e[..., 0])
    ey = quat_from_axis_angle(np.broadcast_to([0, 1.0, 0], e.shape), e[..., 1])
    ez = quat_from_axis_angle(np.broadcast_to([0, 0, 1.0], e.shape), e[..., 2])
    return quat_multiply(quat_multiply(ey, ex), ez)
