"""The per-step arithmetic of the chains' joints, compiled (numba): rotation vectors from the joint
states, the screen for joints past their limits, and the springs' implicit torques.

A physics step of a 2 s clip at 240 Hz has about 0.1 ms for everything outside Bullet; the same
arithmetic as elementwise numpy cost some 40 numpy calls a step (a few microseconds each whatever
the size), so it is written as loops over the joints and compiled once (``cache=True``: the
compiled code is kept beside this file and loaded on later imports). Loops in a fixed order, no
BLAS or LAPACK, no fast-math and no threads: the bytes do not depend on the machine's thread count
(a local process and a Ray worker give the same clip).

Shapes: J joints, each 3 axes (3J rows); B trees of links, each at most n rows, their implicit
step's matrices zero-padded in one (B, n, n) array (:class:`datagen.apparel.springs.Springs`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def rotation_vectors(states: np.ndarray, limit_floor: np.ndarray, swing: np.ndarray, twist: np.ndarray,
                     rotation: np.ndarray) -> int:
    """Joint rotations from rest as rotation vectors, and how many joints are past a limit.

    Args:
        states: (J, 7) per joint its quaternion (x, y, z, w) and velocity (3,); each quaternion
            is turned to w >= 0 in place.
        limit_floor: (J,) rad, below this angle a joint is within both its limits.
        swing: (J,) rad, the swing cone's half angle. twist: (J,) rad, the twist bound.
        rotation: (J, 3) out, the rotation vectors r (|r| the angle, rad, in the joint's frame).

    Returns:
        the number of joints with |(r_x, r_y)| > swing or |r_z| > twist (0 when no joint is turned
        as far as its ``limit_floor``).
    """
    screen = False
    for j in range(states.shape[0]):
        if states[j, 3] < 0.0:
            for a in range(4):
                states[j, a] = -states[j, a]
        x, y, z, w = states[j, 0], states[j, 1], states[j, 2], states[j, 3]
        sin_half = math.sqrt(x * x + y * y + z * z)
        angle = 2.0 * math.atan2(sin_half, w)
        scale = angle / max(sin_half, 1e-12)
        rotation[j, 0], rotation[j, 1], rotation[j, 2] = x * scale, y * scale, z * scale
        if angle > limit_floor[j]:
            screen = True
    over = 0
    if screen:
        for j in range(states.shape[0]):
            bend = math.sqrt(rotation[j, 0] * rotation[j, 0] + rotation[j, 1] * rotation[j, 1])
            if bend > swing[j] or abs(rotation[j, 2]) > twist[j]:
                over += 1
    return over


@njit(cache=True)
def spring_torques(rotation: np.ndarray, velocity: np.ndarray, stiffness: np.ndarray, damping: np.ndarray,
                   blocks: np.ndarray, slots: np.ndarray, inverse_bound: np.ndarray, padded: np.ndarray,
                   torques: np.ndarray) -> float:
    """The springs' implicit torques tau = -A_b (K r + D w) of every tree b, and the largest share
    of a torque bound they use.

    Args:
        rotation, velocity: (J, 3) rad and rad/s (velocity may be a strided view).
        stiffness, damping: (3J,) K and D per joint axis.
        blocks: (B, n, n) each tree's matrix A_b = (1 + dt D M^-1)^-1, zero-padded.
        slots: (3J,) each joint axis's place b * n + i in the padded (B * n,).
        inverse_bound: (3J,) 1 / each axis's torque bound.
        padded: (B * n,) scratch, zero outside the slots.
        torques: (J, 3) out, N m.

    Returns:
        max over axes of |tau| / bound (above 1: some tree must be solved again with weaker springs).
    """
    n = blocks.shape[1]
    axes = slots.shape[0]
    for a in range(axes):
        j, k = a // 3, a % 3
        padded[slots[a]] = stiffness[a] * rotation[j, k] + damping[a] * velocity[j, k]
    worst = 0.0
    for a in range(axes):
        b, i = slots[a] // n, slots[a] % n
        total = 0.0
        for c in range(n):
            total += blocks[b, i, c] * padded[b * n + c]
        torques[a // 3, a % 3] = -total
        share = abs(total) * inverse_bound[a]
        if share > worst:
            worst = share
    return worst


@njit(cache=True)
def joint_torques(states: np.ndarray, limits: np.ndarray, gains: np.ndarray, blocks: np.ndarray, slots: np.ndarray,
                  padded: np.ndarray, rotation: np.ndarray, torques: np.ndarray) -> tuple[int, float]:
    """One step's work in one call: :func:`rotation_vectors`, then, when no joint is past a limit,
    :func:`spring_torques` (velocities: ``states[:, 4:]``).

    Args:
        limits: (3, J) each joint's ``limit_floor``, ``swing`` and ``twist``.
        gains: (3, 3J) each joint axis's stiffness, damping and inverse torque bound.
        the others: as in those two functions.

    Returns:
        (joints past a limit, largest share of a torque bound); with joints past a limit the
        torques are not computed (share 0): the caller puts the joints back onto their limits first.
    """
    over = rotation_vectors(states, limits[0], limits[1], limits[2], rotation)
    if over:
        return over, 0.0
    return 0, spring_torques(rotation, states[:, 4:], gains[0], gains[1], blocks, slots, gains[2], padded, torques)


@njit(cache=True)
def solve_spd_in_place(a: np.ndarray, x: np.ndarray, n: int, columns: int) -> None:
    """Solve a[:n, :n] y = x[:n, :columns] for y, written over x (a is overwritten too), for a
    symmetric positive definite a.

    Gaussian elimination without pivoting, loops in a fixed order, no BLAS or LAPACK: their
    multi-threaded kernels round differently with the number of threads, and the apparel stage's
    output must not depend on where it runs (a local process or a worker with one thread).
    """
    for k in range(n - 1):  # forward elimination
        for i in range(k + 1, n):
            f = a[i, k] / a[k, k]
            for c in range(k + 1, n):
                a[i, c] -= f * a[k, c]
            for c in range(columns):
                x[i, c] -= f * x[k, c]
    for k in range(n - 1, -1, -1):  # back substitution
        for c in range(columns):
            total = 0.0
            for i in range(k + 1, n):
                total += a[k, i] * x[i, c]
            x[k, c] = (x[k, c] - total) / a[k, k]


@njit(cache=True)
def weaker_springs(rotation: np.ndarray, velocity: np.ndarray, gains: np.ndarray, mass_matrices: np.ndarray,
                   sizes: np.ndarray, slots: np.ndarray, dt: float, torques: np.ndarray, system: np.ndarray,
                   solution: np.ndarray) -> int:
    """``torques`` (J, 3) of :func:`spring_torques` with every tree that has an axis past its bound
    solved again, in place, with that axis's K and D scaled down by the overshoot:
    tau = -M (M + dt D')^-1 (K' r + D' w) of that tree alone.

    Args:
        rotation, velocity: (J, 3). gains: (3, 3J) stiffness, damping, inverse bound.
        mass_matrices: (B, n, n) each tree's joint-space mass matrix, zero-padded; sizes: (B,) its rows.
        slots: (3J,) each joint axis's place b * n + i. dt: s.
        system, solution: (n, n) scratch.

    Returns:
        the number of trees solved again.

    The linear solve is :func:`solve_spd_in_place` (M + dt D' is symmetric positive definite).
    """
    n = mass_matrices.shape[1]
    blocks = mass_matrices.shape[0]
    axes = slots.shape[0]
    share = np.ones(blocks * n)  # per padded slot: 1 / max(|tau| / bound, 1)
    member = np.full(blocks * n, -1)  # per padded slot: its joint axis
    over = np.zeros(blocks, np.bool_)
    for a in range(axes):
        used = abs(torques[a // 3, a % 3]) * gains[2, a]
        member[slots[a]] = a
        if used > 1.0:
            share[slots[a]] = 1.0 / used
            over[slots[a] // n] = True
    count = 0
    for b in range(blocks):
        if not over[b]:
            continue
        count += 1
        m = sizes[b]
        for i in range(m):  # system = M + dt D', solution = M
            for c in range(m):
                system[i, c] = mass_matrices[b, i, c]
                solution[i, c] = mass_matrices[b, i, c]
            a = member[b * n + i]
            system[i, i] += dt * (gains[1, a] * share[b * n + i])
        solve_spd_in_place(system, solution, m, m)
        for i in range(m):  # tau_i = -sum_c (M + dt D')^-1 M [c, i] x_c
            total = 0.0
            for c in range(m):
                a = member[b * n + c]
                x = gains[0, a] * share[b * n + c] * rotation[a // 3, a % 3] \
                    + gains[1, a] * share[b * n + c] * velocity[a // 3, a % 3]
                total += solution[c, i] * x
            a = member[b * n + i]
            torques[a // 3, a % 3] = -total
    return count
