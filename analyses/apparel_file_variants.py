"""Issue 52: an MMD model's file physics under variants of its ``SimParams.file_*`` settings.

Simulates the named clips of one or more ingested (or retargeted) datasets with the character's own
rigid bodies and joints (:func:`mimicbench.datagen.apparel.file_physics.simulate_file_motion`, as the stage
does, 30 relaxation frames) once per variant, and prints each clip's quality (peak and p99 apparel
acceleration m/s^2, the jitter bound's kinematic peak, new inside %, largest edge stretch,
re-settles, over the jitter bound) and the count over the bound. A variant is a JSON object of
``simulation`` fields overriding the defaults.

    PYTHONPATH=. python analyses/apparel_file_variants.py gene,gene_bn stand,assets/guide/guide \\
        '{"file_contact_frequency": 0, "file_warmup": false}' '{}'
"""
from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from mimicbench.datagen.apparel.file_physics import simulate_file_motion
from mimicbench.datagen.apparel.params import SimParams
from mimicbench.datagen.apparel.quality import over_jitter_bound
from mimicbench.datagen.apparel.stage import _apparel_masks, _file_physics
from mimicbench.schemas.shards import read_records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("datasets", help="comma-separated dataset folders with rigid_bodies and joints")
    ap.add_argument("clips", help="comma-separated clip names (motion names), or 'all'")
    ap.add_argument("variants", nargs="+", help="JSON objects of SimParams fields")
    args = ap.parse_args()
    chars, rows, motions = {}, {}, []
    for ds in (Path(d) for d in args.datasets.split(",")):
        chars.update({c.character_id: c for c in read_records(ds, "characters")})
        rows.update(_file_physics(ds, None))
        motions += [m for m in read_records(ds, "motions") if not m.name.endswith("@sim")]
    if args.clips != "all":
        motions = [m for m in motions if m.name in args.clips.split(",")]
    for variant in args.variants:
        sim = dataclasses.replace(SimParams(), **json.loads(variant))
        qs = []
        print(variant)
        for m in motions:
            c = chars[m.character_id]
            _, q = simulate_file_motion(c, *rows[c.character_id], m, *_apparel_masks(c, None), 240.0, 30, sim)
            qs.append(q)
            bound = max(q["max_accel_kinematic"], q["max_accel_kinematic_touching"])
            print(f"  {m.name} peak {q['max_accel']:.2f} p99 {q['p99_accel']:.2f} bound {bound:.2f} new_in "
                  f"{q['new_inside_pct']:.2f} stretch {q['max_edge_stretch']:.2f} resettles {q['resettles']}"
                  f"{' OVER' if over_jitter_bound(q) else ''}", flush=True)
        print(f"  over the jitter bound: {sum(map(over_jitter_bound, qs))} of {len(qs)}")


if __name__ == "__main__":
    main()
