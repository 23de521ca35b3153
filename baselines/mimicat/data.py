"""Dataset readers of the ``shape`` and ``prior`` stages: rest and posed meshes, keypoints, rotations.

Everything is expressed in a character's **rest frame**: minus the centre of its rest mesh's
bounding box, divided by the box's largest side (so a snake and a humanoid are the same size).
Posed meshes come from the dataset's clips by linear blend skinning
(:func:`mimicbench.geometry.skinning.linear_blend_skinning`, the dataset's Eq. 1). Every draw is a
function of the ``numpy.random.Generator`` passed in, so an epoch repeats for a seed.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimicbench.geometry.quaternion import quat_to_matrix
from mimicbench.schemas.errors import UserError

SPLITS = ("train", "val", "test", "all")


def rest_frame(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) of the rest mesh's bounding box and its largest side (metres), both float64."""
    v = np.asarray(vertices, np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or not len(v):
        raise ValueError(f"vertices: expected (N, 3) with N > 0, got {v.shape}")
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float((hi - lo).max())
    if not size > 0:
        raise ValueError("vertices: a mesh with zero extent has no rest frame")
    return (lo + hi) / 2.0, size


@dataclass
class Character:
    """One character with its clips, ready for sampling.

    Attributes:
        character_id: stable ID.
        vertices: (N, 3) float64 rest vertices, metres; faces: (M, 3) int64.
        keypoints: (K, 3) float64 rest joint heads; parents: (K,) int64, -1 for roots.
        weights: :class:`mimicbench.schemas.weights.SparseWeights` (N rows).
        centre: (3,) rest bounding-box centre; size: its largest side (metres).
        motions: list of (F, K, 7) float32 transforms (q_w, q_x, q_y, q_z, t_x, t_y, t_z) per clip.
        scales: list of (F, K, 6) float32 or None, one per clip (the ``scale`` column).
    """

    character_id: str
    vertices: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray
    parents: np.ndarray
    weights: object
    centre: np.ndarray
    size: float
    motions: list = field(default_factory=list)
    scales: list = field(default_factory=list)

    def normalised(self, points: np.ndarray) -> np.ndarray:
        """Points (..., 3) metres -> rest frame, float32."""
        return ((np.asarray(points, np.float64) - self.centre) / self.size).astype(np.float32)

    def posed_vertices(self, motion: int, frame: int) -> np.ndarray:
        """(N, 3) float32 vertices of clip ``motion`` at ``frame`` (metres), by LBS; ``motion`` -1: rest."""
        from mimicbench.geometry.skinning import linear_blend_skinning

        if motion < 0:
            return self.vertices.astype(np.float32)
        scale = self.scales[motion]
        return linear_blend_skinning(self.vertices, self.keypoints, self.weights, self.motions[motion][frame],
                                     None if scale is None else scale[frame])


_CACHE: dict = {}


def read_characters(dataset, split: str = "train") -> list[Character]:
    """Characters of ``split`` (or ``all``) that have a mesh, with their clips, sorted by ID.

    Cached per process (dataset folder, split, manifest modification time).

    Raises:
        UserError: unknown split, or no character with a mesh in that split.
    """
    from mimicbench.schemas.shards import has_table, read_records

    if split not in SPLITS:
        raise UserError(f"data.split: expected one of {', '.join(SPLITS)}, got {split!r}")
    root = Path(dataset)
    manifest = root / "manifest.json"
    key = (str(root.resolve()), split, manifest.stat().st_mtime_ns if manifest.is_file() else None)
    if key in _CACHE:
        return _CACHE[key]
    records = [c for c in read_records(root, "characters") if len(c.faces) and split in ("all", c.split)]
    if not records:
        raise UserError(f"{root}: no character with a mesh in split {split!r}; pick another with "
                        f"--set data.split=all (or train, val, test)")
    by_id: dict[str, Character] = {}
    for c in sorted(records, key=lambda r: r.character_id):
        centre, size = rest_frame(c.vertices)
        by_id[c.character_id] = Character(c.character_id, np.asarray(c.vertices, np.float64),
                                          np.asarray(c.faces, np.int64), np.asarray(c.keypoints, np.float64),
                                          np.asarray(c.parents, np.int64), c.weights, centre, size)
    if has_table(root, "motions"):
        for m in sorted(read_records(root, "motions"), key=lambda r: r.motion_id):
            ch = by_id.get(m.character_id)
            if ch is None or m.num_frames < 1:
                continue
            if m.num_joints != len(ch.parents):
                raise UserError(f"{root}: motion {m.motion_id} has {m.num_joints} joints, its character "
                                f"{m.character_id} has {len(ch.parents)}")
            ch.motions.append(np.asarray(m.transforms, np.float32))
            ch.scales.append(None if m.scale is None else np.asarray(m.scale, np.float32))
    out = list(by_id.values())
    _CACHE[key] = out
    return out


def draw_poses(characters: list[Character], frames_per_motion: int, rng: np.random.Generator,
               include_rest: bool) -> list[tuple[int, int, int]]:
    """One epoch's (character index, clip index or -1 for rest, frame) draws, in a fixed order.

    Each clip gives ``frames_per_motion`` frames drawn uniformly (with replacement); with
    ``include_rest`` each character's rest mesh is one more item.
    """
    items = []
    for ci, ch in enumerate(characters):
        if include_rest:
            items.append((ci, -1, 0))
        for mi, clip in enumerate(ch.motions):
            for f in rng.integers(0, len(clip), size=frames_per_motion):
                items.append((ci, mi, int(f)))
    return items


def vertex_points(character: Character, vertices: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 3) float32: ``count`` vertices drawn at random (rest or posed), in the rest frame."""
    idx = rng.choice(len(vertices), size=count, replace=len(vertices) < count)
    return character.normalised(vertices[idx])


def shape_example(character: Character, motion: int, frame: int, rng: np.random.Generator, points: int,
                  queries: int, surface_samples: int) -> dict:
    """One autoencoder example of a rest (``motion`` -1) or posed mesh.

    Returns:
        ``points`` (P, 3) encoder input (random vertices); ``queries`` (Q, 3): a quarter near the
        surface (Gaussian noise 0.01), a quarter farther (0.05), the rest uniform in [-0.6, 0.6]^3;
        ``distances`` (Q,) unsigned distance of each query to the surface, measured to
        ``surface_samples`` area-uniform surface points (trimesh) with a KD-tree (scipy); all
        float32 in the rest frame.
    """
    import trimesh
    from scipy.spatial import cKDTree

    verts = character.posed_vertices(motion, frame)
    mesh = trimesh.Trimesh(character.normalised(verts), character.faces, process=False)
    surface, _ = trimesh.sample.sample_surface(mesh, surface_samples, seed=int(rng.integers(2**31)))
    n_near = queries // 4
    picks = surface[rng.integers(0, len(surface), size=2 * n_near)]
    sigma = np.repeat([0.01, 0.05], n_near)[:, None]
    q = np.concatenate([picks + rng.normal(size=picks.shape) * sigma,
                        rng.uniform(-0.6, 0.6, size=(queries - 2 * n_near, 3))])
    distances, _ = cKDTree(surface).query(q)
    return {"points": vertex_points(character, verts, points, rng), "queries": q.astype(np.float32),
            "distances": distances.astype(np.float32)}


def prior_example(character: Character, motion: int, frame: int, rng: np.random.Generator, points: int,
                  max_keypoints: int | None = None) -> dict:
    """One pose-prior example: a posed frame with its rest mesh, keypoints and rotations.

    Returns (rest frame, float32 unless said):
        ``rest_points``, ``posed_points`` (P, 3): random vertices of the rest and posed mesh (the
        same vertex indices); ``rest`` (K, 3) rest keypoints; ``posed`` (K, 3) posed keypoints
        (the clip's t_k); ``parents`` (K,) int64 (-1 roots); ``rotations`` (K, 3, 3) the clip's
        world rotations R(q_k) relative to rest (Eq. 1); ``keep`` (K,) bool, the keypoints scored
        (all, or ``max_keypoints`` drawn at random when K is larger).
    """
    transforms = character.motions[motion][frame]
    verts = character.posed_vertices(motion, frame)
    idx = rng.choice(len(verts), size=points, replace=len(verts) < points)
    k = len(character.parents)
    keep = np.ones(k, bool)
    if max_keypoints is not None and k > max_keypoints:
        keep[:] = False
        keep[rng.choice(k, size=max_keypoints, replace=False)] = True
    return {"rest_points": character.normalised(character.vertices[idx]),
            "posed_points": character.normalised(verts[idx]),
            "rest": character.normalised(character.keypoints),
            "posed": character.normalised(transforms[:, 4:7]),
            "parents": character.parents.astype(np.int64),
            "rotations": quat_to_matrix(np.asarray(transforms[:, :4], np.float64)).astype(np.float32),
            "keep": keep}


def collate(examples: list[dict], pad_values: dict | None = None) -> dict:
    """Stack examples; arrays whose first axis differs (K) are zero-padded, with ``mask`` (B, K_max) bool.

    ``pad_values`` gives a fill value per key (e.g. ``{"parents": -1}``).
    """
    pad_values = pad_values or {}
    out: dict = {}
    for key in examples[0]:
        arrays = [np.asarray(e[key]) for e in examples]
        lengths = {len(a) for a in arrays}
        if len(lengths) == 1:
            out[key] = np.stack(arrays)
            continue
        kmax = max(lengths)
        fill = pad_values.get(key, 0)
        stacked = np.full((len(arrays), kmax) + arrays[0].shape[1:], fill, dtype=arrays[0].dtype)
        for b, a in enumerate(arrays):
            stacked[b, :len(a)] = a
        out[key] = stacked
    if "rest" in examples[0]:
        kmax = max(len(e["rest"]) for e in examples)
        mask = np.zeros((len(examples), kmax), bool)
        for b, e in enumerate(examples):
            mask[b, :len(e["rest"])] = True
        out["mask"] = mask
    return out
