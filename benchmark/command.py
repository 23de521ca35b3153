"""``mimicbench bench cases|run|leaderboard``."""
from __future__ import annotations

import argparse
import dataclasses
import sys

from mimicbench.argtypes import comma_choices, nonnegative_int, positive_float, positive_int
from mimicbench.summary import StageSummary

SPLIT_CHOICES = ("train", "val", "test", "all")
CASES_CONFIG_KEYS = {"command": "bench", "bench_command": "cases", "debug": False, "no_verify": False}
"""Keys the cases' config has always recorded (from the parsed command line) beside the options
(``--apparel-windows`` only when given, so configs made before it stay the same)."""


def _method_names(text: str) -> tuple[str, ...]:
    """argparse type of ``--methods``: a non-empty comma-separated list of names."""
    names = tuple(dict.fromkeys(m.strip() for m in text.split(",") if m.strip()))
    if not names:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of at least one method name, got {text!r}"
                                         " (see `mimicbench bench methods`)")
    return names


def _protocol_names(text: str) -> tuple[str, ...]:
    """argparse type of ``--protocols``: a non-empty comma-separated subset of the protocols."""
    from benchmark.protocols import available_protocols

    return comma_choices(available_protocols(), allow_empty=False)(text)


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="benchmark pose-transfer methods: cases, run, leaderboard",
                              description="Score pose-transfer methods on a dataset. Example:\n"
                              "  mimicbench bench cases data/zoo\n"
                              "  mimicbench bench run data/zoo --methods identity,name_copy --out results\n"
                              "  mimicbench bench leaderboard results",
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="bench_command", metavar="STEP")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])

    c = sub.add_parser("cases", help="make deterministic h2h and cct cases (cases/ table)",
                       description="Make benchmark cases from one split: h2h, same-skeleton transfer (characters "
                       "of any category that share a skeleton_id; ground truth carries the source's local rotations "
                       "and size-scaled local translations over) and cct (cross-category pairs with a humanoid on "
                       "one side, scored by cycle consistency). The cases record the fingerprints of the characters and "
                       "motions they were built from; `bench run` refuses them once the dataset changes. A run that "
                       "makes no case is an error and keeps the existing cases. Example:\n"
                       "  mimicbench bench cases data/zoo5k --split all --h2h-pairs 50\n"
                       "  mimicbench bench cases data/zoo5k --all-pairs     # every pair, across splits",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("dataset")
    c.add_argument("--split", default=None, choices=SPLIT_CHOICES, help="characters to use: train, val, test or all (default test)")
    c.add_argument("--all-pairs", action="store_true",
                   help="every candidate pair of every protocol, across all splits (no sampling; "
                   "--h2h-pairs and --cct-pairs do not apply; --split may only be 'all')")
    c.add_argument("--h2h-pairs", type=nonnegative_int, default=100, help="ordered same-skeleton pairs (default 100)")
    c.add_argument("--h2h-poses", type=positive_int, default=20, help="poses per h2h pair (default 20)")
    c.add_argument("--cct-pairs", type=nonnegative_int, default=300, help="cross-category pairs (default 300)")
    c.add_argument("--cct-poses", type=positive_int, default=10, help="poses per cct pair (default 10)")
    c.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the pair and pose draws (default 0)")
    c.add_argument("--protocols", default=("h2h", "cct"), type=_protocol_names,
                   help="comma-separated protocols to make cases of (default h2h,cct); apparel: windows of "
                        "16 frames of every clip that `datagen apparel` simulated, 10 per clip")
    c.add_argument("--apparel-windows", type=positive_int, default=None, metavar="N",
                   help="apparel protocol: 16-frame windows per simulated clip, >= 1 (default 10)")
    c.set_defaults(func=run_cases)

    r = sub.add_parser("run", help="run methods on the cases and store per-case results",
                       description="Run registered methods on the dataset's cases. Rows go to "
                       "OUT/<method>/<version>/ with a meta.json (dataset fingerprints, method metadata, toolkit "
                       "version); a re-run computes only missing cases, and refuses an OUT made from another "
                       "dataset state. Each method runs in a worker process: a case that hangs past "
                       "--case-timeout, or a crash, fails that case and the run goes on with a fresh worker. "
                       "Under torchrun the cases are sharded by RANK/WORLD_SIZE, e.g.\n"
                       "  torchrun --nproc-per-node 2 -m mimicbench bench run DATA --methods name_copy --out results",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("dataset")
    r.add_argument("--methods", required=True, type=_method_names,
                   help="comma-separated method names (see `mimicbench bench methods`)")
    r.add_argument("--protocols", default=("h2h", "cct"), type=_protocol_names,
                   help="comma-separated protocols: h2h (same-skeleton), cct (cross-category cycle), apparel "
                        "(motion transfer with simulated apparel; needs `datagen apparel` data); default h2h,cct")
    r.add_argument("--out", default="results", help="results folder (default results)")
    r.add_argument("--device", default="cpu", help="cpu or cuda[:i] (default cpu)")
    r.add_argument("--batch-size", type=positive_int, default=16, help="requests per transfer call (default 16)")
    r.add_argument("--case-timeout", type=positive_float, default=600.0, metavar="SECONDS",
                   help="seconds a case may take before it fails as timed out (a batch of B gets B times "
                   "this; default 600)")
    r.add_argument("--in-process", action="store_true",
                   help="call methods in this process: no worker start-up, but no timeout and no protection "
                   "from a method that hangs or crashes")
    r.add_argument("--retry-failed", action="store_true", help="also re-run cases whose stored row failed")
    r.add_argument("--engine", choices=("local", "ray"), default="local",
                   help="local (default: a worker process a method, or torchrun ranks) or ray: each batch of cases a "
                        "Ray task, for CPU-bound methods and many small cases (same results rows, same "
                        "--case-timeout)")
    r.add_argument("--ray-address", default=None, metavar="ADDRESS",
                   help="with --engine ray: a running cluster (e.g. ray://head:10001); default: a local Ray instance")
    r.add_argument("--quiet", action="store_true", help="no progress bars")
    r.set_defaults(func=run_run)

    lb = sub.add_parser("leaderboard", help="write leaderboard.md/.csv/.json/.html from results",
                        description="Aggregate RESULTS into a leaderboard (Markdown, CSV, JSON, HTML with plots): per protocol "
                        "a method x category matrix of the headline metric, plots per category, and rendered strips of "
                        "a few sampled cases (source, ground truth, every method's prediction) through Blender. "
                        "Methods with failed, missing or unsupported cases show their counts and no average.")
    lb.add_argument("results")
    lb.add_argument("--out", default=None, help="folder for the files (default: RESULTS-leaderboard, beside RESULTS: "
                                                "never into the folder it reads, so a re-run of bench finds its "
                                                "results as it left them)")
    lb.add_argument("--no-pictures", action="store_true",
                    help="skip the rendered strips of sampled cases (they need Blender, about 30 s)")
    lb.set_defaults(func=run_leaderboard)

    ls = sub.add_parser("methods", help="list the registered methods")
    ls.set_defaults(func=run_methods)


def run_cases(args) -> int:
    from benchmark.cases import build_cases, write_cases

    if args.all_pairs and args.split not in (None, "all"):
        print(f"error: --all-pairs takes every pair across all splits; it cannot be limited to --split {args.split}")
        return 2
    split = "all" if args.all_pairs else (args.split or "test")
    protocols = list(args.protocols)
    cases = build_cases(args.dataset, split, args.h2h_pairs, args.h2h_poses, args.cct_pairs, args.cct_poses,
                        args.seed, all_pairs=args.all_pairs, protocols=protocols,
                        sizes=None if args.apparel_windows is None else {"apparel": (None, args.apparel_windows)})
    options = {k: v for k, v in dataclasses.asdict(args).items() if not (k == "apparel_windows" and v is None)}
    config = {"stage": "bench cases", **CASES_CONFIG_KEYS, **options, "split": split}
    counts = write_cases(args.dataset, cases, config)
    print(f"cases in {args.dataset}: " + ", ".join(f"{p} {n}" for p, n in counts.items()))
    return StageSummary(sum(counts.values()), out=str(args.dataset))


def run_run(args) -> int:
    from benchmark.evaluator import run_benchmark
    from benchmark.leaderboard import markdown_tables
    from mimicbench.engines import get_engine

    summary = run_benchmark(args.dataset, list(args.methods), list(args.protocols), args.out, args.device,
                            args.batch_size, progress=not args.quiet, retry_failed=args.retry_failed,
                            case_timeout=args.case_timeout, in_process=args.in_process,
                            engine=None if args.engine == "local" and not args.ray_address
                            else get_engine(args.engine, 1, args.ray_address))
    if summary["rank"] == 0:
        print(markdown_tables(summary["aggregate"]))
        print(f"{summary['computed']} cases computed ({summary['failed']} failed, {summary['not_supported']} not "
              f"supported by their method), {summary['skipped']} already done; results in {args.out}")
    for reason in summary["unavailable"].values():
        print(f"mimicbench: error: not run: {reason}", file=sys.stderr)
    return StageSummary(summary["computed"] - summary["failed"] - summary["not_supported"], summary["failed"],
                        out=str(args.out), exit_code=1 if summary["unavailable"] else 0)


def run_leaderboard(args) -> int:
    from benchmark.leaderboard import markdown_tables, write_leaderboard
    from benchmark.aggregate import aggregate

    from benchmark.leaderboard import default_out

    out = args.out or default_out(args.results)
    paths = write_leaderboard(args.results, out, pictures=not args.no_pictures)
    print(markdown_tables(aggregate(args.results)))
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return StageSummary(len(paths), out=str(out))


def run_methods(args) -> int:
    """One line a method; a method that cannot be loaded (a broken plug-in) is named on stderr, exit 1."""
    from benchmark.registry import METHODS, get_method
    from schemas.errors import UserError

    broken, rows = [], []
    for name in METHODS.names():
        try:
            rows.append((name, get_method(name).metadata))
        except (UserError, TypeError) as exc:  # LoadError, NameCollision, not a method
            broken.append(str(exc))
    width = max((len(name) for name, _ in rows), default=0)
    for name, md in rows:
        print(f"{name:{width}s}  v{md.version:6s} {md.licence:8s} {md.description}")
    for reason in broken:
        print(f"mimicbench: error: {reason}", file=sys.stderr)
    return 1 if broken else 0
