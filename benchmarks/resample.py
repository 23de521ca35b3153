"""Resampling to 5,000 faces: this stage (pymeshlab and fast backends) against Blender's route
(Decimate modifier + Data Transfer of vertex groups, face-interpolated), on zoo characters at
their own resolution (11k-26k triangles) and subdivided once (4x, like dense artist meshes).

Two timings per route, in seconds per character:
- work: Blender's two modifiers applied, against this stage's clean + decimate + closest points
  + barycentric reskin;
- record to record: what a stage pays to turn a character record into a resampled one. For
  Blender: build the mesh and its vertex groups, the modifiers, read coordinates, triangles and
  weights back (the fastest bpy calls: ``foreach_set``/``foreach_get``, one ``VertexGroup.add``
  per influence). For this stage: ``resample_character``, quality report (Hausdorff and
  transfer error) included.
Blender runs in one child process (``benchmarks/resample_blender_child.py``); its start-up and
the loading of the arrays are not counted. Both routes' outputs are scored the same way against
the original mesh: skinning transfer error (% of height, on frames of the characters' own
clips) and vertex-sampled Hausdorff distance (% of height). The ratios are printed last.

    python benchmarks/resample.py [--characters 8] [--faces 5000]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def subdivided(record):
    """The character with every triangle split into four; weights interpolated at the midpoints."""
    import dataclasses

    import trimesh

    from mimicbench.schemas.weights import SparseWeights

    v, f, attr = trimesh.remesh.subdivide(record.vertices.astype(np.float64), record.faces,
                                          vertex_attributes={"w": record.weights.to_dense(np.float64)})
    w = SparseWeights.from_dense(attr["w"])
    mask = np.zeros(len(v), bool)
    return dataclasses.replace(record, vertices=v.astype(np.float32), faces=f.astype(np.int32),
                               weight_indices=w.indices, weight_values=w.values, apparel_vertex_mask=mask)


def score(record, motions, v, f, weights):
    """(transfer error, Hausdorff), % of height, of a resampled mesh against the original."""
    from mimicbench.datagen.resample.character import sample_frames
    from mimicbench.datagen.resample.closest_point import closest_points
    from mimicbench.datagen.resample.quality import hausdorff_percent, transfer_error_percent

    old_v = record.vertices.astype(np.float64)
    height = float(np.ptp(old_v[:, 1]))
    surface = closest_points(old_v, record.faces, v)
    err = transfer_error_percent(old_v, record.faces, record.weights, v, weights, record.keypoints, surface,
                                 sample_frames(motions), height)
    return err, hausdorff_percent(old_v, record.faces, v, f, height, surface)


def run_ours(chars, motions, faces, backend):
    """Seconds per character (work, record to record), mean transfer error and Hausdorff."""
    from mimicbench.datagen.resample.character import resample_character
    from mimicbench.datagen.resample.clean import clean_mesh
    from mimicbench.datagen.resample.closest_point import closest_points
    from mimicbench.datagen.resample.reskin import interpolate_weights
    from mimicbench.datagen.resample.simplify import resample_to

    start = time.perf_counter()
    for c in chars:
        clean = clean_mesh(c.vertices, c.faces, c.weights, c.apparel_vertex_mask)
        v, f, _, _ = resample_to(clean.vertices, clean.faces, faces, backend)
        interpolate_weights(clean.weights, clean.faces, closest_points(clean.vertices, clean.faces, v))
    work = (time.perf_counter() - start) / len(chars)
    start = time.perf_counter()
    out = [resample_character(c, motions[c.character_id], faces, backend) for c in chars]
    record = (time.perf_counter() - start) / len(chars)
    scores = [score(c, motions[c.character_id], o.vertices.astype(np.float64), o.faces, o.weights)
              for c, o in zip(chars, out)]
    return work, record, *np.mean(scores, axis=0)


def run_blender(chars, motions, faces, tmp):
    """The same for Blender's route, in a child process."""
    from mimicbench.schemas.weights import SparseWeights

    arrays = {"count": len(chars), "target": faces}
    for i, c in enumerate(chars):
        arrays[f"v{i}"], arrays[f"f{i}"] = c.vertices.astype(np.float64), c.faces
        arrays[f"wi{i}"], arrays[f"wv{i}"] = c.weight_indices, c.weight_values
    np.savez(tmp / "in.npz", **arrays)
    child = Path(__file__).with_name("resample_blender_child.py")
    subprocess.run([sys.executable, str(child), str(tmp / "in.npz"), str(tmp / "out.npz")], check=True,
                   capture_output=True, timeout=3600)
    res = np.load(tmp / "out.npz")
    scores = []
    for i, c in enumerate(chars):
        w = res[f"w{i}"]
        w = SparseWeights.from_dense(w + 1e-12 * (w.sum(1, keepdims=True) <= 0))
        scores.append(score(c, motions[c.character_id], res[f"v{i}"], res[f"f{i}"], w))
    return float(res["modifier_seconds"].mean()), float(res["route_seconds"].mean()), *np.mean(scores, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--characters", type=int, default=8)
    ap.add_argument("--faces", type=int, default=5000)
    args = ap.parse_args()
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import read_records

    tmp = Path(tempfile.mkdtemp(prefix="mimicbench-resample-"))
    build_zoo(tmp / "zoo", args.characters, seed=0, progress=False)
    chars = read_records(tmp / "zoo", "characters")
    motions = {}
    for m in read_records(tmp / "zoo", "motions"):
        motions.setdefault(m.character_id, []).append(m)
    print(f"{'meshes':18s} {'route':32s} {'work s':>8s} {'record s':>9s} {'transfer %':>11s} {'Hausdorff %':>12s}")
    ratios = []
    for label, group in (("zoo", chars), ("zoo x4", [subdivided(c) for c in chars])):
        label = f"{label} ({int(np.mean([len(c.faces) for c in group]) / 1000)}k tris)"
        rows = {"blender decimate+data transfer": run_blender(group, motions, args.faces, tmp)}
        for backend in ("pymeshlab", "fast"):
            rows[f"mimicbench {backend}"] = run_ours(group, motions, args.faces, backend)
        for name, (work, record, err, haus) in rows.items():
            print(f"{label:18s} {name:32s} {work:8.3f} {record:9.3f} {err:11.3f} {haus:12.3f}")
        blender, fast = rows["blender decimate+data transfer"], rows["mimicbench fast"]
        ratios.append(f"{label}: work {blender[0] / fast[0]:.1f}x, record to record {blender[1] / fast[1]:.1f}x")
    print("ratio blender / mimicbench fast (seconds per character): " + "; ".join(ratios))


if __name__ == "__main__":
    main()
