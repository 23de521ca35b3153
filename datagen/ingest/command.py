"""``mimicbench datagen ingest PATH_OR_GLOB... --out DATASET``."""
from __future__ import annotations

import argparse

from mimicbench.datagen.ingest.clip_length import MAX_CLIP_FRAMES
from mimicbench.runtime.argtypes import MAX_JOBS, comma_choices, job_count, positive_float, positive_int
from mimicbench.engines import add_engine_arguments
from mimicbench.runtime.summary import StageSummary

EXPORT_FORMATS = ("obj", "bvh")  # as mimicbench.datagen.ingest.runner.EXPORT_FORMATS (kept here so --help stays fast)

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


def bvh_scale_arg(text: str) -> float | str:
    """``--bvh-scale``: ``auto`` or metres per file unit greater than 0."""
    return "auto" if text == "auto" else positive_float(text)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "ingest", help="import rigged assets (glTF/GLB, FBX, BVH, OBJ, .blend through Blender; MMD .pmx/.pmd "
        "without) into a dataset",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="+", help="asset files, folders (walked for asset files) or glob patterns")
    p.add_argument("--out", required=True, help="dataset folder (created, or added to)")
    p.add_argument("--jobs", type=job_count, default=1, help=f"Blender processes at once, 1 to {MAX_JOBS} (default 1)")
    p.add_argument("--timeout", type=positive_float, default=300.0,
                   help="seconds per asset before its Blender process is killed, > 0 (default 300)")
    p.add_argument("--category-map", default=None,
                   help="JSON file mapping a glob or file stem to a category; assets it does not name get an "
                        "inferred category")
    p.add_argument("--bvh-scale", type=bvh_scale_arg, default="auto",
                   help="metres per BVH file unit, > 0, or 'auto' (default): the first of centimetres, metres, "
                        "CMU units (0.056444), inches, millimetres that makes the rest skeleton 0.3-3 m tall; "
                        "the choice is recorded in each character's meta")
    p.add_argument("--mmd-unit", type=positive_float, default=0.08, metavar="METRES",
                   help="metres per MMD unit for .pmx/.pmd/.vmd files, > 0 (default 0.08, the scale of mmd_tools "
                        "and of MMD players); recorded in each MMD character's meta.mmd.metres_per_unit")
    p.add_argument("--mesh-unit", type=positive_float, default=1.0, metavar="METRES",
                   help="metres per unit of the scene Blender imports from .glb/.gltf/.fbx/.obj/.blend, > 0 "
                        "(default 1: glTF is in metres and Blender converts FBX units); every length is "
                        "multiplied by it (0.01 for a file authored in centimetres but declared in metres); "
                        "a character under 0.05 m or over 30 m across gets a warning; recorded in meta.ingest")
    p.add_argument("--export", type=comma_choices(EXPORT_FORMATS), default=(), help="comma-separated of obj,bvh: also write OUT/export/ files")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--split", choices=("train", "val", "test"), default=None,
                       help="put every asset of this run in one split (default: a hash of the character ID)")
    group.add_argument("--split-file", default=None,
                       help="JSON mapping split name to a list of character IDs (others: hashed split)")
    p.add_argument("--allow-external-uris", action="store_true",
                   help="let glTF buffers and images point outside the asset's folder (refused by default)")
    p.add_argument("--max-clip-frames", type=positive_int, default=MAX_CLIP_FRAMES, metavar="N",
                   help=f"the most frames a clip may have, checked before it is sampled, for every format (default "
                        f"{MAX_CLIP_FRAMES}: 20 minutes at 30 fps); a longer clip becomes a failed status row")
    p.add_argument("--motions", default=None, metavar="DIR",
                   help="folder of .vmd motions to play on every MMD model of the run (besides <stem>_<clip>.vmd)")
    p.add_argument("--roles", nargs="+", default=None, metavar="FILE",
                   help="role-label files (.toml/.json, docs/roles.md) attached after the ingest, as "
                        "`mimicbench datagen roles OUT --labels FILE` does: hidden bone roles and categories")
    add_engine_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    import glob
    import json

    from mimicbench.datagen.ingest.runner import ingest_assets
    from mimicbench.datagen.stage_runner import summarize_statuses
    from mimicbench.engines import engine_from_args

    paths = []
    for pattern in args.paths:
        matches = sorted(glob.glob(pattern))
        paths.extend(matches or [pattern])
    if args.motions:  # MMD motions for every model (datagen/mmd/ingest.py); a missing folder is an error
        from pathlib import Path

        if not Path(args.motions).is_dir():
            raise NotADirectoryError(f"--motions: {args.motions} is not a folder of .vmd files")
        paths.extend(str(p) for p in sorted(Path(args.motions).glob("*.vmd")))
    cmap = json.loads(open(args.category_map).read()) if args.category_map else None
    s = ingest_assets(paths, args.out, not args.quiet, engine_from_args(args), jobs=args.jobs, timeout=args.timeout,
                      category_map=cmap, export=args.export, bvh_scale=args.bvh_scale,
                      allow_external_uris=args.allow_external_uris, split=args.split, split_file=args.split_file,
                      mmd_unit=args.mmd_unit, mesh_unit=args.mesh_unit, max_clip_frames=args.max_clip_frames)
    print(summarize_statuses([x for x in s["statuses"] if x.status != "skipped"]))
    for w in s["warnings"]:
        print(f"warning: {w}")
    print(f"{s['characters']} characters and {s['motions']} clips in {args.out} ({s['skipped']} already done, "
          f"{s['failed']} failed, {s['failed_clips']} clips unreadable) in {s['seconds']:.1f} s")
    from mimicbench.schemas.dataset import Dataset

    if not Dataset.of(args.out).has_table("characters"):  # every asset failed: nothing to label or report
        return StageSummary(s["characters"], s["failed"], s["seconds"], str(args.out))
    if args.roles:
        from mimicbench.datagen.roles.attach import attach_roles, print_warnings, summary_lines

        labels = attach_roles(args.out, args.roles)
        print_warnings(labels)
        print("\n".join(summary_lines(labels)))
    from mimicbench.datagen.roles.categories import inferred_lines

    for line in inferred_lines(args.out):
        print(line)
    return StageSummary(s["characters"], s["failed"], s["seconds"], str(args.out))
