"""The chains' joint springs: torques toward the rest pose, for all joints at once (compiled,
:func:`mimicbench.datagen.apparel.joint_kernel.spring_torques`).

Each spherical joint is pulled toward rest by a spring with damping. Stiff springs on light links
blow up when their torque is taken from the present state alone (explicit: the chain's fast
zig-zag mode has a far smaller inertia than any one joint), so the torque is the implicit one of
"stable PD" control (Tan, Liu and Turk, 2011), with the joint-space mass matrix M of each tree of
links at the joints' present rotations (a chain; a multibody of merged chains holds several,
:func:`chain_components`, and solving them apart costs a fraction of solving them together): the
torque that, after one step of length dt, meets the spring and damper at the new speed,

    tau = -(K q + D w+),  w+ = w + dt M^-1 tau,  D = K dt + C
    =>  tau = -(1 + dt D M^-1)^-1 (K q + D w)

with q a joint's rotation vector from rest and w its velocity (each 3 per joint, in the child
link's frame). Where a joint's torque passes its ``max_torque`` on an axis, that axis's K and
D are scaled down by the overshoot and that tree's implicit step is solved again with them, so
the torque comes back to about the bound (clipping the torque alone would undo the implicit
step: its neighbours overcorrect and the chain zig-zags; any K, D >= 0 keep the step stable);
with ``max_torque`` 0 the joint is free. The gains follow a joint's
``stiffness`` s (the share of an angle error taken out in one step) and ``damping`` v (the share
of a speed) on the joint's own diagonal of the rest pose's M0: K = s diag(M0) / dt^2,
C = v diag(M0) / dt.

M is taken anew every step (:func:`mimicbench.datagen.apparel.joint_kernel.posed_mass_matrices`). The rest
pose's M would not do: on a folded chain the light modes' true inertia is far below the straight
chain's, so a damper's torque sized for the heavier chain drives them past zero and back every step
(a strand's kinetic energy grows tenfold in one step in tests/test_apparel_whip.py). With the present M the step
w+ = (M + dt D)^-1 M w takes energy out: KE - KE+ = dt w+^T D w+ + dt^2 w+^T D M^-1 D w+ / 2 >= 0.

M treats the chain's anchor as fixed (it outweighs the chain ten times and its constraint holds
it on its bone); links are the URDF's inertias (:func:`mimicbench.datagen.apparel.urdf.capsule_inertia`, at
each capsule's centre). Units: N m, rad, s, kg m^2.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.apparel.chain_spec import ChainSpec
from mimicbench.datagen.apparel.joint_kernel import (COMPOSITE_FIELDS, LINK_FIELDS, POSE_FIELDS, posed_mass_matrices,
                                          solve_spd_in_place, spring_torques, weaker_springs)
from mimicbench.datagen.apparel.urdf import bone_frame, capsule_inertia


def _skew(v: np.ndarray) -> np.ndarray:
    """(3, 3) cross-product matrix of v (3,): _skew(v) @ u = v x u."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def chain_mass_matrix(chain: ChainSpec) -> np.ndarray:
    """(3L, 3L) joint-space mass matrix of ``chain`` at rest with its anchor fixed.

    Joint j's three speeds are the angular velocity of link j relative to its parent, in link j's
    rest frame R_j (Z along the bone). Link i moves with the joints on its path to the anchor:
    angular velocity sum_j R_j w_j, centre velocity sum_j (R_j w_j) x (c_i - h_j); M = sum over
    links of J_v^T m J_v + J_w^T I_world J_w.
    """
    n = len(chain.links)
    frames = [bone_frame(link.axis).as_matrix() for link in chain.links]
    heads = [np.asarray(link.head, np.float64) for link in chain.links]
    mass_matrix = np.zeros((3 * n, 3 * n))
    for i, link in enumerate(chain.links):
        axis = np.asarray(link.axis, np.float64) / np.linalg.norm(link.axis)
        centre = heads[i] + 0.5 * link.length * axis
        transverse, axial = capsule_inertia(link.mass, link.radius, link.length, link.axial_share)
        inertia = frames[i] @ np.diag([transverse, transverse, axial]) @ frames[i].T
        jv, jw = np.zeros((3, 3 * n)), np.zeros((3, 3 * n))
        j = i
        while j >= 0:
            jw[:, 3 * j:3 * j + 3] = frames[j]
            jv[:, 3 * j:3 * j + 3] = -_skew(centre - heads[j]) @ frames[j]
            j = chain.link_parents[j]
        mass_matrix += link.mass * np.einsum("ai,aj->ij", jv, jv) + np.einsum("ai,ab,bj->ij", jw, inertia, jw)
    return mass_matrix


