"""``mimicbench pipeline PIPELINE.toml``: run every step of a pipeline file, resumably."""
from __future__ import annotations

import argparse

DESCRIPTION = """\
Run a pipeline file: zoo or ingest -> resample -> apparel -> correspond -> cases -> bench run ->
leaderboard, each step one `mimicbench` command with the options the file gives it. A step whose
inputs and options are unchanged since it last finished, and whose output is still there, is
skipped; a killed pipeline resumes with the first unfinished step (and that step resumes its own
work). The engine (local or ray) applies to every step that runs per-item work; it never changes
the output, so switching engines does not redo finished steps.

examples:
  mimicbench pipeline examples/pipelines/demo.toml
  mimicbench pipeline examples/pipelines/pokeanimdb.toml --engine ray --jobs 2
  mimicbench pipeline examples/pipelines/demo.toml --workdir /tmp/demo --force correspond

The file (TOML):
  [pipeline]
  name = "demo"            # names the record WORKDIR/.pipeline/<name>.json
  workdir = "data/demo"    # step folders are relative to it
  engine = "local"         # or "ray" (ray_address = "...", jobs = N)
  [[steps]]
  run = "zoo"              # zoo, ingest, retarget, roles, resample, apparel, correspond, cases, bench,
                           # validity, leaderboard
  out = "zoo"
  characters = 16          # any option of the command, with _ for -
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("pipeline", help="run a whole pipeline file (zoo/ingest to leaderboard), resumably",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("pipeline_file", metavar="PIPELINE.toml")
    p.add_argument("--workdir", default=None, help="folder for the steps' data (default: the file's workdir)")
    p.add_argument("--engine", choices=("local", "ray"), default=None, help="override the file's engine")
    p.add_argument("--ray-address", default=None, help="override the file's ray_address (with --engine ray)")
    p.add_argument("--jobs", type=int, default=None, help="override the file's jobs (worker processes or CPUs)")
    p.add_argument("--force", nargs="+", default=(), metavar="STEP", help="run these steps even if finished")
    p.add_argument("--dry-run", action="store_true", help="print each step's command and whether it would run")
    p.add_argument("--quiet", action="store_true", help="no pipeline progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from mimicbench.pipeline import format_summary, load_pipeline, run_pipeline, step_argv
    from mimicbench.pipeline.state import PipelineState, outputs_digest, step_fingerprint

    pipeline = load_pipeline(args.pipeline_file, args.workdir)
    if args.engine:
        pipeline.engine = args.engine
    if args.ray_address:
        pipeline.ray_address = args.ray_address
    if args.jobs is not None:
        if args.jobs < 1:
            raise ValueError(f"--jobs: expected >= 1, got {args.jobs}")
        pipeline.jobs = args.jobs
    if pipeline.ray_address and pipeline.engine != "ray":
        raise ValueError("ray_address: only with engine = \"ray\"")
    if args.dry_run:
        state = PipelineState(pipeline)
        for step in pipeline.steps:
            done = state.is_done(step, step_fingerprint(step, pipeline), outputs_digest(step, pipeline))
            print(f"{'skip' if done and step.name not in args.force else 'run '}  mimicbench "
                  + " ".join(step_argv(step, pipeline)))
        return 0
    results = run_pipeline(pipeline, progress=not args.quiet, force=tuple(args.force))
    print(format_summary(pipeline, results))
    if any(r.status == "failed" for r in results):
        return 2
    return 1 if any(r.status == "partial" for r in results) else 0
