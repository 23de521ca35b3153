"""``mimicbench datagen retarget MOTIONS CHARACTERS OUT``."""
from __future__ import annotations

import argparse

from mimicbench.datagen.retarget.params import RetargetParams
from mimicbench.runtime.options import add_options
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
    add_options(p, RetargetParams)
    p.set_defaults(func=run)


def run(params: RetargetParams) -> StageSummary:
    from mimicbench.datagen.retarget.stage import run_command

    return run_command(params)