def link_geometry(chain: ChainSpec) -> np.ndarray:
    """(L, LINK_FIELDS) what :func:`mimicbench.datagen.apparel.joint_kernel.posed_mass_matrices` needs of each link
    of ``chain``: its rest turn in its parent's frame (row-major 3 x 3; a root's in the anchor's,
    which is the world's at rest), its head's offset from the parent's head in the parent's frame
    (m; 0 for a root), half its length (m), its mass (kg) and its transverse and axial moments
    (kg m^2, :func:`mimicbench.datagen.apparel.urdf.capsule_inertia`)."""
    frames = [bone_frame(link.axis).as_matrix() for link in chain.links]
    out = np.zeros((len(chain.links), LINK_FIELDS))
    for i, (link, p) in enumerate(zip(chain.links, chain.link_parents)):
        parent = frames[p] if p >= 0 else np.eye(3)
        out[i, :9] = (parent.T @ frames[i]).ravel()
        if p >= 0:
            out[i, 9:12] = parent.T @ (np.asarray(link.head, np.float64) - np.asarray(chain.links[p].head, np.float64))
        out[i, 12] = 0.5 * link.length
        out[i, 13] = link.mass
        out[i, 14:16] = capsule_inertia(link.mass, link.radius, link.length, link.axial_share)
    return out


