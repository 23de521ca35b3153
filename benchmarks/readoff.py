"""The shared read-off (joint fit of all bones, :func:`mimicbench.geometry.transform_estimation.estimate_transforms`)
against per-bone weighted Kabsch (:func:`mimicbench.geometry.kabsch.kabsch_transforms`), its peer, on a
dataset's characters posed by linear blend skinning with frames of their own clips.

Per character: bones, vertices, the largest rotation error of each estimator against the
transforms the mesh was posed with (degrees, supported bones), and the median seconds per frame
of each. The ratio (joint fit / Kabsch seconds) of the characters with the most bones is printed last.

    python benchmarks/readoff.py DATA [--frames 6] [--characters zoo/apparel-0000,zoo/apparel-0001] [--noise 0.003]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="dataset with characters and motions (e.g. a 5,000-face zoo)")
    ap.add_argument("--frames", type=int, default=6, help="frames per character (default 6)")
    ap.add_argument("--characters", default=None, help="comma-separated character IDs (default: all)")
    ap.add_argument("--noise", type=float, default=0.0,
                    help="Gaussian noise added to the posed vertices, fraction of the height (default 0: exact "
                         "LBS poses, as a forward leg's source; 0.003 is a mesh no rig poses exactly, as a return leg's)")
    args = ap.parse_args()

    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.geometry.kabsch import kabsch_transforms
    from mimicbench.geometry.quaternion import quat_angle
    from mimicbench.geometry.transform_estimation import estimate_transforms
    from mimicbench.schemas.dataset import Dataset

    ev = EvalData.load(args.data)
    wanted = set(args.characters.split(",")) if args.characters else set(ev.characters)
    table = Dataset.of(args.data).read_table("motions", columns=["character_id", "num_frames", "num_joints",
                                                                  "transforms"]).to_pylist()
    rows = []
    for cid, char in sorted(ev.characters.items(), key=lambda kv: len(kv[1].rig.parents)):
        if cid not in wanted:
            continue
        rig = char.rig
        frames = [f for m in table if m["character_id"] == cid
                  for f in np.asarray(m["transforms"], np.float32).reshape(m["num_frames"], m["num_joints"], 7)[1::9]]
        frames = frames[:args.frames]
        if not frames:
            continue
        err = {"joint": 0.0, "kabsch": 0.0}
        sec = {"joint": [], "kabsch": []}
        rng = np.random.default_rng(0)
        for frame in frames:
            posed = ev.posed(char, frame) + rng.normal(size=rig.vertices.shape) * args.noise * rig.height
            for name, fn in (("joint", estimate_transforms), ("kabsch", kabsch_transforms)):
                start = time.perf_counter()
                est, supported = fn(rig.vertices, posed, rig.weights, rig.keypoints)
                sec[name].append(time.perf_counter() - start)
                angle = np.degrees(quat_angle(est[supported, :4], frame[supported, :4].astype(np.float64)))
                err[name] = max(err[name], float(angle.max()))
        rows.append((cid, len(rig.parents), len(rig.vertices), len(rig.faces), err, {k: float(np.median(v)) for k, v in sec.items()}))
        print(f"{cid:28s} K={len(rig.parents):3d} N={len(rig.vertices):5d} faces={len(rig.faces):5d}  "
              f"max error: joint {err['joint']:.1e} deg, Kabsch {err['kabsch']:.1f} deg;  "
              f"s/frame: joint {rows[-1][5]['joint']:.3f}, Kabsch {rows[-1][5]['kabsch']:.4f}", flush=True)
    if rows:
        cid, k, _, _, _, s = rows[-1]
        print(f"joint fit / Kabsch seconds on {cid} ({k} bones): {s['joint'] / s['kabsch']:.0f}x")


if __name__ == "__main__":
    main()
