"""Cost of running methods in a worker process (`bench run`'s default) against `--in-process`.

Builds a zoo (or uses DATASET), makes cases, then scores the same methods twice into fresh
results folders: once in process, once through :class:`mimicbench.benchmark.worker.WorkerRunner` (one spawn
worker a method, rigs sent once, requests as IDs plus posed vertices). Prints both wall times and
their ratio, and the per-case overhead of the worker.

    python benchmarks/bench_worker.py [--characters 20] [--methods identity,name_copy] [--batch-size 16]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default=None, help="a dataset with cases (default: build a zoo here)")
    ap.add_argument("--characters", type=int, default=20)
    ap.add_argument("--methods", default="identity,name_copy")
    ap.add_argument("--batch-size", type=int, default=16)
    args = ap.parse_args()

    from mimicbench.benchmark.cases import build_cases, write_cases
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import read_records

    work = Path(tempfile.mkdtemp(prefix="bench_worker-"))
    data = Path(args.dataset) if args.dataset else work / "zoo"
    if not args.dataset:
        build_zoo(data, args.characters, seed=0, progress=False)
        write_cases(data, build_cases(data, "all", h2h_pairs=20, h2h_poses=10, cct_pairs=40, cct_poses=4),
                    {"stage": "benchmarks/bench_worker"})
    n_cases = len(read_records(data, "cases"))
    methods = [m for m in args.methods.split(",") if m]
    times = {}
    for mode, in_process in (("in-process", True), ("worker", False)):
        start = time.perf_counter()
        run_benchmark(data, methods, out=work / f"res-{mode}", batch_size=args.batch_size, progress=False,
                      in_process=in_process)
        times[mode] = time.perf_counter() - start
    calls = n_cases * len(methods)
    print(f"{n_cases} cases x {len(methods)} methods ({', '.join(methods)}), batch {args.batch_size}")
    for mode, t in times.items():
        print(f"  {mode:10s} {t:7.2f} s  ({1000 * t / calls:.2f} ms a case and method)")
    print(f"worker / in-process: {times['worker'] / times['in-process']:.2f}x; overhead "
          f"{1000 * (times['worker'] - times['in-process']) / calls:.2f} ms a case and method")


if __name__ == "__main__":
    main()
