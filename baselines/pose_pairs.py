"""Training examples of the re-implemented published baselines (NPT, CGT, SFPT), drawn from a zoo.

A dataset's characters with a mesh and their clips (:func:`mimicbench.baselines.mimicat.transfer_data.read_transfer_pool`)
give two kinds of example:

- **same-skeleton pairs** (characters with equal ``skeleton_id``: the zoo's H2H family, any other
  shared rig): the source posed by one frame of one of its clips, and the target posed by the
  same pose carried over bone by bone, the h2h protocol's own ground truth
  (:func:`mimicbench.benchmark.protocols.h2h.ground_truth_transforms`). NPT's and CGT's supervised loss,
  SFPT's cross-transfer term.
- **self examples** of any character (source = target): SFPT's reconstruction and skinning terms on
  every category.

Posed meshes are the dataset's Eq. 1 (:func:`mimicbench.geometry.skinning.linear_blend_skinning`). Every draw
is a function of the generator passed in, so an epoch repeats for a seed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.runtime.errors import UserError


@dataclass
class PoseExample:
    """One training example, metres, dataset frame.

    Attributes:
        source_id, target_id: character IDs (equal for a self example).
        source_rest, source_posed: (Ns, 3) float32.
        target_rest, target_posed: (Nt, 3) float32 (``target_posed`` the ground truth).
        source_weights, target_weights: dense (N, K) float32 skin weights of each rig.
    """

    source_id: str
    target_id: str
    source_rest: np.ndarray
    source_posed: np.ndarray
    target_rest: np.ndarray
    target_posed: np.ndarray
    source_weights: np.ndarray
    target_weights: np.ndarray


class PosePool:
    """A dataset's characters and clips, with the pairs that share a skeleton.

    Attributes:
        records: character ID -> :class:`mimicbench.schemas.character.CharacterRecord` (with a mesh and a clip).
        motions: character ID -> list of (F, K, 7) float32 clips.
        pairs: sorted list of ordered (source ID, target ID) pairs sharing a skeleton, source != target.
        ids: sorted character IDs.
    """

    def __init__(self, records: dict, motions: dict):
        self.records = {k: records[k] for k in sorted(motions)}
        self.motions = motions
        self.ids = sorted(self.records)
        groups: dict[str, list[str]] = {}
        for cid in self.ids:
            sid = self.records[cid].skeleton_id
            if sid:
                groups.setdefault(sid, []).append(cid)
        self.pairs = sorted((s, t) for g in groups.values() for s in g for t in g if s != t)
        self._dense: dict[str, np.ndarray] = {}

    @classmethod
    def load(cls, dataset, split: str = "all") -> "PosePool":
        """The pool of ``dataset`` (cached per process, dataset folder and split)."""
        from mimicbench.baselines.mimicat.transfer_data import read_transfer_pool

        key = (str(dataset), split)
        if key not in _CACHE:
            try:
                records, motions = read_transfer_pool(dataset, split)
            except ValueError as exc:
                raise UserError(str(exc)) from exc
            _CACHE[key] = cls(records, motions)
        return _CACHE[key]

    def weights(self, cid: str) -> np.ndarray:
        """Dense (N, K) float32 skin weights of character ``cid``."""
        if cid not in self._dense:
            self._dense[cid] = self.records[cid].weights.to_dense(np.float32)
        return self._dense[cid]

    def draw_pose(self, cid: str, rng: np.random.Generator) -> np.ndarray:
        """(K, 7) float32: one frame of one of ``cid``'s clips, uniformly."""
        clips = self.motions[cid]
        clip = clips[int(rng.integers(len(clips)))]
        return clip[int(rng.integers(len(clip)))]

    def posed(self, cid: str, transforms: np.ndarray) -> np.ndarray:
        """(N, 3) float32 character ``cid`` posed by ``transforms`` (K, 7) (Eq. 1)."""
        from mimicbench.geometry.skinning import linear_blend_skinning

        r = self.records[cid]
        return linear_blend_skinning(r.vertices, r.keypoints, r.weights, transforms).astype(np.float32)

    def example(self, source: str, target: str, rng: np.random.Generator) -> PoseExample:
        """A random pose of ``source`` and the same pose on ``target`` (same skeleton, or the same character)."""
        from mimicbench.benchmark.protocols.h2h import ground_truth_transforms

        s, t = self.records[source], self.records[target]
        pose = self.draw_pose(source, rng)
        target_pose = pose if source == target else ground_truth_transforms(s, t, pose)
        return PoseExample(source, target, np.asarray(s.vertices, np.float32), self.posed(source, pose),
                           np.asarray(t.vertices, np.float32), self.posed(target, target_pose),
                           self.weights(source), self.weights(target))

    def require_pairs(self, dataset) -> None:
        """Raise a UserError when no two characters share a skeleton (NPT and CGT need such pairs)."""
        if not self.pairs:
            raise UserError(f"{dataset}: no two characters with a mesh and clips share a skeleton_id; NPT and CGT "
                            f"train on same-skeleton pairs (a zoo's H2H family: `mimicbench zoo` with humanoids)")


_CACHE: dict = {}


def subsample(n: int, points: int, rng: np.random.Generator) -> np.ndarray:
    """(min(points, n),) sorted vertex rows drawn without replacement (all of them when ``points`` <= 0)."""
    if points <= 0 or points >= n:
        return np.arange(n)
    return np.sort(rng.choice(n, size=points, replace=False))


def neighbours(points: np.ndarray, k: int) -> np.ndarray:
    """(P, k) int64 nearest neighbours of each point (P, 3), the point itself first: the EdgeConv
    neighbourhoods (MMDMC's :func:`mimicbench.baselines.mmdmc.apparel.component_neighbours` over one component)."""
    from mimicbench.baselines.mmdmc.apparel import component_neighbours

    return component_neighbours(points, np.zeros(len(points), np.int64), k)


def knn_pairs(points: np.ndarray, k: int) -> np.ndarray:
    """(P*k, 2) int64 pairs of each point (P, 3) with its k nearest others: the edges the edge terms
    use on a vertex subsample, where mesh edges are mostly cut."""
    nb = neighbours(points, k + 1)
    return np.stack([np.repeat(np.arange(len(points)), k), nb[:, 1:].reshape(-1)], 1).astype(np.int64)
