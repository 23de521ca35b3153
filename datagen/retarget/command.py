"""``mimicbench datagen retarget MOTIONS CHARACTERS OUT``."""
from __future__ import annotations

import argparse

from mimicbench.runtime.summary import StageSummary


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "retarget", help="put humanoid clips of one dataset onto the humanoids of another, by bone roles",
        description="Map bones by humanoid role from their names (hips, spine, neck, head, shoulders, arms, "
        "hands, legs, feet, toes; Mixamo, Blender, 3ds Max, CMU and MMD names alike), align rest poses per "
        "mapped bone (T-pose or A-pose: the target bone's rest direction is turned onto the source's), carry "
        "the source's world rotations, keep unmapped target bones at rest, and move the root with the "
        "source's hips scaled by the ratio of leg lengths. Writes the target characters, the clips "
        "(<target>/<source>/<clip>), status rows and OUT/retarget_report.json (mapped and unmapped bones per "
        "pair). Example:\n"
        "  mimicbench datagen ingest mocap/CMU_02_01.bvh --out data/cmu\n"
        "  mimicbench datagen ingest mmd/*.pmx --out data/mmd\n"
        "  mimicbench datagen retarget data/cmu data/mmd data/mmd_cmu",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("motions", help="dataset whose clips are retargeted (its characters and motions)")
    p.add_argument("characters", help="dataset whose characters receive the clips")
    p.add_argument("out", help="output dataset folder")
    p.add_argument("--sources", default="*", help="glob on source character IDs (default: all)")
    p.add_argument("--targets", default="*", help="glob on target character IDs (default: all)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args) -> StageSummary:
    from mimicbench.datagen.retarget.stage import retarget_datasets
    from mimicbench.datagen.stage_runner import summarize_statuses

    s = retarget_datasets(args.motions, args.characters, args.out, args.sources, args.targets, not args.quiet)
    print(summarize_statuses(s["statuses"]))
    print(f"{s['clips']} clips on {s['characters']} characters ({s['pairs']} pairs) in {args.out} in "
          f"{s['seconds']:.1f} s; report: {args.out}/retarget_report.json")
    return StageSummary(s["clips"], s["failed"], s["seconds"], str(args.out))