def solve_spd(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x (n, m) with a x = b, for a symmetric positive definite (n, n) and b (n, m)
    (:func:`mimicbench.datagen.apparel.joint_kernel.solve_spd_in_place`, no BLAS or LAPACK)."""
    a = np.array(a, np.float64)
    x = np.array(b, np.float64)
    solve_spd_in_place(a, x, len(a), x.shape[1])
    return x


def chain_components(chain: ChainSpec) -> list[np.ndarray]:
    """Each tree of ``chain``'s links (a root with every link below it) as its link indices in order.

    A multibody of merged chains (:func:`mimicbench.datagen.apparel.chain_spec.merged_by_anchor`) holds several
    trees on one anchor; with the anchor fixed they do not move one another, so the mass matrix
    is block-diagonal by tree and each tree's springs are solved on their own.
    """
    tree = []
    for j, p in enumerate(chain.link_parents):
        tree.append(j if p < 0 else tree[p])  # parents come before children
    return [np.flatnonzero(np.array(tree) == root) for root in sorted(set(tree))]


class Springs:
    """The springs of every joint of ``chains`` (in chain order, J joints), for physics step ``dt`` (s).

    Solved per tree of links (:func:`chain_components`), each step with the tree's mass matrix at
    the joints' present rotations (:func:`mimicbench.datagen.apparel.joint_kernel.posed_mass_matrices`; the
    gains K and C stay those of the rest pose's diagonal): trees of B, each at most n = 3 x its
    links rows, kept zero-padded in one (B, n, n) array.
    """

    def __init__(self, chains: list[ChainSpec], dt: float):
        stiff, damp, bound, rows, parents, links = [], [], [], [], [], []
        self.dt = float(dt)
        self.mass_matrices: list[np.ndarray] = []  # per tree (n, n), at rest
        self.resolved = 0  # trees solved again with weaker springs (bound passed), a count
        start = 0
        for chain in chains:
            mass_matrix = chain_mass_matrix(chain)
            diag = np.diag(mass_matrix)
            k = np.repeat([joint.stiffness for joint in chain.joints], 3) * diag / dt ** 2
            c = np.repeat([joint.damping for joint in chain.joints], 3) * diag / dt
            stiff.append(k)
            damp.append(k * dt + c)
            bound.append(np.repeat([joint.max_torque for joint in chain.joints], 3))
            for links_of_tree in chain_components(chain):
                axes = (3 * links_of_tree[:, None] + np.arange(3)).ravel()  # this tree's rows in the chain's
                self.mass_matrices.append(mass_matrix[np.ix_(axes, axes)])
                rows.append(3 * start + axes)
            parents += [p + start if p >= 0 else -1 for p in chain.link_parents]
            links.append(link_geometry(chain))
            start += len(chain.links)
        width = max((len(m) for m in self.mass_matrices), default=0)
        order = np.concatenate(rows).astype(int) if rows else np.zeros(0, int)  # (3J,) axes tree by tree
        slots = np.concatenate([i * width + np.arange(len(r)) for i, r in enumerate(rows)]).astype(np.int64) \
            if rows else np.zeros(0, np.int64)  # (3J,) their places in the padded (B * n,)
        self.rows = np.empty_like(slots)  # (3J,) each joint axis's place in the padded (B * n,)
        self.rows[order] = slots
        self.member = np.full(len(self.mass_matrices) * width, -1, np.int64)  # (B * n,) the axis at each place
        self.member[self.rows] = np.arange(len(self.rows))
        self.parents = np.array(parents, np.int64)  # (J,) each link's parent link over all chains, -1: the anchor
        self.links = np.concatenate(links) if links else np.zeros((0, LINK_FIELDS))  # (J, LINK_FIELDS)
        self.stiffness = np.concatenate(stiff) if stiff else np.zeros(0)  # (3J,) K, N m/rad
        self.damping = np.concatenate(damp) if damp else np.zeros(0)  # (3J,) D = K dt + C, N m s/rad
        self.bound = np.concatenate(bound) if bound else np.zeros(0)  # (3J,) N m
        self.inverse_bound = 1.0 / np.maximum(self.bound, 1e-300)  # (3J,) 1/N m
        self.gains = np.stack([self.stiffness, self.damping, self.inverse_bound])  # (3, 3J) for the compiled step
        self.padded = np.zeros(len(self.mass_matrices) * width)  # (B * n,) scratch
        self.padded_mass = np.zeros((len(self.mass_matrices), width, width))  # (B, n, n) present mass matrices
        self.sizes = np.array([len(m) for m in self.mass_matrices], np.int64)  # (B,) each tree's rows
        self._system, self._solution = np.zeros((width, width)), np.zeros((width, width))  # scratch
        self._pose = np.zeros((len(self.parents) + 4, POSE_FIELDS))  # scratch (4 rows of 3 x 3 products)
        self._composite = np.zeros((len(self.parents), COMPOSITE_FIELDS))  # scratch
        # what joint_kernel.joint_torques takes after the states, limits and gains
        self.kernel_arrays = (self.parents, self.links, self.rows, self.member, self.sizes, self.dt, self.padded_mass,
                              self._pose, self._composite, self.padded, self._system, self._solution)

    def posed(self, rotation: np.ndarray) -> np.ndarray:
        """(B, n, n) every tree's mass matrix with the joints at rotation vectors ``rotation`` (J, 3)
        (:func:`mimicbench.datagen.apparel.joint_kernel.posed_mass_matrices`), kept for :meth:`within_bounds`."""
        posed_mass_matrices(np.ascontiguousarray(rotation, np.float64), self.parents, self.links, self.rows,
                            self.padded_mass, self._pose, self._composite)
        return self.padded_mass

    def torques(self, rotation: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """(J, 3) torques for joints at rotation vectors ``rotation`` (J, 3) with velocities ``velocity`` (J, 3).

        Every tree's implicit step at once with its present mass matrix (:meth:`posed`; compiled,
        :func:`mimicbench.datagen.apparel.joint_kernel.spring_torques`); then :meth:`within_bounds`.
        """
        rotation = np.ascontiguousarray(rotation, np.float64)
        velocity = np.asarray(velocity, np.float64)
        self.posed(rotation)
        tau = np.empty((len(rotation), 3))
        worst = spring_torques(rotation, velocity, self.stiffness, self.damping, self.padded_mass, self.sizes,
                               self.rows, self.member, self.inverse_bound, self.dt, self.padded, self._system,
                               self._solution, tau)
        return tau if worst <= 1.0 else self.within_bounds(rotation, velocity, tau)

    def within_bounds(self, rotation: np.ndarray, velocity: np.ndarray, torques: np.ndarray) -> np.ndarray:
        """``torques`` (J, 3) of :meth:`torques` with every tree that has an axis past its bound
        solved again with that axis's springs weaker by the overshoot (the trees within their
        bounds keep their torques); the mass matrices are those of the last :meth:`posed` (or of
        :func:`mimicbench.datagen.apparel.joint_kernel.joint_torques`, which fills the same array); compiled,
        :func:`mimicbench.datagen.apparel.joint_kernel.weaker_springs`."""
        tau = np.array(torques, np.float64)
        self.resolved += weaker_springs(np.asarray(rotation, np.float64), np.asarray(velocity, np.float64), self.gains,
                                        self.padded_mass, self.sizes, self.rows, self.dt, tau, self._system,
                                        self._solution)
        return tau
