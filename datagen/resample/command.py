"""``mimicbench datagen resample IN_DATASET OUT_DATASET``."""
from __future__ import annotations

import argparse

from datagen.resample import MAX_FACES, MIN_FACES
from mimicbench.argtypes import MAX_JOBS, int_in, job_count
from mimicbench.engines import add_engine_arguments
from mimicbench.summary import StageSummary


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "resample", help="resample meshes to a face count and re-skin them by barycentric interpolation",
        description="Clean every character's mesh, bring it to --faces faces (quadric edge collapse above, "
        "subdivision then collapse below), carry skin weights and the apparel mask over by barycentric "
        "interpolation at the closest point of the original surface, and record the face counts, Hausdorff "
        "distance and skinning transfer error (percent of height) in meta['resample']. Motions are copied "
        "unchanged. Finished characters are written as they complete; a re-run into the same OUT_DATASET "
        "resumes, reusing only rows made from the same input tables with the same --faces and --backend "
        "(others are redone). Example:\n"
        "  mimicbench datagen resample data/zoo data/zoo5k\n\n"
        "Backends: fast (default; fast-simplification, the quadric error metric with a low aggressiveness) "
        "and pymeshlab (MeshLab's quadric edge collapse). On 8 zoo characters fast is about 4x faster "
        "and keeps the Hausdorff distance lower (mean 0.51 vs 0.75 % of height): python benchmarks/resample.py",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("in_dataset")
    p.add_argument("out_dataset")
    p.add_argument("--faces", type=int_in(MIN_FACES, MAX_FACES), default=5000,
                   help=f"target face count, {MIN_FACES} to {MAX_FACES:,} (default 5000)")
    p.add_argument("--backend", choices=("fast", "pymeshlab"), default="fast",
                   help="fast (fast-simplification, default) or pymeshlab (MeshLab's quadric edge collapse)")
    p.add_argument("--jobs", type=job_count, default=1, help=f"worker processes, 1 to {MAX_JOBS} (default 1)")
    add_engine_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from mimicbench.engines import engine_from_args
    from datagen.resample.stage import resample_dataset

    s = resample_dataset(args.in_dataset, args.out_dataset, args.faces, args.backend, args.jobs, not args.quiet,
                         engine=engine_from_args(args))
    for note in s["notes"]:
        print(f"resample: {note}")
    h = s["hausdorff_pct_mean"]
    t = s["transfer_error_pct_mean"]
    print(f"{s['resampled']} resampled, {s['already_done']} already done, {s['failed']} failed in {s['seconds']:.1f} s; "
          f"mean Hausdorff {h if h is None else round(h, 3)} %, mean transfer error {t if t is None else round(t, 3)} % "
          f"of height -> {args.out_dataset}")
    return StageSummary(s["resampled"] + s["already_done"], s["failed"], s["seconds"], str(args.out_dataset))
