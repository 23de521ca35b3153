"""``mimicbench datagen ingest PATH_OR_GLOB... --out DATASET``."""
from __future__ import annotations

import argparse

from mimicbench.datagen.ingest.params import IngestParams
from mimicbench.runtime.options import add_options
from mimicbench.runtime.summary import StageSummary

DESCRIPTION = """\
Import rigged assets with Blender (bpy) into a dataset: rest mesh (all meshes the armature drives,
merged, triangulated, metres, Y up), deform bones, skin weights, and every animation clip as
per-frame transforms (plus a per-bone stretch for bones that scale) that linear blend skinning
turns back into the file's own deformation. Each clip starts from the file's default pose, so
clips do not depend on each other; frame f of a clip is at time t0 + f / fps.

Ingest is additive and resumable: characters already in DATASET stay, a re-run skips files whose
content and options are unchanged (cache key = content hash), and two files with the same name
get different IDs (assets/<stem>-<path hash>). A crash, a timeout, an unreadable file or clip, or
a glTF resource outside the asset's folder becomes a status row and the rest goes on. One Blender
process ingests many assets (factory reset in between; a fresh one after a crash).

MMD models (.pmx, .pmd) are read without Blender (datagen/mmd): 1 MMD unit = 0.08 m (--mmd-unit), z mirrored,
rigid bodies and joints in the tables rigid_bodies and joints, and each <stem>.vmd or
<stem>_<clip>.vmd beside a model (or given with it) played on it with MMD's IK and grants
(see schemas/FORMAT.md).

Categories come from --category-map, or a role-label file (--roles), or are inferred from bone
names and the skeleton, which says unknown where the body plan is ambiguous (meta.category says how;
the summary lists the inferred ones). Characters with equal bone names and parents share a skeleton_id.

A folder stands for every asset file under it (.glb .gltf .fbx .bvh .obj .blend .pmx .pmd; a model's
own .vmd motions are found beside it by name); hidden folders and OUT itself are not walked.

Examples:
  mimicbench datagen ingest 'assets/*.glb' --out data/mine --jobs 2
  mimicbench datagen ingest my_characters/ --out data/mine
  mimicbench datagen ingest mocap/run.bvh --out data/mine --bvh-scale 0.01 --split test
  mimicbench datagen ingest Fox.glb --out data/mine --mesh-unit 0.01   # authored in cm, declared in metres
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "ingest", help="import rigged assets (glTF/GLB, FBX, BVH, OBJ, .blend through Blender; MMD .pmx/.pmd "
        "without) into a dataset",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(p, IngestParams)
    p.set_defaults(func=run)


def run(params: IngestParams) -> StageSummary:
    from mimicbench.datagen.ingest.runner import run_command

    return run_command(params)
