"""Apparel from the file's physics on Gene.pmx: this stage's file physics
(:mod:`mimicbench.datagen.apparel.file_physics`, the model's 87 rigid bodies and 92 joints) against the
chain defaults (:mod:`mimicbench.datagen.apparel.setup`, the zoo's chains on the same apparel bones), on
the same clips, with the same substeps (240 Hz), solver iterations and relaxation (30 frames).

Clips: Gene_stand.vmd (121 frames, ingested with it), and a quarter turn of the whole body in
0.2 s then held (30 frames). Printed per clip and route: CPU seconds (process time, so other
work on the machine does not count), secondary motion (mean and worst frame, % of height),
apparel vertices newly inside the body (mean, %; the kinematic clip's beside it), largest edge
stretch and vertex acceleration. The ratio of CPU seconds file / defaults is printed last.

    python benchmarks/apparel_file.py [--assets ../shared/assets]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def _turn(c, frames: int = 30):
    from mimicbench.schemas.motion import MotionRecord

    angles = np.minimum(np.arange(frames) / 6, 1.0) * (np.pi / 2)
    root = np.asarray(c.keypoints[0], np.float64)
    out = []
    for a in angles:
        rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        t = (c.keypoints - root) @ rot.T + root
        out.append(np.concatenate([np.tile([np.cos(a / 2), 0, np.sin(a / 2), 0], (len(t), 1)), t], 1))
    return MotionRecord(f"{c.character_id}/turn", c.character_id, "turn", c.split, 30.0, frames, c.num_joints,
                        np.array(out, np.float32), "benchmark")


def main() -> None:
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.file_physics import simulate_file_motion
    from mimicbench.datagen.apparel.params import ApparelParams
    from mimicbench.datagen.apparel.quality import clip_quality
    from mimicbench.datagen.apparel.selection import dominant_bone
    from mimicbench.datagen.apparel.setup import character_physics, simulate_motion
    from mimicbench.datagen.ingest.runner import ingest_assets
    from mimicbench.schemas.shards import read_records

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--assets", default=str(Path(__file__).resolve().parents[2] / "shared" / "assets"))
    args = ap.parse_args()
    params = ApparelParams()
    with tempfile.TemporaryDirectory() as tmp:
        ingest_assets([Path(args.assets) / "mmd" / "Gene.pmx"], Path(tmp) / "gene", progress=False)
        c = read_records(Path(tmp) / "gene", "characters")[0]
        stand = read_records(Path(tmp) / "gene", "motions")[0]
        bodies = sorted(read_records(Path(tmp) / "gene", "rigid_bodies"), key=lambda b: b.body_index)
        joints = sorted(read_records(Path(tmp) / "gene", "joints"), key=lambda j: j.joint_index)
    bones, vertices = np.asarray(c.apparel_bone_mask, bool), np.asarray(c.apparel_vertex_mask, bool)
    pieces = body_pieces(c.vertices, c.keypoints, dominant_bone(c.weights, c.num_joints), ~bones)
    ratios = []
    for clip in (stand, _turn(c)):
        kin = clip_quality(c.vertices, c.faces, c.keypoints, c.weights, vertices, pieces, clip.transforms,
                           clip.transforms, clip.fps, c.height)
        seconds = {}
        for route in ("file", "defaults"):
            start = time.process_time()
            if route == "file":
                _, q = simulate_file_motion(c, bodies, joints, clip, bones, vertices, 240.0, 30, params.simulation)
            else:
                _, q = simulate_motion(c, character_physics(c, bones, vertices, params), clip, params, 240.0, 30)
            seconds[route] = time.process_time() - start
            print(f"{clip.name:6s} {route:8s} {clip.num_frames:4d} frames  cpu {seconds[route]:6.1f} s  "
                  f"secondary {q['secondary_motion_pct']:.3f} % (worst {q['secondary_motion_max_pct']:.3f} %)  "
                  f"new inside {q['new_inside_pct']:.2f} % (kinematic {kin['new_inside_pct']:.2f} %)  "
                  f"stretch {q['max_edge_stretch']:.2f} (kinematic {kin['max_edge_stretch']:.2f})  "
                  f"accel {q['max_accel']:.1f} m/s^2  links {q['links']}")
        ratios.append(seconds["file"] / seconds["defaults"])
    print("cpu seconds file / defaults: " + ", ".join(f"{r:.2f}" for r in ratios))


if __name__ == "__main__":
    main()
