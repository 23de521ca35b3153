"""Resampling to 5,000 faces: this stage (pymeshlab and fast backends) against Blender's route
(Decimate modifier + Data Transfer of vertex groups, face-interpolated), on zoo characters.

Prints seconds per character for each route, both routes' skinning transfer errors (% of
height, on frames of the characters' own clips), and the speed ratio last. Blender runs in a
child process (``benchmarks/resample_blender_child.py``); its time is measured inside Blender,
excluding the import of the data.

    python benchmarks/resample.py [--characters 8]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--characters", type=int, default=8)
    ap.add_argument("--faces", type=int, default=5000)
    args = ap.parse_args()
    from datagen.resample.character import resample_character, sample_frames
    from datagen.resample.clean import clean_mesh
    from datagen.resample.closest_point import closest_points
    from datagen.resample.reskin import interpolate_weights
    from datagen.resample.simplify import resample_to
    from datagen.resample.quality import transfer_error_percent
    from datagen.zoo import build_zoo
    from mimicbench.weights import SparseWeights
    from schemas.shards import read_records

    tmp = Path(tempfile.mkdtemp(prefix="mimicbench-resample-"))
    build_zoo(tmp / "zoo", args.characters, seed=0, progress=False)
    chars = read_records(tmp / "zoo", "characters")
    motions = {}
    for m in read_records(tmp / "zoo", "motions"):
        motions.setdefault(m.character_id, []).append(m)

    ours, full = {}, {}
    for backend in ("pymeshlab", "fast"):
        start = time.perf_counter()
        for c in chars:  # the same work as Blender's route: clean, simplify, re-skin (no quality report)
            clean = clean_mesh(c.vertices, c.faces, c.weights.to_dense(np.float64), c.apparel_vertex_mask)
            v, f, _ = resample_to(clean.vertices, clean.faces, args.faces, backend)
            interpolate_weights(clean.weights, clean.faces, closest_points(clean.vertices, clean.faces, v))
        core = (time.perf_counter() - start) / len(chars)
        start = time.perf_counter()
        out = [resample_character(c, motions[c.character_id], args.faces, backend) for c in chars]
        full[backend] = (time.perf_counter() - start) / len(chars)
        ours[backend] = (core, float(np.mean([o.meta["resample"]["transfer_error_pct"] for o in out])))

    arrays = {"count": len(chars), "target": args.faces}
    for i, c in enumerate(chars):
        arrays[f"v{i}"], arrays[f"f{i}"], arrays[f"w{i}"] = c.vertices.astype(float), c.faces, c.weights.to_dense()
    np.savez(tmp / "in.npz", **arrays)
    child = Path(__file__).with_name("resample_blender_child.py")
    subprocess.run([sys.executable, str(child), str(tmp / "in.npz"), str(tmp / "out.npz")], check=True,
                   capture_output=True, timeout=1800)
    res = np.load(tmp / "out.npz")
    errors = []
    for i, c in enumerate(chars):
        v, f, w = res[f"v{i}"], res[f"f{i}"], res[f"w{i}"]
        w = w / np.maximum(w.sum(1, keepdims=True), 1e-12)
        surface = closest_points(c.vertices.astype(float), c.faces, v)
        errors.append(transfer_error_percent(c.vertices.astype(float), c.faces, c.weights.to_dense(np.float64), v,
                                             SparseWeights.from_dense(np.maximum(w, 1e-12)), c.keypoints, surface,
                                             sample_frames(motions[c.character_id]), float(np.ptp(c.vertices[:, 1]))))
    blender = (float(res["seconds"].mean()), float(np.mean(errors)))
    for name, (sec, err) in (("blender decimate+data transfer", blender), ("mimicbench pymeshlab", ours["pymeshlab"]),
                             ("mimicbench fast", ours["fast"])):
        print(f"{name:32s} {sec:7.3f} s/character   transfer error {err:.3f} % of height")
    print(f"(with the quality report, Hausdorff and transfer error: pymeshlab {full['pymeshlab']:.3f}, "
          f"fast {full['fast']:.3f} s/character)")
    print(f"ratio blender / pymeshlab: {blender[0] / ours['pymeshlab'][0]:.2f}x; blender / fast: "
          f"{blender[0] / ours['fast'][0]:.2f}x")


if __name__ == "__main__":
    main()
