"""Data for the MMDMC reference: characters prepared once (unit-height frame, body joints,
geodesics), and the training dataset's clip pairs (kinematic clip, ``<clip>@sim``).

A training dataset is one written by ``mimicbench datagen apparel``: characters with apparel
bones and, per clip, the kinematic motion and the simulated one. Ground truth of a frame is the
simulated clip posed by LBS with the dataset's weights. The body module's target is the
kinematic clip posed with each apparel bone's weight moved onto the body bone its chain hangs
from (its nearest body ancestor; :func:`body_target_weights`): the ground truth itself on body
vertices, and elsewhere the apparel carried rigidly by the body part it is attached to (what a
skinning of body joints can reach, and what the apparel module then displaces).

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimicbench.baselines.mmdmc.bone_distance import bone_distances, mesh_box
from mimicbench.baselines.mmdmc.geodesic import geodesic_distances
from mimicbench.baselines.mmdmc.piece_prior import piece_prior
from mimicbench.baselines.mmdmc.rig import attachment_bones
from mimicbench.geometry.mesh import unique_edges, unit_height_frame
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.motion import SIM_SUFFIX
from mimicbench.schemas.weights import SparseWeights


@dataclass
class Prepared:
    """A character in the form the modules read.

    Attributes:
        character_id: stable ID.
        rest: (N, 3) float32 rest vertices, metres.
        faces: (M, 3) int32.
        keypoints: (K, 3) float32 rest joints, metres.
        parents: (K,) int32.
        body: (K,) bool body bones (the request's ``body_bones``).
        centre: (3,) float64, height: float: the unit-height frame (rest bounding-box centre, Y extent).
        geo: (N, Kb) float32 geodesic distance to each body joint's anchor, divided by the height.
        bone: (N, Kb) float32 distance to each body bone's segments, divided by the height
            (:mod:`mimicbench.baselines.mmdmc.bone_distance`).
        edges: (E, 2) int64 unique mesh edges.
        prior: (N, Kb) float32 piece prior on f_s's scores, NaN rows where no piece wraps a bone
            (:mod:`mimicbench.baselines.mmdmc.piece_prior`).
        apparel: (N,) bool ground-truth apparel vertices (training data only).
        weights: ground-truth skin weights (training data only).
    """

    character_id: str
    rest: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray
    parents: np.ndarray
    body: np.ndarray
    centre: np.ndarray
    height: float
    geo: np.ndarray
    bone: np.ndarray
    edges: np.ndarray
    prior: np.ndarray
    apparel: np.ndarray | None = None
    weights: SparseWeights | None = None
    cache: dict = field(default_factory=dict, repr=False)

    @property
    def body_index(self) -> np.ndarray:
        """(Kb,) indices of the body bones."""
        return np.flatnonzero(self.body)

    def norm(self, points: np.ndarray) -> np.ndarray:
        """Metres -> unit-height frame, (..., 3) float32."""
        return ((np.asarray(points, np.float64) - self.centre) / self.height).astype(np.float32)

    @property
    def rest_norm(self) -> np.ndarray:
        return self.norm(self.rest)

    @property
    def joints_norm(self) -> np.ndarray:
        """(Kb, 3) rest body joints in the unit-height frame."""
        return self.norm(self.keypoints[self.body])


def prepare(character_id: str, vertices, faces, keypoints, parents, body, bridge_neighbours: int = 4,
            apparel=None, weights: SparseWeights | None = None) -> Prepared:
    """A :class:`Prepared` character (computes G and the bone distances over the body joints)."""
    v = np.array(vertices, np.float32)  # own writable copies: torch tensors are made from them
    body = np.array(body, bool)
    if body.shape != (len(keypoints),) or not body.any():
        raise ValueError(f"{character_id}: expected a body-bone mask of {len(keypoints)} entries with at least one "
                         f"body bone, got shape {body.shape} with {int(body.sum())} body bones")
    centre, height = unit_height_frame(v)
    geo = geodesic_distances(v, faces, np.asarray(keypoints)[body], bridge_neighbours) / height
    bone = bone_distances(v, keypoints, parents, body, mesh_box(v)) / height
    prior = piece_prior((v - centre) / height, faces, bone, (np.asarray(keypoints)[body] - centre) / height, parents, body)
    return Prepared(character_id, v, np.array(faces, np.int32), np.array(keypoints, np.float32),
                    np.array(parents, np.int32), body, centre, height, geo.astype(np.float32),
                    bone.astype(np.float32), unique_edges(faces), prior, None if apparel is None else np.asarray(apparel, bool), weights)


@dataclass
class ClipPair:
    """A clip of a training character: kinematic and simulated transforms, each (F, K, 7) (simulated
    None when the data was loaded for the body stage alone)."""

    character_id: str
    name: str
    kinematic: np.ndarray
    simulated: np.ndarray | None

    @property
    def frames(self) -> int:
        return len(self.kinematic)


@dataclass
class TrainingData:
    """Prepared training characters and their clip pairs."""

    characters: dict[str, Prepared]
    clips: list[ClipPair]

    @classmethod
    def load(cls, dataset, split: str = "all", bridge_neighbours: int = 4, simulated: bool = True) -> "TrainingData":
        """Characters of ``split`` (``all``: every split) that have apparel bones and simulated clips.

        With ``simulated=False`` (the body stage, whose target needs only the kinematic clip) every
        kinematic clip of a character with apparel bones is a :class:`ClipPair` with ``simulated``
        None, so f_s can train on a zoo that ``datagen apparel`` never simulated.
        """
        from mimicbench.schemas.shards import read_records

        dataset = Path(dataset)
        chars = {c.character_id: c for c in read_records(dataset, "characters")
                 if len(c.faces) and np.asarray(c.apparel_bone_mask, bool).any() and split in ("all", c.split)}
        by_char: dict[str, dict] = {}
        for m in read_records(dataset, "motions"):
            if m.character_id in chars:
                by_char.setdefault(m.character_id, {})[m.name] = m
        clips = []
        for cid in sorted(by_char):
            k = len(chars[cid].parents)
            for name, sim in sorted(by_char[cid].items()):
                if not simulated:
                    if not name.endswith(SIM_SUFFIX):
                        clips.append(ClipPair(cid, name, np.asarray(sim.transforms, np.float32).reshape(-1, k, 7), None))
                    continue
                kin = by_char[cid].get(name[: -len(SIM_SUFFIX)]) if name.endswith(SIM_SUFFIX) else None
                if kin is None or kin.num_frames != sim.num_frames:
                    continue
                clips.append(ClipPair(cid, kin.name, np.asarray(kin.transforms, np.float32).reshape(-1, k, 7),
                                      np.asarray(sim.transforms, np.float32).reshape(-1, k, 7)))
        if not clips and not simulated:
            raise ValueError(f"{dataset}: no character with apparel bones and a clip in split {split!r}; make a zoo "
                             f"with `mimicbench zoo --out {dataset} --categories apparel`")
        if not clips:
            raise ValueError(f"{dataset}: no character with apparel bones and a simulated clip ('<clip>@sim') in "
                             f"split {split!r}; make one with `mimicbench datagen apparel IN {dataset}`")
        used = sorted({c.character_id for c in clips})
        prepared = {}
        for cid in used:
            c = chars[cid]
            prepared[cid] = prepare(cid, c.vertices, c.faces, c.keypoints, c.parents,
                                    ~np.asarray(c.apparel_bone_mask, bool), bridge_neighbours,
                                    c.apparel_vertex_mask, c.weights)
        return cls(prepared, clips)


def posed(character: Prepared, transforms: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Ground truth (..., n, 3) float32 metres: LBS with the dataset's weights of transforms (..., K, 7),
    for the vertices ``rows`` (all by default)."""
    w = character.weights if rows is None else character.weights.take(rows)
    v = character.rest if rows is None else character.rest[rows]
    return linear_blend_skinning(v, character.keypoints, w, transforms).astype(np.float32)


def body_target_weights(character: Prepared) -> np.ndarray:
    """(N, Kb) float32 dense weights over the body bones (cached on the character): the dataset's,
    with each apparel bone's weight moved onto the body bone its chain hangs from
    (:func:`attachment_bones`); a chain attached to no body bone gives its weight to the vertex's
    nearest body bone (:func:`mimicbench.baselines.body_only.nearest_body_bone`)."""
    if "body_weights" not in character.cache:
        from mimicbench.baselines.body_only import nearest_body_bone
        from mimicbench.schemas.weights import as_dense

        k = len(character.parents)
        dense = as_dense(character.weights, k).astype(np.float64)
        attach = attachment_bones(character.parents, character.body)
        out = dense * character.body[None, :]
        for bone in np.flatnonzero(~character.body):
            col = dense[:, bone]
            rows = np.flatnonzero(col > 0)
            if not len(rows):
                continue
            if attach[bone] >= 0:
                out[rows, attach[bone]] += col[rows]
            else:
                near = nearest_body_bone(character.rest[rows], character.keypoints, character.parents, character.body)
                np.add.at(out, (rows, near), col[rows])
        character.cache["body_weights"] = out[:, character.body].astype(np.float32)
    return character.cache["body_weights"]
