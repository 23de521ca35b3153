"""MMD's IK: cyclic coordinate descent as MMD players do it (Saba's ``MMDIkSolver``).

For an IK bone (the goal, e.g. 左足ＩＫ) with target bone (the effector, e.g. 左足首) and links
(e.g. 左ひざ, 左足), repeat up to the file's loop count: for each link, turn it so that the
effector points at the goal as seen from the link, by at most the file's unit angle; a link
limited to one axis (the knee: x only) turns about that axis only, its accumulated angle clamped
to the limits (on the first iteration a wrong-signed angle is flipped, which bends knees forward);
other limited links are clamped per Euler angle (R = Rx Ry Rz). The loop stops when the distance
stops shrinking, keeping the best rotations.
"""
from __future__ import annotations

import math

import numpy as np

from datagen.mmd.pose import IDENTITY, qmul, quat_to_mat

AXES = np.eye(3)


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (w, x, y, z) turning ``angle`` radians about the unit ``axis`` (3,)."""
    s = math.sin(0.5 * angle)
    return np.array([math.cos(0.5 * angle), axis[0] * s, axis[1] * s, axis[2] * s])


def conj(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _plane_axis(lo: np.ndarray, hi: np.ndarray) -> int | None:
    """The one axis a link turns about when only that axis has limits (Saba's plane mode)."""
    for a in range(3):
        others = [b for b in range(3) if b != a]
        if (lo[a] != 0 or hi[a] != 0) and all(lo[b] == 0 or hi[b] == 0 for b in others):
            return a
    return None


def euler_xyz(m: np.ndarray) -> np.ndarray:
    """Angles (a, b, c) with m = Rx(a) Ry(b) Rz(c)."""
    b = np.arcsin(np.clip(m[0, 2], -1.0, 1.0))
    return np.array([np.arctan2(-m[1, 2], m[2, 2]), b, np.arctan2(-m[0, 1], m[0, 0])])


def euler_xyz_to_quat(e: np.ndarray) -> np.ndarray:
    q = IDENTITY
    for a in range(3):
        q = qmul(q, axis_angle(AXES[a], e[a]))
    return q


def solve_ik(poser, ik_bone: int) -> None:
    """Run CCD for ``ik_bone``'s chain, writing the links' ``poser.ik_rot`` (and their globals)."""
    chain = poser.model.bones[ik_bone].ik
    target = chain.target
    links = chain.links
    plane_angle = np.zeros(len(links))
    for link in links:
        poser.ik_rot[link.bone] = IDENTITY
        poser.update_local(link.bone)
        poser.update_global(link.bone)
    best = np.inf
    saved = [poser.ik_rot[l.bone].copy() for l in links]
    for it in range(chain.loop):
        _iterate(poser, ik_bone, chain, target, plane_angle, it)
        d = poser.t[target] - poser.t[ik_bone]
        dist = math.sqrt(d @ d)
        if dist < best:
            best = dist
            saved = [poser.ik_rot[l.bone].copy() for l in links]
        else:
            for l, q in zip(links, saved):
                poser.ik_rot[l.bone] = q
                poser.update_local(l.bone)
            break
    for l in reversed(links):  # links run from the effector up: refresh from the top link down
        poser.update_global(l.bone)


def _iterate(poser, ik_bone: int, chain, target: int, plane_angle: np.ndarray, it: int) -> None:
    goal = poser.t[ik_bone].copy()
    for li, link in enumerate(chain.links):
        j = link.bone
        if j == target:
            continue
        R, t = poser.R[j], poser.t[j]
        to_goal = R.T @ (goal - t)
        to_eff = R.T @ (poser.t[target] - t)
        ng, ne = math.sqrt(to_goal @ to_goal), math.sqrt(to_eff @ to_eff)
        if ng < 1e-12 or ne < 1e-12:
            continue
        to_goal, to_eff = to_goal / ng, to_eff / ne
        angle = math.acos(min(1.0, max(-1.0, float(to_eff @ to_goal))))
        limited = link.limit_min is not None
        axis_i = _plane_axis(link.limit_min, link.limit_max) if limited else None
        if axis_i is not None:
            angle = min(angle, chain.limit_angle)
            axis = AXES[axis_i]
            r1 = quat_to_mat(axis_angle(axis, angle)) @ to_eff
            r2 = quat_to_mat(axis_angle(axis, -angle)) @ to_eff
            new = plane_angle[li] + (angle if np.dot(r1, to_goal) > np.dot(r2, to_goal) else -angle)
            lo, hi = float(link.limit_min[axis_i]), float(link.limit_max[axis_i])
            if it == 0 and not lo <= new <= hi:
                if lo < -new < hi:
                    new = -new
                elif abs(0.5 * (lo + hi) - new) > abs(0.5 * (lo + hi) + new):
                    new = -new
            new = float(np.clip(new, lo, hi))
            plane_angle[li] = new
            ik = qmul(axis_angle(axis, new), conj(poser.anim_rot[j]))
        else:
            if np.degrees(angle) < 1e-3:
                continue
            angle = min(angle, chain.limit_angle)
            cross = np.cross(to_eff, to_goal)
            n = math.sqrt(cross @ cross)
            if n < 1e-12:
                continue
            rot = axis_angle(cross / n, angle)
            full = qmul(qmul(poser.ik_rot[j], poser.anim_rot[j]), rot)
            if limited:
                e = np.clip(euler_xyz(quat_to_mat(full)), link.limit_min, link.limit_max)
                full = euler_xyz_to_quat(e)
            ik = qmul(full, conj(poser.anim_rot[j]))
        poser.ik_rot[j] = ik / math.sqrt(ik @ ik)
        poser.update_local(j)
        poser.update_chain(j, target)


