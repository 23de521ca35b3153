"""``mimicbench demo``: the whole toolkit end to end on a small procedural zoo, offline.

The bundled pipeline file :data:`DEMO_PIPELINE` (``mimicbench/commands/demo.toml``) run by the pipeline code:
a zoo resampled to 5,000 faces, bone-name correspondences, h2h and cct cases, every bundled method
and its leaderboard; then the apparel characters' clips simulated with Bullet, apparel cases and
the apparel methods' leaderboard. The demo's options replace the file's values (CLI > file).
Sized to finish within about 10 minutes on 2 CPU cores.
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from mimicbench.runtime.argtypes import positive_int

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

DEMO_PIPELINE = Path(__file__).with_name("demo.toml")
OPTION_STEPS = {"characters": ("zoo",), "seed": ("zoo", "cases", "apparel-cases"), "h2h_poses": ("cases",),
                "cct_pairs": ("cases",), "cct_poses": ("cases",), "apparel_windows": ("apparel-cases",)}
"""Each demo option -> the steps of :data:`DEMO_PIPELINE` whose key of that name it sets."""


def _methods(step: str) -> tuple[str, ...]:
    return tuple(next(s for s in tomllib.loads(DEMO_PIPELINE.read_text())["steps"] if s.get("name", s["run"]) == step)["methods"])


BUNDLED = _methods("bench")  # identity, name_copy, nearest_joint, text_soft, mimicat, mimicat_init_only, npt, cgt, sfpt
BUNDLED_APPAREL = _methods("apparel-bench")  # lbs_kinematic, body_only, mmdmc, sfpt (shipped checkpoints)
"""Methods run on the apparel protocol (motion transfer on simulated apparel)."""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="build a small zoo, run every bundled method, print the leaderboard",
        description="Run the whole toolkit offline on a small procedural zoo: zoo -> resample (5,000 faces) "
        "-> correspondences (MiniLM bone-name embeddings) -> h2h and cct cases -> every bundled method -> "
        "leaderboard (Markdown, CSV, JSON, HTML); then the apparel characters' clips simulated with Bullet -> "
        "apparel cases -> lbs_kinematic, body_only, mmdmc and sfpt (shipped weights) -> the apparel table. Example:\n  mimicbench demo --out demo-output",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="demo-output", help="folder for the datasets and results (default demo-output)")
    p.add_argument("--characters", type=int, default=None, help="zoo size (default 16)")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--h2h-poses", type=int, default=None, help="poses per h2h pair (default 10)")
    p.add_argument("--cct-pairs", type=int, default=None, help="cross-category pairs (default 24)")
    p.add_argument("--cct-poses", type=int, default=None, help="poses per cct pair (default 4)")
    p.add_argument("--apparel-windows", type=positive_int, default=None, help="16-frame windows per simulated clip (default 4)")
    p.add_argument("--fresh", action="store_true", help="delete OUT first instead of resuming")
    p.set_defaults(func=run)


def run(args) -> int:
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.benchmark.leaderboard import markdown_tables
    from mimicbench.pipeline import format_summary, load_pipeline, run_pipeline

    out = Path(args.out)
    if args.fresh and out.exists():
        shutil.rmtree(out)
    pipeline = load_pipeline(DEMO_PIPELINE, workdir=out)
    steps = {s.name: s for s in pipeline.steps}
    for option, names in OPTION_STEPS.items():
        if getattr(args, option) is not None:
            for name in names:
                steps[name].options[option] = getattr(args, option)
    results = run_pipeline(pipeline)  # checks every step's options before it runs any
    print()
    print(format_summary(pipeline, results))
    if any(r.status == "failed" for r in results):
        return 2
    boards = {s.name: s.folder("out", out)[0] for s in pipeline.steps if s.kind == "leaderboard"}
    print(markdown_tables(aggregate(out / "results")))
    print(markdown_tables(aggregate(out / "results-apparel")))
    print(f"leaderboard: {(boards['leaderboard'] / 'leaderboard.html').resolve()}")
    print(f"apparel leaderboard: {(boards['apparel-leaderboard'] / 'leaderboard.html').resolve()}")
    return 1 if any(r.status == "partial" for r in results) else 0
