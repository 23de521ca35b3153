"""``--export obj,bvh`` for ingested assets: the rest mesh as .obj, each clip as .bvh (PokeAnimDB's
file convention), with the zoo's writers (dataset frame, Y up, metres)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mimicbench.datagen.zoo.export_bvh import write_bvh
from mimicbench.datagen.zoo.export_obj import write_obj


def end_sites(keypoints: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Bone tails for BVH End Sites (K, 3): continue each bone's direction from its parent by half
    its length (a root continues +Y by 5% of the skeleton's size)."""
    k = np.asarray(keypoints, np.float64)
    size = float(np.ptp(k, axis=0).max()) or 1.0
    tails = k + [0.0, 0.05 * size, 0.0]
    for j, p in enumerate(parents):
        if p >= 0:
            tails[j] = k[j] + 0.5 * (k[j] - k[p])
    return tails


def export_dataset(out_dir, characters, motions, formats) -> list[Path]:
    """Write ``out_dir/export/<stem>.obj`` and ``out_dir/export/<stem>/<clip>.bvh``; returns the paths."""
    out = Path(out_dir) / "export"
    written = []
    by_char: dict[str, list] = {}
    for m in motions:
        by_char.setdefault(m.character_id, []).append(m)
    for c in characters:
        stem = c.character_id.split("/", 1)[1]
        if "obj" in formats and len(c.faces):
            written.append(write_obj(out / f"{stem}.obj", c.vertices, c.faces, stem))
        if "bvh" in formats and (np.asarray(c.parents) < 0).sum() == 1:
            for m in by_char.get(c.character_id, []):
                safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in m.name)
                written.append(write_bvh(out / stem / f"{safe}.bvh", c.bone_names, c.parents, c.keypoints,
                                         end_sites(c.keypoints, c.parents), m.transforms, m.fps))
    return written
