"""What the apparel protocol's burn-in cap costs: the simulation itself started at the cap.

    python analyses/apparel_burn_in.py FULL_SIM CUT_SIM [--window-start 120]

``FULL_SIM``: ``datagen apparel`` output of long clips (simulated from their first frame).
``CUT_SIM``: ``datagen apparel`` output of the same characters with each clip ``<clip>`` cut to
``<clip>_from<S>`` (its frames S onward, simulated from rest at frame S, as a method started S
frames in sees it). For each clip and cut, the apparel vertices' mean distance over the window of
16 frames at ``--window-start`` (cm of the character scaled to 1.70 m, ground-truth apparel mask,
LBS of the simulated transforms): the cut simulation against the full one (what a perfect
simulator loses to starting at the cut: the cap's cost at a burn-in of window-start - S frames),
and, for scale, the kinematic clip against the full simulation (the whole lag).
"""
from __future__ import annotations

import argparse
import re
from collections import defaultdict

import numpy as np

from mimicbench.benchmark.protocols.apparel import REFERENCE_HEIGHT_CM, WINDOW
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.motion import SIM_SUFFIX
from mimicbench.schemas.shards import read_records


def _apparel(char, transforms: np.ndarray) -> np.ndarray:
    """(F, A, 3) apparel vertices of ``char`` posed by (F, K, 7) ``transforms``, metres."""
    mask = np.asarray(char.apparel_vertex_mask, bool)
    v = linear_blend_skinning(np.asarray(char.vertices, np.float32), np.asarray(char.keypoints, np.float32),
                              char.weights, np.asarray(transforms, np.float32))
    return np.asarray(v)[:, mask]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("full")
    ap.add_argument("cut")
    ap.add_argument("--window-start", type=int, default=120)
    a = ap.parse_args(argv)
    chars = {c.character_id: c for c in read_records(a.full, "characters")}
    full = {m.motion_id: m for m in read_records(a.full, "motions")}
    cut = {m.motion_id: m for m in read_records(a.cut, "motions") if m.motion_id.endswith(SIM_SUFFIX)}
    w = slice(a.window_start, a.window_start + WINDOW)
    by_cut = defaultdict(list)
    lag = {}
    for mid, m in sorted(cut.items()):
        base, start = re.fullmatch(r"(.*)_from(\d+)" + re.escape(SIM_SUFFIX), mid).groups()
        start = int(start)
        ref, kin = full.get(base + SIM_SUFFIX), full.get(base)
        if ref is None or kin is None or ref.num_frames < w.stop:
            continue
        c = chars[m.character_id]
        scale = REFERENCE_HEIGHT_CM / float(np.ptp(np.asarray(c.vertices)[:, 1]))
        truth = _apparel(c, ref.transforms[w])
        late = _apparel(c, m.transforms[w.start - start:w.stop - start])
        d = float(np.linalg.norm(late - truth, axis=-1).mean() * scale)
        lag[base] = float(np.linalg.norm(_apparel(c, kin.transforms[w]) - truth, axis=-1).mean() * scale)
        by_cut[a.window_start - start].append(d)
        print(f"{base}: burn-in {a.window_start - start:3d}: simulation started there {d:.3f} cm; kinematic {lag[base]:.3f} cm")
    for b, ds in sorted(by_cut.items()):
        print(f"burn-in {b} frames: mean {np.mean(ds):.3f} cm over {len(ds)} clips (kinematic lag {np.mean(list(lag.values())):.3f} cm)")


if __name__ == "__main__":
    main()
