"""Paired per-case differences between methods of one results folder (`mimicbench bench run`).

For each protocol and metric, every method's mean over the cases that all the listed methods
scored ``ok``, and for each method against the reference (the first one listed) the mean of the
per-case difference ``method - reference`` with its standard error ``std(d, ddof=1) / sqrt(n)``
(the cases are the pairing; a difference larger than twice its standard error is unlikely to be
the draw of cases).

    python benchmarks/mimicat_paired.py RESULTS --methods mimicat,mimicat_init_only,text_soft,nearest_joint \
        [--metrics h2h:pmd_height,h2h:els,cct:pmd_extent,cct:els]
"""
from __future__ import annotations

import argparse

import numpy as np


def per_case(results, method: str, protocol: str, metric: str) -> dict[str, float]:
    """case ID -> metric of the ``ok`` rows of the method's newest stored version."""
    from benchmark.results import method_dir, method_versions, read_result_records

    versions = [v for m, v in method_versions(results) if m == method]
    if not versions:
        raise SystemExit(f"{results}: no results of method {method!r}")
    rows = read_result_records(method_dir(results, method, sorted(versions, key=str)[-1]))
    return {r.case_id: float(getattr(r, metric)) for r in rows
            if r.protocol == protocol and r.status == "ok" and getattr(r, metric) is not None}


def paired_table(results, methods: list[str], protocol: str, metric: str) -> str:
    """Lines: each method's mean over the common cases, and its paired difference to methods[0]."""
    values = {m: per_case(results, m, protocol, metric) for m in methods}
    common = sorted(set.intersection(*(set(v) for v in values.values())))
    if len(common) < 2:
        return f"{protocol} {metric}: fewer than two cases scored by every method"
    arr = {m: np.array([values[m][c] for c in common]) for m in methods}
    ref = methods[0]
    lines = [f"{protocol} {metric} over {len(common)} cases (difference to {ref}, standard error of the paired "
             f"difference):"]
    for m in methods:
        d = arr[m] - arr[ref]
        se = d.std(ddof=1) / np.sqrt(len(d))
        extra = "" if m == ref else f"   {m} - {ref}: {d.mean():+.4f} +- {se:.4f}"
        lines.append(f"  {m:20s} {arr[m].mean():.4f}  (min {arr[m].min():.3f}){extra}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results")
    ap.add_argument("--methods", required=True, help="comma-separated; the first is the reference")
    ap.add_argument("--metrics", default="h2h:pmd_height,h2h:els,cct:pmd_extent,cct:els",
                    help="comma-separated protocol:metric")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    for spec in args.metrics.split(","):
        protocol, metric = spec.split(":")
        print(paired_table(args.results, methods, protocol, metric))


if __name__ == "__main__":
    main()
