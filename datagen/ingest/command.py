"""``mimicbench datagen ingest PATH_OR_GLOB... --out DATASET``."""
from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "ingest", help="import rigged assets (glTF/GLB, FBX, BVH, OBJ, .blend through Blender; MMD .pmx/.pmd without) into a dataset",
        description="Import each asset with Blender (bpy) in its own child process with a timeout: rest mesh "
        "(all skinned meshes of the armature merged, triangulated, Y up), deform bones, skin weights and every "
        "animation clip as per-frame transforms that reproduce Blender's own deformation by linear blend "
        "skinning. A crash, timeout or unreadable file becomes a status row; a re-run skips assets already "
        "done. MMD models (.pmx, .pmd) are read without Blender (datagen/mmd): 1 MMD unit = 0.08 m, z mirrored, "
        "rigid bodies and joints in the tables rigid_bodies and joints, and each <stem>.vmd or <stem>_<clip>.vmd "
        "beside a model (or given with it) played on it with MMD's IK and grants "
        "(see schemas/FORMAT.md). Example:\n  mimicbench datagen ingest 'assets/*.glb' mocap/run.bvh --out data/mine --jobs 2",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="+", help="asset files or glob patterns")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--jobs", type=int, default=1, help="Blender processes at once (default 1)")
    p.add_argument("--timeout", type=float, default=300.0, help="seconds per asset (default 300)")
    p.add_argument("--category-map", default=None,
                   help="JSON file mapping a glob or file stem to a category (default: unknown)")
    p.add_argument("--export", default="", help="comma-separated of obj,bvh: also write OUT/export/ files")
    p.add_argument("--motions", default=None, metavar="DIR",
                   help="folder of .vmd motions to play on every MMD model of the run (besides <stem>_<clip>.vmd)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    import glob
    import json

    from datagen.ingest.runner import ingest_assets
    from datagen.stage_runner import summarize_statuses

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
    export = tuple(x for x in args.export.split(",") if x)
    s = ingest_assets(paths, args.out, args.jobs, args.timeout, cmap, export, not args.quiet)
    print(summarize_statuses([x for x in s["statuses"] if x.status != "skipped"]))
    print(f"{s['characters']} characters and {s['motions']} clips in {args.out} ({s['skipped']} already done) "
          f"in {s['seconds']:.1f} s")
    return 1 if s["failed"] else 0
