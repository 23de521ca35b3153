"""Each rigid body's own velocity damping in a chain of joints, as MMD's Bullet damps its bodies.

MMD's Bullet scales every rigid body's world velocity by ``(1 - d)`` per second (``d`` the body's
linear damping for its linear velocity, its angular damping for its angular velocity) before it
solves the joints. pybullet's multibody has one damping for all its links (``changeDynamics`` sets
it for the whole multibody whichever link it names), so a chain whose bodies' dampings differ (a
hair strand whose 50 g tip has ``d = 1`` under a 7 kg root at 0.67) cannot take them per link.

Here each link's world velocity is scaled by its own factor and the chain's joint velocities are
the ones that come nearest those scaled velocities in the chain's kinetic energy (the least squares
weighted by each link's mass and world inertia), the anchor's velocity kept. The result is a
contraction of the velocities relative to the anchor in the kinetic-energy norm (each factor in
[0, 1]), so it is stable at any damping and step, unlike a damping force.

Conventions (pybullet's, checked against ``getLinkStates`` in the tests): a spherical joint's
velocity (3,) is the angular velocity of its link relative to its parent, expressed in the link's
centre-of-mass frame; the joint's pivot is the link frame's origin.
"""
from __future__ import annotations

import math

import numpy as np

MAX_DAMPING = 0.999
"""A damping of 1 (velocity zeroed every step) is taken as this, as the chains' Bullet damping is."""


def keep_factors(linear_damping: np.ndarray, angular_damping: np.ndarray, dt: float) -> np.ndarray:
    """(L, 2) the share of each body's linear and angular world speed kept over one step of ``dt``
    seconds: ``(1 - d) ** dt`` for MMD's damping ``d`` (0..1, the share lost in one second), ``d``
    capped at :data:`MAX_DAMPING`."""
    d = np.minimum(np.stack([np.asarray(linear_damping, np.float64), np.asarray(angular_damping, np.float64)], 1),
                   MAX_DAMPING)
    if (d < 0).any():
        raise ValueError(f"damping must be in [0, 1]; got {d.min()}")
    return np.exp(float(dt) * np.log1p(-d))


def chain_jacobian(parents: list[int], free: np.ndarray, centres: np.ndarray, pivots: np.ndarray,
                   frames: np.ndarray) -> np.ndarray:
    """(L, 6, 3L) world linear (rows 0-2) and angular (rows 3-5) velocity of each link's centre per
    unit of each joint's velocity (three columns a link, zero for a fixed joint).

    Args:
        parents: (L,) each link's parent link, parents first; -1 the anchor.
        free: (L,) bool, whether the link's joint turns (spherical) rather than being fixed.
        centres: (L, 3) world centres of mass, metres. pivots: (L, 3) world joint pivots, metres.
        frames: (L, 3, 3) world rotation of each link's centre-of-mass frame (the joint velocity's frame).
    """
    n = len(parents)
    jac = np.zeros((n, 6, 3 * n))
    for j in range(n):
        if not free[j]:
            continue
        axes = frames[j]  # columns: the joint velocity's axes in world
        for i in range(n):
            a = i
            while a >= 0 and a != j:
                a = parents[a]
            if a != j:
                continue  # j is not on i's path to the anchor
            jac[i, 3:, 3 * j:3 * j + 3] = axes
            jac[i, :3, 3 * j:3 * j + 3] = np.cross(axes.T, centres[i] - pivots[j]).T
    return jac


def damped_joint_velocities(jac: np.ndarray, velocities: np.ndarray, joint_velocities: np.ndarray,
                            masses: np.ndarray, inertias: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(3L,) joint velocities after each link's world velocity is scaled by its own factor.

    Args:
        jac: (L, 6, 3L) from :func:`chain_jacobian`. velocities: (L, 6) each link's world linear
            (m/s) and angular (rad/s) velocity. joint_velocities: (3L,) the joints' velocities now.
        masses: (L,) kg. inertias: (L, 3, 3) world inertia tensors about the centres, kg m^2.
        keep: (L, 2) the linear and angular factors (:func:`keep_factors`).

    The anchor's share of each link's velocity (``velocities - jac @ joint_velocities``) is kept as
    it is; the joints take the least squares ``min sum_i m_i |v_i' - k_i v_i|^2 + (w_i' - k'_i w_i)^T
    I_i (w_i' - k'_i w_i)``.
    """
    n = len(masses)
    v = np.asarray(velocities, np.float64)
    qd = np.asarray(joint_velocities, np.float64)
    carried = v - np.einsum("lrc,c->lr", jac, qd)
    target = np.concatenate([keep[:, :1] * v[:, :3], keep[:, 1:] * v[:, 3:]], 1) - carried
    root_i = np.empty((n, 3, 3))
    for i in range(n):
        w, u = np.linalg.eigh(0.5 * (inertias[i] + inertias[i].T))
        root_i[i] = (u * np.sqrt(np.maximum(w, 0.0))) @ u.T
    root_m = np.sqrt(np.asarray(masses, np.float64))
    a = np.concatenate([root_m[:, None, None] * jac[:, :3], np.einsum("lab,lbc->lac", root_i, jac[:, 3:])], 1)
    b = np.concatenate([root_m[:, None] * target[:, :3], np.einsum("lab,lb->la", root_i, target[:, 3:])], 1)
    solved, *_ = np.linalg.lstsq(a.reshape(6 * n, -1), b.reshape(-1), rcond=None)
    cols = np.abs(jac).sum(axis=(0, 1)) > 0
    return np.where(cols, solved, 0.0)


def differs(linear_damping: np.ndarray, angular_damping: np.ndarray, tolerance: float = 1e-6) -> bool:
    """Whether a chain's bodies' dampings differ (rates ``-ln(1 - d)`` apart by more than ``tolerance``
    per second): only such chains need per-body damping; one damping for all is the multibody's own."""
    rates = [[-math.log1p(-min(float(x), MAX_DAMPING)) for x in d] for d in (linear_damping, angular_damping)]
    return any(max(r) - min(r) > tolerance for r in rates)
