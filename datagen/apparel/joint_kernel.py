"""The per-step arithmetic of the chains' joints, compiled (numba): rotation vectors from the joint
states, the screen for joints past their limits, and the springs' implicit torques.

A physics step of a 2 s clip at 240 Hz has about 0.1 ms for everything outside Bullet; the same
arithmetic as elementwise numpy cost some 40 numpy calls a step (a few microseconds each whatever
the size), so it is written as loops over the joints and compiled once (``cache=True``: the
compiled code is kept beside this file and loaded on later imports). Loops in a fixed order, no
BLAS or LAPACK, no fast-math and no threads: the bytes do not depend on the machine's thread count
(a local process and a Ray worker give the same clip).

Shapes: J joints, each 3 axes (3J rows); B trees of links, each at most n rows, their mass
matrices at the present pose zero-padded in one (B, n, n) array, refilled every step
(:class:`mimicbench.datagen.apparel.springs.Springs`).
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


LINK_FIELDS = 16  # per link in ``links``: rest turn (9, row-major), offset (3), half length, mass, transverse, axial
POSE_FIELDS = 12  # per link in the ``pose`` scratch: world turn (9), head (3)
COMPOSITE_FIELDS = 22  # per link in the ``composite`` scratch: mass, first moment (3), second moment (9), inertia (9)


@njit(cache=True)
def _turn(r0: float, r1: float, r2: float, out: np.ndarray) -> None:
    """out (9,) row-major: the rotation matrix of rotation vector (r0, r1, r2) (Rodrigues)."""
    angle = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if angle < 1e-12:
        c, s, t = 1.0, 0.0, 0.0
        x = y = z = 0.0
    else:
        c, s = math.cos(angle), math.sin(angle)
        t = 1.0 - c
        x, y, z = r0 / angle, r1 / angle, r2 / angle
    out[0], out[1], out[2] = c + t * x * x, t * x * y - s * z, t * x * z + s * y
    out[3], out[4], out[5] = t * x * y + s * z, c + t * y * y, t * y * z - s * x
    out[6], out[7], out[8] = t * x * z - s * y, t * y * z + s * x, c + t * z * z


@njit(cache=True)
def posed_mass_matrices(rotation: np.ndarray, parents: np.ndarray, links: np.ndarray, slots: np.ndarray,
                        mass_matrices: np.ndarray, pose: np.ndarray, composite: np.ndarray) -> None:
    """Each tree's joint-space mass matrix at the joints' present rotations, its anchor held still.

    Link i's world turn is R_i = R_p T_i Q(r_i) (R_p its parent's, the identity for a root; T_i its
    rest turn in the parent's frame; Q(r_i) its joint's rotation) and its head h_i = h_p + R_p o_i
    (o_i the head's offset in the parent's frame; a root's head at the origin: only differences
    count). Joint j moves link i below it with angular velocity R_j w_j and centre velocity
    (R_j w_j) x (c_i - h_j), so block (j, k) of M, k an ancestor of j or j, is
    R_j^T W_jk R_k with W_jk = sum over links i at or below j of
    m_i ((d_j . d_k) 1 - d_k d_j^T) + I_i,  d_j = c_i - h_j;
    with the subtree's mass m, first moment s = sum m_i c_i, second moment S = sum m_i c_i c_i^T
    and inertia sum I (world, about the centres) that is tr(P) 1 - P + I, P = S - s h_j^T - h_k s^T
    + m h_k h_j^T, one constant-time block per pair (the composite-body form).

    Args:
        rotation: (J, 3) joint rotation vectors (rad, joint frame); links in topological order.
        parents: (J,) each link's parent link (-1: on the anchor).
        links: (J, LINK_FIELDS) rest turn (row-major 3 x 3), offset (m), half length (m), mass (kg),
            transverse and axial moment (kg m^2) of each link.
        slots: (3J,) each joint axis's place b * n + i in the zero-padded trees.
        mass_matrices: (B, n, n) out, zero-padded.
        pose, composite: (J + 4, POSE_FIELDS), (J, COMPOSITE_FIELDS) scratch.
    """
    joints = rotation.shape[0]
    n = mass_matrices.shape[1]
    q, tr, w, left = pose[joints, :9], pose[joints + 1, :9], pose[joints + 2, :9], pose[joints + 3, :9]
    for i in range(joints):  # world turns and heads, parents first
        _turn(rotation[i, 0], rotation[i, 1], rotation[i, 2], q)
        p = parents[i]
        for a in range(3):  # tr = T_i Q
            for b in range(3):
                tr[3 * a + b] = links[i, 3 * a] * q[b] + links[i, 3 * a + 1] * q[3 + b] + links[i, 3 * a + 2] * q[6 + b]
        if p < 0:
            for a in range(9):
                pose[i, a] = tr[a]
            for a in range(3):
                pose[i, 9 + a] = 0.0
        else:
            for a in range(3):
                for b in range(3):
                    pose[i, 3 * a + b] = pose[p, 3 * a] * tr[b] + pose[p, 3 * a + 1] * tr[3 + b] \
                        + pose[p, 3 * a + 2] * tr[6 + b]
                pose[i, 9 + a] = pose[p, 9 + a] + pose[p, 3 * a] * links[i, 9] + pose[p, 3 * a + 1] * links[i, 10] \
                    + pose[p, 3 * a + 2] * links[i, 11]
    for i in range(joints):  # each link's own moments
        m, half, it, ia = links[i, 13], links[i, 12], links[i, 14], links[i, 15]
        c0 = pose[i, 9] + half * pose[i, 2]
        c1 = pose[i, 10] + half * pose[i, 5]
        c2 = pose[i, 11] + half * pose[i, 8]
        z = (pose[i, 2], pose[i, 5], pose[i, 8])  # the link's axis in the world
        centre = (c0, c1, c2)
        composite[i, 0] = m
        for a in range(3):
            composite[i, 1 + a] = m * centre[a]
            for b in range(3):
                composite[i, 4 + 3 * a + b] = m * centre[a] * centre[b]
                composite[i, 13 + 3 * a + b] = (ia - it) * z[a] * z[b] + (it if a == b else 0.0)
    for i in range(joints - 1, -1, -1):  # subtree sums, children first
        p = parents[i]
        if p >= 0:
            for a in range(COMPOSITE_FIELDS):
                composite[p, a] += composite[i, a]
    for j in range(joints):  # zero each joint's rows within its tree (siblings' blocks stay zero)
        tree, row_j = slots[3 * j] // n, slots[3 * j] % n
        for a in range(3):
            for c in range(n):
                mass_matrices[tree, row_j + a, c] = 0.0
    for j in range(joints):
        m = composite[j, 0]
        tree, row_j = slots[3 * j] // n, slots[3 * j] % n
        k = j
        while k >= 0:  # k: j and its ancestors
            row_k = slots[3 * k] % n
            trace = 0.0
            for a in range(3):
                for b in range(3):  # P = S - s h_j^T - h_k s^T + m h_k h_j^T, entry (a, b)
                    w[3 * a + b] = composite[j, 4 + 3 * a + b] - composite[j, 1 + a] * pose[j, 9 + b] \
                        - pose[k, 9 + a] * composite[j, 1 + b] + m * pose[k, 9 + a] * pose[j, 9 + b]
                trace += w[4 * a]
            for a in range(9):  # W = tr(P) 1 - P + I
                w[a] = composite[j, 13 + a] - w[a]
            for a in range(3):
                w[4 * a] += trace
            for a in range(3):  # left = R_j^T W
                for b in range(3):
                    left[3 * a + b] = pose[j, a] * w[b] + pose[j, 3 + a] * w[3 + b] + pose[j, 6 + a] * w[6 + b]
            for a in range(3):  # block = left R_k
                for b in range(3):
                    v = left[3 * a] * pose[k, b] + left[3 * a + 1] * pose[k, 3 + b] + left[3 * a + 2] * pose[k, 6 + b]
                    mass_matrices[tree, row_j + a, row_k + b] = v
                    mass_matrices[tree, row_k + b, row_j + a] = v
            k = parents[k]


@njit(cache=True)
def spring_torques(rotation: np.ndarray, velocity: np.ndarray, stiffness: np.ndarray, damping: np.ndarray,
                   mass_matrices: np.ndarray, sizes: np.ndarray, slots: np.ndarray, member: np.ndarray,
                   inverse_bound: np.ndarray, dt: float, padded: np.ndarray, system: np.ndarray, solution: np.ndarray,
                   torques: np.ndarray) -> float:
    """The springs' implicit torques tau = -M_b (M_b + dt D)^-1 (K r + D w) of every tree b, and the
    largest share of a torque bound they use.

    Args:
        rotation, velocity: (J, 3) rad and rad/s (velocity may be a strided view).
        stiffness, damping: (3J,) K and D per joint axis.
        mass_matrices: (B, n, n) each tree's joint-space mass matrix (:func:`posed_mass_matrices`),
            zero-padded; sizes: (B,) its rows.
        slots: (3J,) each joint axis's place b * n + i in the padded (B * n,); member: (B * n,) the
            joint axis at each place (-1: padding).
        inverse_bound: (3J,) 1 / each axis's torque bound. dt: s.
        padded: (B * n,) scratch; system: (n, n), solution: (n, 1) scratch.
        torques: (J, 3) out, N m.

    Returns:
        max over axes of |tau| / bound (above 1: some tree must be solved again with weaker springs).
    """
    n = mass_matrices.shape[1]
    axes = slots.shape[0]
    for a in range(axes):
        j, k = a // 3, a % 3
        padded[slots[a]] = stiffness[a] * rotation[j, k] + damping[a] * velocity[j, k]
    worst = 0.0
    for b in range(mass_matrices.shape[0]):
        m = sizes[b]
        for i in range(m):
            for c in range(m):
                system[i, c] = mass_matrices[b, i, c]
            system[i, i] += dt * damping[member[b * n + i]]
            solution[i, 0] = padded[b * n + i]
        solve_spd_in_place(system, solution, m, 1)
        for i in range(m):
            total = 0.0
            for c in range(m):
                total += mass_matrices[b, i, c] * solution[c, 0]
            a = member[b * n + i]
            torques[a // 3, a % 3] = -total
            share = abs(total) * inverse_bound[a]
            if share > worst:
                worst = share
    return worst


@njit(cache=True)
def joint_torques(states: np.ndarray, limits: np.ndarray, gains: np.ndarray, parents: np.ndarray, links: np.ndarray,
                  slots: np.ndarray, member: np.ndarray, sizes: np.ndarray, dt: float, mass_matrices: np.ndarray,
                  pose: np.ndarray,
                  composite: np.ndarray, padded: np.ndarray, system: np.ndarray, solution: np.ndarray,
                  rotation: np.ndarray, torques: np.ndarray) -> tuple[int, float]:
    """One step's work in one call: :func:`rotation_vectors`, then, when no joint is past a limit,
    :func:`posed_mass_matrices` and :func:`spring_torques` (velocities: ``states[:, 4:]``).

    Args:
        limits: (3, J) each joint's ``limit_floor``, ``swing`` and ``twist``.
        gains: (3, 3J) each joint axis's stiffness, damping and inverse torque bound.
        the others: as in those functions.

    Returns:
        (joints past a limit, largest share of a torque bound); with joints past a limit neither the
        mass matrices nor the torques are computed (share 0): the caller puts the joints back onto
        their limits first.
    """
    over = rotation_vectors(states, limits[0], limits[1], limits[2], rotation)
    if over:
        return over, 0.0
    posed_mass_matrices(rotation, parents, links, slots, mass_matrices, pose, composite)
    return 0, spring_torques(rotation, states[:, 4:], gains[0], gains[1], mass_matrices, sizes, slots, member,
                             gains[2], dt, padded, system, solution, torques)


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
