"""``mimicbench bench cases|run|leaderboard``."""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from mimicbench.runtime.argtypes import comma_choices, nonnegative_int, positive_float, positive_int
from mimicbench.runtime.summary import StageSummary

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
    from mimicbench.benchmark.protocols import available_protocols

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

    c = sub.add_parser("cases", help="make deterministic h2h, h2h_xskel and cct cases (cases/ table)",
                       description="Make benchmark cases from one split: h2h, same-skeleton transfer (characters "
                       "of any category that share a skeleton_id; ground truth carries the source's local rotations "
                       "and size-scaled local translations over), h2h_xskel (humanoids of different skeleton families with "
                       "role labels; ground truth retargeted through the hidden roles) and cct (cross-category pairs "
                       "with a humanoid on one side, scored by cycle consistency and by the forward leg against the "
                       "hidden roles). The cases record the fingerprints of the characters and "
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
    c.add_argument("--protocols", default=("h2h", "h2h_xskel", "cct"), type=_protocol_names,
                   help="comma-separated protocols to make cases of (default h2h,h2h_xskel,cct; h2h_xskel: "
                        "humanoids of different skeletons that carry role labels, sized like h2h); apparel: windows of "
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
    r.add_argument("--protocols", default=None, type=_protocol_names,
                   help="comma-separated protocols: h2h (same-skeleton), h2h_xskel (humanoids across skeleton "
                        "families), cct (cross-category cycle), apparel (motion transfer with simulated apparel; "
                        "needs `datagen apparel` data); default: those of h2h,h2h_xskel,cct the dataset has cases of")
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
    lb.add_argument("--reference", default="nearest_joint",
                    help="method (NAME or NAME/VERSION) every paired difference is taken against (default: "
                         "nearest_joint); intervals and ties need no reference")
    lb.set_defaults(func=run_leaderboard)

    v = sub.add_parser("validity", help="run the probe corruptions and print which scores detect them",
                       description="Run the validity probes (a right transfer corrupted in known ways: left/right "
                       "mirror, fore/hind swap, a frozen limb, 15 degree rotation noise, half the rotation angle, the "
                       "target at rest; and nearest_joint against a mirrored or front-back reflected target) with "
                       "their uncorrupted methods on DATA's cases, then print per protocol column and corruption "
                       "the paired difference, its z (standard error clustered by (source, target) pair) and "
                       "whether the column detects it (z > 2). Results go to OUT/results (resumable); the table "
                       "to OUT/validity.md and OUT/validity.json. Example:\n"
                       "  mimicbench bench validity data/zoo5k --out validity",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    v.add_argument("dataset")
    v.add_argument("--out", default="validity", help="folder for results and the table (default validity)")
    v.add_argument("--protocols", default=None, type=_protocol_names,
                   help="comma-separated protocols (default: those of h2h,h2h_xskel,cct the dataset has cases of)")
    v.add_argument("--in-process", action="store_true", help="call the probes in this process (faster start)")
    v.add_argument("--quiet", action="store_true", help="no progress bars")
    v.set_defaults(func=run_validity)

    ls = sub.add_parser("methods", help="list the registered methods")
    ls.set_defaults(func=run_methods)


def refuse_flat_characters(dataset, case_ids: bool = False) -> None:
    """Refuse, naming them, the characters of ``dataset`` whose rest mesh has no height (Y extent 0):
    every score divides by the target's height, so their cases cannot be scored. ``bench cases`` refuses
    any such character; ``bench run`` (``case_ids``) those its cases use, with the number of cases.

    Raises:
        ValueError: one line naming the characters and what to do.
    """
    from mimicbench.schemas.integrity import entry_path
    from mimicbench.schemas.shards import has_table, read_table, shard_entries
    from mimicbench.schemas.validate import skeleton_and_height_problems

    flat = {cid for entry in shard_entries(dataset, "characters")
            for cid, kind, _ in skeleton_and_height_problems(entry_path(Path(dataset), entry["path"]))
            if kind == "height"}
    if not flat:
        return
    used = ""
    if case_ids and has_table(dataset, "cases"):
        cases = read_table(dataset, "cases", columns=["source_id", "target_id"])
        pairs = zip(cases.column("source_id").to_pylist(), cases.column("target_id").to_pylist())
        counts = {}
        for source, target in pairs:
            for cid in {source, target} & set(flat):
                counts[cid] = counts.get(cid, 0) + 1
        if not counts:
            return
        flat = set(counts)
        used = f" (used by {sum(counts.values())} cases)"
    names = ", ".join(sorted(flat)[:5]) + (", ..." if len(flat) > 5 else "")
    raise ValueError(f"{dataset}: {len(flat)} character(s) whose rest mesh has no height (Y extent 0; every score "
                     f"divides by it){used}: {names}; remove them from the dataset (or give them a mesh with "
                     f"height) and run `mimicbench bench cases` again")


def run_cases(args) -> StageSummary:
    """``bench cases`` holding the writer's lock of the dataset."""
    from mimicbench.schemas.folder_lock import hold

    with hold(args.dataset):  # one writer of the dataset at a time (a stage writing it makes this wait)
        return _run_cases(args)


def _run_cases(args) -> StageSummary:
    from mimicbench.benchmark.cases import build_cases, write_cases

    refuse_flat_characters(args.dataset)
    if args.all_pairs and args.split not in (None, "all"):
        raise ValueError(f"--all-pairs takes every pair across all splits; it cannot be limited to "
                         f"--split {args.split}")
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


def _run_protocols(args) -> list[str]:
    """``--protocols``, or by default each default protocol the dataset has cases of (h2h and cct
    when it has none: the run then says to build cases)."""
    from pathlib import Path

    from mimicbench.benchmark.protocols import DEFAULT_PROTOCOLS
    from mimicbench.schemas.dataset import Dataset

    if args.protocols is not None:
        return list(args.protocols)
    if not (Path(args.dataset) / "manifest.json").is_file():
        return ["h2h", "cct"]  # the run itself says what is wrong with the folder, after checking the methods
    dataset = Dataset.of(args.dataset)
    have = [p for p in DEFAULT_PROTOCOLS if dataset.has_table("cases", p)]
    return have or ["h2h", "cct"]


def run_validity(args) -> StageSummary:
    from pathlib import Path

    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.validity import markdown_validity, methods_to_run, validity_table, write_validity

    results = Path(args.out) / "results"
    summary = run_benchmark(args.dataset, methods_to_run(), _run_protocols(args), results,
                            progress=not args.quiet, in_process=args.in_process)
    rows = validity_table(results)
    path = write_validity(args.out, rows)
    print(markdown_validity(rows))
    print(f"validity table: {path}")
    return StageSummary(summary["computed"] - summary["failed"] - summary["not_supported"], summary["failed"],
                        out=str(args.out))


def run_run(args) -> StageSummary:
    """``bench run`` holding the writer's lock of ``--out`` (of this rank's share under torchrun): a second
    run into the same results folder waits for the first, then skips the cases it computed."""
    import os

    from mimicbench.schemas.folder_lock import hold

    rank = os.environ.get("RANK", "0") if os.environ.get("WORLD_SIZE", "1") not in ("", "1") else ""
    with hold(Path(args.out) if not rank else Path(f"{args.out}.rank-{rank}")):
        return _run_run(args)


def _run_run(args) -> StageSummary:
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.leaderboard import markdown_tables
    from mimicbench.engines import get_engine

    from mimicbench.benchmark.registry import check_method_names

    check_method_names(args.methods)  # a typo is named before anything about the dataset
    refuse_flat_characters(args.dataset, case_ids=True)
    summary = run_benchmark(args.dataset, list(args.methods), _run_protocols(args), args.out, args.device,
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


def run_leaderboard(args) -> StageSummary:
    from mimicbench.benchmark.leaderboard import markdown_tables, write_leaderboard
    from mimicbench.benchmark.aggregate import aggregate

    from mimicbench.benchmark.leaderboard import default_out

    out = args.out or default_out(args.results)
    reference = getattr(args, "reference", "nearest_joint")
    paths = write_leaderboard(args.results, out, pictures=not args.no_pictures, reference=reference)
    print(markdown_tables(aggregate(args.results, reference)))
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return StageSummary(len(paths), out=str(out))


def run_methods(args) -> int:
    """One line a method; a method that cannot be loaded (a broken plug-in) is named on stderr, exit 1."""
    from mimicbench.benchmark.registry import METHODS, get_method
    from mimicbench.schemas.errors import UserError

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
