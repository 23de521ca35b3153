"""MMD's IK: cyclic coordinate descent as MMD players do it (Saba's ``MMDIkSolver``), on all
frames at once.

For an IK bone (the goal, e.g. 左足ＩＫ) with target bone (the effector, e.g. 左足首) and links
(e.g. 左ひざ, 左足), repeat up to the file's loop count: for each link, turn it so that the
effector points at the goal as seen from the link, by at most the file's unit angle; a link
limited to one axis (the knee: x only) turns about that axis only, its accumulated angle clamped
to the limits (on the first iteration a wrong-signed angle is flipped, which bends knees forward);
other limited links are clamped per Euler angle (R = Rx Ry Rz). A frame stops when its distance
stops shrinking, keeping its best rotations.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import IDENTITY, quat_conjugate, quat_multiply, quat_to_matrix

AXES = np.eye(3)


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (F, 4) turning ``angle`` (F,) radians about unit axes (3,) or (F, 3)."""
    half = 0.5 * np.asarray(angle, np.float64)
    axis = np.broadcast_to(axis, half.shape + (3,))
    return np.concatenate([np.cos(half)[:, None], axis * np.sin(half)[:, None]], axis=1)


def unrotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R^T v for rotations (F, 3, 3) and vectors (F, 3)."""
    return np.einsum("fji,fj->fi", R, v)


def _rodrigues(v: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Vectors v (F, 3) turned by ``angle`` (F,) about the unit ``axis`` (3,)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * (v @ axis)[:, None] * (1 - c)


def _plane_axis(lo: np.ndarray, hi: np.ndarray) -> int | None:
    """The one axis a link turns about when only that axis has limits (Saba's plane mode)."""
    for a in range(3):
        others = [b for b in range(3) if b != a]
        if (lo[a] != 0 or hi[a] != 0) and all(lo[b] == 0 or hi[b] == 0 for b in others):
            return a
    return None


def euler_xyz(m: np.ndarray) -> np.ndarray:
    """Angles (..., 3) (a, b, c) with m = Rx(a) Ry(b) Rz(c), for rotations m (..., 3, 3)."""
    b = np.arcsin(np.clip(m[..., 0, 2], -1.0, 1.0))
    return np.stack([np.arctan2(-m[..., 1, 2], m[..., 2, 2]), b, np.arctan2(-m[..., 0, 1], m[..., 0, 0])], axis=-1)


def euler_xyz_to_quat(e: np.ndarray) -> np.ndarray:
    """Quaternions (F, 4) of Rx(a) Ry(b) Rz(c) for angles (F, 3)."""
    q = np.broadcast_to(IDENTITY, e.shape[:-1] + (4,))
    for a in range(3):
        q = quat_multiply(q, axis_angle(AXES[a], e[..., a]))
    return q


def solve_ik(poser, ik_bone: int) -> None:
    """Run CCD for ``ik_bone``'s chain on every frame, writing the links' ``poser.ik_rot``."""
    chain = poser.model.bones[ik_bone].ik
    target, links = chain.target, chain.links
    f = poser.t.shape[0]
    for link in links:
        poser.ik_rot[:, link.bone] = IDENTITY
        poser.update_local(link.bone)
        poser.update_global(link.bone)
    plane_angle = np.zeros((f, len(links)))
    best = np.full(f, np.inf)
    saved = [poser.ik_rot[:, link.bone].copy() for link in links]
    active = np.ones(f, bool)
    for it in range(chain.loop):
        if not active.any():
            break
        _iterate(poser, ik_bone, chain, target, plane_angle, it, active)
        dist = np.linalg.norm(poser.t[:, target] - poser.t[:, ik_bone], axis=1)
        improved = active & (dist < best)
        best = np.where(improved, dist, best)
        stop = active & ~improved
        for n, link in enumerate(links):
            saved[n] = np.where(improved[:, None], poser.ik_rot[:, link.bone], saved[n])
            if stop.any():  # frames that stopped improving go back to their best rotations
                poser.ik_rot[stop, link.bone] = saved[n][stop]
                poser.update_local(link.bone)
        active = improved
    for link in reversed(links):  # links run from the effector up: refresh from the top link down
        poser.update_global(link.bone)


def _iterate(poser, ik_bone: int, chain, target: int, plane_angle: np.ndarray, it: int, active: np.ndarray) -> None:
    goal = poser.t[:, ik_bone].copy()
    for li, link in enumerate(chain.links):
        j = link.bone
        if j == target:
            continue
        R, t = poser.R[:, j], poser.t[:, j]
        to_goal = unrotate(R, goal - t)
        to_eff = unrotate(R, poser.t[:, target] - t)
        ng, ne = np.linalg.norm(to_goal, axis=1), np.linalg.norm(to_eff, axis=1)
        valid = active & (ng > 1e-12) & (ne > 1e-12)
        to_goal = to_goal / np.maximum(ng, 1e-12)[:, None]
        to_eff = to_eff / np.maximum(ne, 1e-12)[:, None]
        angle = np.arccos(np.clip(np.sum(to_eff * to_goal, axis=1), -1.0, 1.0))
        limited = link.limit_min is not None
        axis_i = _plane_axis(link.limit_min, link.limit_max) if limited else None
        if axis_i is not None:
            angle = np.minimum(angle, chain.limit_angle)
            axis = AXES[axis_i]
            d1 = np.sum(_rodrigues(to_eff, axis, angle) * to_goal, axis=1)
            d2 = np.sum(_rodrigues(to_eff, axis, -angle) * to_goal, axis=1)
            new = plane_angle[:, li] + np.where(d1 > d2, angle, -angle)
            lo, hi = float(link.limit_min[axis_i]), float(link.limit_max[axis_i])
            if it == 0:
                out = (new < lo) | (new > hi)
                flip = out & (lo < -new) & (-new < hi)
                mid = 0.5 * (lo + hi)
                flip |= out & ~flip & (np.abs(mid - new) > np.abs(mid + new))
                new = np.where(flip, -new, new)
            new = np.clip(new, lo, hi)
            plane_angle[:, li] = np.where(valid, new, plane_angle[:, li])
            ik = quat_multiply(axis_angle(axis, new), quat_conjugate(poser.anim_rot[:, j]))
        else:
            valid &= np.degrees(angle) >= 1e-3
            angle = np.minimum(angle, chain.limit_angle)
            cross = np.cross(to_eff, to_goal)
            n = np.linalg.norm(cross, axis=1)
            valid &= n > 1e-12
            rot = axis_angle(cross / np.maximum(n, 1e-12)[:, None], angle)
            full = quat_multiply(quat_multiply(poser.ik_rot[:, j], poser.anim_rot[:, j]), rot)
            if limited:
                e = np.clip(euler_xyz(quat_to_matrix(full)), link.limit_min, link.limit_max)
                full = euler_xyz_to_quat(e)
            ik = quat_multiply(full, quat_conjugate(poser.anim_rot[:, j]))
        if not valid.any():
            continue
        ik = ik / np.linalg.norm(ik, axis=1, keepdims=True)
        poser.ik_rot[:, j] = np.where(valid[:, None], ik, poser.ik_rot[:, j])
        poser.update_local(j)
        poser.update_chain(j, target)
