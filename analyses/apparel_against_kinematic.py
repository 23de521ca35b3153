"""Issue 33: each simulated clip's quality beside the same measures of its kinematic clip.

The apparel stage records a clip's quality (:mod:`mimicbench.datagen.apparel.quality`) in the character's
``meta["apparel"]``; the penetration and stretch of the clip it came from are not recorded. On
real motions much of the penetration is the skinned clip's own (Gene's cloak inside the arms'
pieces in poses far from its rest), so this prints, per clip of OUT (a ``datagen apparel``
output folder), the stage's figures beside :func:`~mimicbench.datagen.apparel.quality.clip_quality` of the
kinematic clip taken as the simulated one (same body pieces, same apparel vertices), and for
each folder the medians and the clips over the jitter bound (3x the larger of the apparel's
kinematic peak and that of the body it touches, :func:`~mimicbench.datagen.apparel.quality.over_jitter_bound`). A second folder (the same clips simulated with other ``--params``) adds its
figures beside the first's.

    PYTHONPATH=. python analyses/apparel_against_kinematic.py OUT [OTHER_OUT]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mimicbench.datagen.apparel.body_shapes import body_pieces
from mimicbench.datagen.apparel.quality import clip_quality, over_jitter_bound
from mimicbench.datagen.apparel.selection import dominant_bone
from mimicbench.datagen.apparel.stage import _apparel_masks
from mimicbench.schemas.motion import SIM_SUFFIX
from mimicbench.schemas.shards import read_records

SHOWN = ("max_accel", "p99_accel", "new_inside_pct", "new_inside_max_pct", "max_edge_stretch")


def recorded(out: Path) -> dict[str, dict]:
    """``{motion_id of the kinematic clip: the stage's quality}`` of every simulated clip in ``out``."""
    clips = {}
    for c in read_records(out, "characters"):
        for clip, q in (((c.meta or {}).get("apparel") or {}).get("clips") or {}).items():
            clips[f"{c.character_id}/{clip}"] = q
    return clips


def kinematic(out: Path, wanted: set[str]) -> dict[str, dict]:
    """``{motion_id: quality of the kinematic clip taken as the simulated one}`` for ``wanted``."""
    chars = {c.character_id: c for c in read_records(out, "characters")}
    result = {}
    for m in read_records(out, "motions"):
        if m.motion_id not in wanted or m.name.endswith(SIM_SUFFIX):
            continue
        c = chars[m.character_id]
        bones, vertices = _apparel_masks(c, ((c.meta or {}).get("apparel") or {}).get("apparel_bones"))
        pieces = body_pieces(c.vertices, c.keypoints, dominant_bone(c.weights, c.num_joints), ~bones)
        height = float(c.height or np.ptp(np.asarray(c.vertices)[:, 1]))
        clip = np.asarray(m.transforms, np.float64)
        result[m.motion_id] = clip_quality(c.vertices, c.faces, c.keypoints, c.weights, vertices, pieces, clip, clip,
                                           m.fps, height) | {"frames": len(clip)}
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="a datagen apparel output folder")
    ap.add_argument("other", type=Path, nargs="?", help="the same clips simulated otherwise (optional)")
    args = ap.parse_args()
    runs = [recorded(args.out)] + ([recorded(args.other)] if args.other else [])
    kin = kinematic(args.out, set(runs[0]))
    print("clip frames " + " ".join(f"{k}(sim{'/other' if args.other else ''}/kinematic)" for k in SHOWN))
    for clip in sorted(runs[0], key=lambda c: (kin[c]["frames"], c)):
        cells = ["/".join(f"{r[clip][k]:.2f}" if clip in r else "-" for r in runs) + f"/{kin[clip][k]:.2f}"
                 for k in SHOWN]
        print(clip, kin[clip]["frames"], *cells)
    for name, r in zip(("out", "other"), runs):
        medians = " ".join(f"{k} {np.median([q[k] for q in r.values()]):.2f}" for k in SHOWN)
        print(f"{name}: {len(r)} clips, median {medians}; over the jitter bound "
              f"{sum(over_jitter_bound(q) for q in r.values())}, "
              f"re-settles {sum(q['resettles'] for q in r.values())}")
    print("kinematic: median " + " ".join(f"{k} {np.median([q[k] for q in kin.values()]):.2f}" for k in SHOWN[1:]))


if __name__ == "__main__":
    main()
