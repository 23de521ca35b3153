"""MMD's bone evaluation for one frame: local transforms from animation, then grant (付与) and IK
in MMD's order, as MMD players do it (Saba's ``MMDModel::UpdateNodeAnimation``):

1. every bone's local transform = translate(rest offset from parent + animated translation
   [+ granted translation]) x rotate(IK rotation x animated rotation [x granted rotation]);
2. global transforms from the roots down;
3. bones in deform order (after-physics bones last, then by deform layer, then file index): a
   grant bone takes its share of its grant parent's rotation/translation
   (:mod:`datagen.mmd.grant`), an IK bone runs CCD on its chain (:mod:`datagen.mmd.ik`), each
   followed by an update of the bone's subtree.

All in the file's frame and units; rest orientations are identity (MMD bones have none), so a
bone's global rotation is its rotation relative to rest. Physics is not run here.
"""
from __future__ import annotations

import numpy as np

from datagen.mmd.model import MMDModel
from datagen.mmd.records import topological_order


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b of two quaternions (w, x, y, z) (b applied first)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


class MMDPoser:
    """The bones of one model and their state for the frame being evaluated (file order, K bones).

    State arrays: ``anim_rot`` (K, 4) and ``anim_trans`` (K, 3) from the motion; ``ik_rot`` (K, 4)
    set by the IK solver on chain links; ``grant_rot`` (K, 4) and ``grant_trans`` (K, 3) set by
    grants; ``local_R`` (K, 3, 3), ``local_t`` (K, 3); ``R`` (K, 3, 3) and ``t`` (K, 3) global.
    """

    def __init__(self, model: MMDModel):
        self.model = model
        bones = model.bones
        k = len(bones)
        self.rest = np.array([b.position for b in bones], np.float64).reshape(k, 3)
        self.parents = np.array([b.parent for b in bones], np.int64)
        self.offset = self.rest - np.where(self.parents[:, None] >= 0, self.rest[np.maximum(self.parents, 0)], 0.0)
        topo = topological_order(self.parents)
        self.topo = topo
        self.children: list[list[int]] = [[] for _ in range(k)]
        for i in topo:
            if self.parents[i] >= 0:
                self.children[self.parents[i]].append(int(i))
        self.subtree = [self._subtree(i) for i in range(k)]
        rank = np.empty(k, np.int64)
        rank[topo] = np.arange(k)
        self.deform_order = sorted(range(k), key=lambda i: (bones[i].after_physics, bones[i].layer, i))
        self.is_ik_link = np.zeros(k, bool)
        for b in bones:
            if b.ik is not None:
                for link in b.ik.links:
                    self.is_ik_link[link.bone] = True
        self.reset()

    def _subtree(self, i: int) -> list[int]:
        out, stack = [], [i]
        while stack:
            j = stack.pop()
            out.append(j)
            stack.extend(reversed(self.children[j]))
        return out

    def reset(self, anim_rot: np.ndarray | None = None, anim_trans: np.ndarray | None = None) -> None:
        """Start a frame: animated local rotations (K, 4) (w, x, y, z) and translations (K, 3)."""
        k = len(self.rest)
        self.anim_rot = np.tile(IDENTITY, (k, 1)) if anim_rot is None else np.asarray(anim_rot, np.float64).copy()
        self.anim_trans = np.zeros((k, 3)) if anim_trans is None else np.asarray(anim_trans, np.float64).copy()
        self.ik_rot = np.tile(IDENTITY, (k, 1))
        self.grant_rot = np.tile(IDENTITY, (k, 1))
        self.grant_trans = np.zeros((k, 3))
        self.local_R = np.tile(np.eye(3), (k, 1, 1))
        self.local_t = self.offset.copy()
        self.R = np.tile(np.eye(3), (k, 1, 1))
        self.t = self.rest.copy()

    def local_rotation(self, i: int) -> np.ndarray:
        """IK rotation x animated rotation x granted rotation of bone i (w, x, y, z)."""
        r = qmul(self.ik_rot[i], self.anim_rot[i]) if self.is_ik_link[i] else self.anim_rot[i]
        if self.model.bones[i].grant_rotation:
            r = qmul(r, self.grant_rot[i])
        return r

    def update_local(self, i: int) -> None:
        b = self.model.bones[i]
        self.local_R[i] = quat_to_mat(self.local_rotation(i))
        t = self.offset[i] + self.anim_trans[i]
        if b.grant_translation:
            t = t + self.grant_trans[i]
        self.local_t[i] = t

    def update_global(self, i: int) -> None:
        """Global transforms of bone i and everything below it."""
        for j in self.subtree[i]:
            p = self.parents[j]
            if p < 0:
                self.R[j] = self.local_R[j]
                self.t[j] = self.local_t[j]
            else:
                self.R[j] = self.R[p] @ self.local_R[j]
                self.t[j] = self.R[p] @ self.local_t[j] + self.t[p]

    def update_chain(self, i: int, end: int) -> None:
        """Global transforms of bone i and the bones between it and its descendant ``end`` only
        (what CCD needs between its steps; the caller updates whole subtrees afterwards)."""
        path = [end]
        while path[-1] != i and path[-1] >= 0:
            path.append(int(self.parents[path[-1]]))
        if path[-1] != i:  # end is not below i
            self.update_global(i)
            return
        for j in reversed(path):
            p = self.parents[j]
            if p < 0:
                self.R[j] = self.local_R[j]
                self.t[j] = self.local_t[j]
            else:
                self.R[j] = self.R[p] @ self.local_R[j]
                self.t[j] = self.R[p] @ self.local_t[j] + self.t[p]

    def evaluate(self, anim_rot: np.ndarray, anim_trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose one frame: global rotations (K, 3, 3) and bone head positions (K, 3), file frame."""
        from datagen.mmd.grant import apply_grant
        from datagen.mmd.ik import solve_ik

        self.reset(anim_rot, anim_trans)
        bones = self.model.bones
        for after in (False, True):
            group = [i for i in self.deform_order if bones[i].after_physics == after]
            for i in group:
                self.update_local(i)
            for i in self.topo:
                if self.parents[i] < 0:
                    self.update_global(int(i))
            for i in group:
                if bones[i].grant_rotation or bones[i].grant_translation:
                    apply_grant(self, i)
                    self.update_global(i)
                if bones[i].ik is not None:
                    solve_ik(self, i)
                    self.update_global(i)
        return self.R.copy(), self.t.copy()
