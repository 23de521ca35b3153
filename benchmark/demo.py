"""``mimicbench demo``: the whole toolkit end to end on a small procedural zoo, offline.

Builds a zoo, resamples it to 5,000 faces, computes bone-name correspondences, makes h2h and cct
cases, runs every bundled method and prints the leaderboard with the path of its HTML page; then
simulates the apparel characters' clips with Bullet, makes apparel cases and prints the apparel
table of :data:`BUNDLED_APPAREL`.
Sized to finish within about 10 minutes on 2 CPU cores.
"""
from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

from mimicbench.argtypes import positive_int

BUNDLED = ("identity", "name_copy", "nearest_joint", "text_soft",
           "mimicat",  # the MimiCAT reference with its shipped checkpoint (baselines/mimicat/checkpoints)
           "npt", "cgt", "sfpt")  # the published baselines re-implemented from their papers, shipped checkpoints
BUNDLED_APPAREL = ("lbs_kinematic", "body_only", "mmdmc", "sfpt")  # mmdmc, sfpt: shipped checkpoints, no training
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
    p.add_argument("--characters", type=int, default=16, help="zoo size (default 16)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--h2h-poses", type=int, default=10, help="poses per h2h pair (default 10)")
    p.add_argument("--cct-pairs", type=int, default=24, help="cross-category pairs (default 24)")
    p.add_argument("--cct-poses", type=int, default=4, help="poses per cct pair (default 4)")
    p.add_argument("--apparel-windows", type=positive_int, default=4, help="16-frame windows per simulated clip (default 4)")
    p.add_argument("--fresh", action="store_true", help="delete OUT first instead of resuming")
    p.set_defaults(func=run)


def run(args) -> int:
    from benchmark.cases import build_cases, write_cases
    from benchmark.evaluator import run_benchmark
    from benchmark.leaderboard import markdown_tables, write_leaderboard
    from benchmark.provenance import cases_are_current
    from datagen.correspond import correspond_dataset
    from datagen.resample import resample_dataset
    from datagen.zoo import build_zoo
    from schemas.shards import has_table

    out = Path(args.out)
    if args.fresh and out.exists():
        shutil.rmtree(out)
    zoo, data, results = out / "zoo", out / "zoo5k", out / "results"
    t0 = time.perf_counter()
    steps = []

    def step(name, fn):
        start = time.perf_counter()
        print(f"== {name}", flush=True)
        value = fn()
        steps.append((name, time.perf_counter() - start))
        return value

    if not (zoo / "manifest.json").exists():
        step("zoo", lambda: build_zoo(zoo, args.characters, seed=args.seed, clips_per_character=3))
    step("resample to 5,000 faces", lambda: resample_dataset(zoo, data, faces=5000, backend="fast", jobs=1))
    if not has_table(data, "pairs"):
        corr = step("correspondences (MiniLM)", lambda: correspond_dataset(data, all_pairs=True, encoder="minilm",
                                                                          progress=False))
        agree = corr["report"]["humanoid_cross_style_agreement"]
        print(f"   {sum(corr['pairs'].values())} pairs; humanoid bones matched to the same role across naming "
              f"styles: {'n/a' if agree is None else f'{agree:.0%}'} (details: {data}/correspond_report.json)")
    if not has_table(data, "cases") or not cases_are_current(data):
        if results.exists():  # scored on cases of an earlier dataset state
            shutil.rmtree(results)

        def make_cases():
            cases = build_cases(data, "test", h2h_pairs=100, h2h_poses=args.h2h_poses, cct_pairs=args.cct_pairs,
                                cct_poses=args.cct_poses, seed=args.seed)
            return write_cases(data, cases, {"stage": "demo cases", "split": "test"})
        counts = step("cases", make_cases)
        print("   " + ", ".join(f"{p}: {n} cases" for p, n in counts.items()))
    step("run methods", lambda: run_benchmark(data, BUNDLED, ("h2h", "cct"), results, progress=True))
    step("apparel: simulate, cases, run methods", lambda: run_apparel(data, out, args))
    paths = write_leaderboard(results)
    apparel_paths = write_leaderboard(out / "results-apparel")
    from benchmark.aggregate import aggregate

    print()
    print(markdown_tables(aggregate(results)))
    print(markdown_tables(aggregate(out / "results-apparel")))
    print("timings: " + ", ".join(f"{n} {s:.0f} s" for n, s in steps) + f"; total {time.perf_counter() - t0:.0f} s")
    print(f"leaderboard: {paths['html'].resolve()}")
    print(f"apparel leaderboard: {apparel_paths['html'].resolve()}")
    return 0


def run_apparel(data: Path, out: Path, args) -> None:
    """Simulate the apparel characters' clips (Bullet), build apparel cases from every split (the
    demo zoo has too few apparel characters for one split) and run :data:`BUNDLED_APPAREL`."""
    from benchmark.cases import build_cases, write_cases
    from benchmark.evaluator import run_benchmark
    from benchmark.provenance import cases_are_current
    from datagen.apparel.stage import simulate_dataset
    from schemas.shards import has_table

    sim, results = out / "zoo5k_sim", out / "results-apparel"
    s = simulate_dataset(data, sim, progress=False)  # resumes when already simulated
    print(f"   {s['simulated'] + s['reused']} clips simulated on {s['characters']} apparel characters")
    if not has_table(sim, "cases") or not cases_are_current(sim):
        if results.exists():
            shutil.rmtree(results)
        cases = build_cases(sim, "all", protocols=("apparel",), sizes={"apparel": (None, args.apparel_windows)},
                            seed=args.seed)
        print("   " + ", ".join(f"{p}: {n} cases" for p, n in write_cases(
            sim, cases, {"stage": "demo cases", "split": "all"}).items()))
    run_benchmark(sim, BUNDLED_APPAREL, ("apparel",), results, progress=True)
