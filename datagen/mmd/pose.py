"""MMD's bone evaluation, for many frames at once: local transforms from animation, then grant
(付与) and IK in MMD's order, as MMD players do it (Saba's ``MMDModel::UpdateNodeAnimation``):

1. every bone's local transform = translate(rest offset from parent + animated translation
   [+ granted translation]) x rotate(IK rotation x animated rotation [x granted rotation]);
2. global transforms from the roots down;
3. bones in deform order (after-physics bones last, then by deform layer, then file index): a
   grant bone takes its share of its grant parent's rotation/translation
   (:mod:`mimicbench.datagen.mmd.grant`), an IK bone runs CCD on its chain (:mod:`mimicbench.datagen.mmd.ik`), each
   followed by an update of the bone's subtree.

Frames are independent, so every array carries a leading frame axis F and each step runs on all
frames together. All in the file's frame and units; rest orientations are identity (MMD bones
have none), so a bone's global rotation is its rotation relative to rest. Physics is not run.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.mmd.grant import apply_grant
from mimicbench.datagen.mmd.ik import solve_ik
from mimicbench.datagen.mmd.model import MMDModel
from mimicbench.datagen.mmd.records import topological_order
from mimicbench.geometry.quaternion import IDENTITY, quat_multiply, quat_to_matrix


def rotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R v for rotations (F, 3, 3) and vectors (F, 3)."""
    return np.einsum("fij,fj->fi", R, v)


class MMDPoser:
    """The bones of one model and their state for the F frames being evaluated (file order, K bones).

    State arrays: ``anim_rot`` (F, K, 4) and ``anim_trans`` (F, K, 3) from the motion; ``ik_rot``
    (F, K, 4) set by the IK solver on chain links; ``grant_rot`` (F, K, 4) and ``grant_trans``
    (F, K, 3) set by grants; ``local_R`` (F, K, 3, 3), ``local_t`` (F, K, 3); ``R`` (F, K, 3, 3)
    and ``t`` (F, K, 3) global.
    """

    def __init__(self, model: MMDModel):
        self.model = model
        bones = model.bones
        k = len(bones)
        self.rest = np.array([b.position for b in bones], np.float64).reshape(k, 3)
        self.parents = np.array([b.parent for b in bones], np.int64)
        self.offset = self.rest - np.where(self.parents[:, None] >= 0, self.rest[np.maximum(self.parents, 0)], 0.0)
        self.topo = topological_order(self.parents)
        self.children: list[list[int]] = [[] for _ in range(k)]
        for i in self.topo:
            if self.parents[i] >= 0:
                self.children[self.parents[i]].append(int(i))
        self.subtree = [self._subtree(i) for i in range(k)]
        self.deform_order = sorted(range(k), key=lambda i: (bones[i].after_physics, bones[i].layer, i))
        self.is_ik_link = np.zeros(k, bool)
        for b in bones:
            if b.ik is not None:
                for link in b.ik.links:
                    self.is_ik_link[link.bone] = True
        self.reset(np.tile(IDENTITY, (1, k, 1)), np.zeros((1, k, 3)))

    def _subtree(self, i: int) -> list[int]:
        out, stack = [], [i]
        while stack:
            j = stack.pop()
            out.append(j)
            stack.extend(reversed(self.children[j]))
        return out

    def reset(self, anim_rot: np.ndarray, anim_trans: np.ndarray) -> None:
        """Start: animated local rotations (F, K, 4) (w, x, y, z) and translations (F, K, 3)."""
        self.anim_rot = np.asarray(anim_rot, np.float64).copy()
        self.anim_trans = np.asarray(anim_trans, np.float64).copy()
        f, k = self.anim_rot.shape[:2]
        self.ik_rot = np.tile(IDENTITY, (f, k, 1))
        self.grant_rot = np.tile(IDENTITY, (f, k, 1))
        self.grant_trans = np.zeros((f, k, 3))
        self.local_R = np.tile(np.eye(3), (f, k, 1, 1))
        self.local_t = np.broadcast_to(self.offset, (f, k, 3)).copy()
        self.R = np.tile(np.eye(3), (f, k, 1, 1))
        self.t = np.broadcast_to(self.rest, (f, k, 3)).copy()

    def local_rotation(self, i: int) -> np.ndarray:
        """IK rotation x animated rotation x granted rotation of bone i (F, 4)."""
        r = quat_multiply(self.ik_rot[:, i], self.anim_rot[:, i]) if self.is_ik_link[i] else self.anim_rot[:, i]
        if self.model.bones[i].grant_rotation:
            r = quat_multiply(r, self.grant_rot[:, i])
        return r

    def update_local(self, i: int) -> None:
        b = self.model.bones[i]
        self.local_R[:, i] = quat_to_matrix(self.local_rotation(i))
        t = self.offset[i] + self.anim_trans[:, i]
        if b.grant_translation:
            t = t + self.grant_trans[:, i]
        self.local_t[:, i] = t

    def _update(self, bones) -> None:
        for j in bones:
            p = self.parents[j]
            if p < 0:
                self.R[:, j] = self.local_R[:, j]
                self.t[:, j] = self.local_t[:, j]
            else:
                self.R[:, j] = self.R[:, p] @ self.local_R[:, j]
                self.t[:, j] = rotate(self.R[:, p], self.local_t[:, j]) + self.t[:, p]

    def update_global(self, i: int) -> None:
        """Global transforms of bone i and everything below it."""
        self._update(self.subtree[i])

    def update_chain(self, i: int, end: int) -> None:
        """Global transforms of bone i and the bones between it and its descendant ``end`` only
        (what CCD needs between its steps; the caller updates whole subtrees afterwards)."""
        path = [end]
        while path[-1] != i and path[-1] >= 0:
            path.append(int(self.parents[path[-1]]))
        if path[-1] != i:  # end is not below i
            self.update_global(i)
            return
        self._update(reversed(path))

    def _undo_ik(self, ik_bone: int, off: np.ndarray) -> None:
        """Frames ``off`` (F,) bool: the IK rotations of ``ik_bone``'s links back to identity."""
        links = [link.bone for link in self.model.bones[ik_bone].ik.links]
        for b in links:
            self.ik_rot[off, b] = IDENTITY
            self.update_local(b)
        for b in reversed(links):  # links run from the effector up: refresh from the top link down
            self.update_global(b)

    def evaluate(self, anim_rot: np.ndarray, anim_trans: np.ndarray,
                 ik_on: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Pose frames: global rotations (F, K, 3, 3) and bone heads (F, K, 3), file frame, from
        animated local rotations (F, K, 4) and translations (F, K, 3); (K, ...) inputs give (K, ...).
        ``ik_on`` (F, K) bool: IK bones that solve at each frame (default all); where an IK bone
        is off, its links keep their animated rotations (the VMD's show/IK keys)."""

        single = np.ndim(anim_rot) == 2
        if single:
            anim_rot, anim_trans = np.asarray(anim_rot)[None], np.asarray(anim_trans)[None]
            ik_on = None if ik_on is None else np.asarray(ik_on)[None]
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
                    if ik_on is not None and not ik_on[:, i].all():
                        self._undo_ik(i, ~np.asarray(ik_on[:, i], bool))
                    self.update_global(i)
        if single:
            return self.R[0].copy(), self.t[0].copy()
        return self.R.copy(), self.t.copy()
