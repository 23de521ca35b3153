"""Paired per-case differences between methods of one results folder (`mimicbench bench run`),
with standard errors clustered by (source, target) pair.

For each protocol and metric, every method's mean over the cases that all the listed methods
scored ``ok`` with a value, its pair-clustered standard error, and for each method against the
reference (the first one listed) the mean of the per-case difference ``method - reference`` with
its pair-clustered standard error (:func:`mimicbench.benchmark.intervals.pair_clustered_se`: the cases of one
pair share a correspondence, so the pair is the unit sampled), the difference in standard errors
(``z``), the relative difference and the share of pairs on which the method is lower. A metric
that no stored row has (an older results folder) is reported as missing. An entry of ``--methods``
may be ``LABEL=FOLDER:METHOD``: that method's rows from another results folder (the same method
run with other weights, e.g. ``MIMICAT_CHECKPOINT=RUN bench run ... --out FOLDER``).

    python analyses/mimicat_paired.py RESULTS --methods mimicat,mimicat_init_only,text_soft,nearest_joint \
        [--metrics cct:pmd_extent,cct:semantic_deg,cct:out_of_range,h2h:pmd_height,h2h_xskel:pmd_height] \
        [--versions mimicat=9]
    python analyses/mimicat_paired.py RES --methods mimicat,a3=RES_A3:mimicat,nearest_joint
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root

DEFAULT_METRICS = ("h2h:pmd_height,h2h:els,h2h_xskel:pmd_height,cct:pmd_extent,cct:els,cct:els_forward,"
                   "cct:semantic_deg,cct:out_of_range")


def _version_key(v) -> tuple:
    s = str(v)
    return (0, int(s), s) if s.isdigit() else (1, 0, s)


def per_case(results, method: str, protocol: str, metric: str, version: str | None = None) -> dict[str, float]:
    """case ID -> metric of the ``ok`` rows of the method's ``version`` (None: its newest stored
    version, numeric versions compared as numbers)."""
    from mimicbench.benchmark.results import method_dir, method_versions, read_result_records

    versions = [v for m, v in method_versions(results) if m == method]
    if not versions:
        raise SystemExit(f"{results}: no results of method {method!r}")
    if version is None:
        version = sorted(versions, key=_version_key)[-1]
    elif version not in [str(v) for v in versions]:
        raise SystemExit(f"{results}: method {method!r} has versions {sorted(map(str, versions))}, not {version!r}")
    rows = read_result_records(method_dir(results, method, version))
    return {r.case_id: float(getattr(r, metric)) for r in rows
            if r.protocol == protocol and r.status == "ok" and getattr(r, metric, None) is not None}


def paired_rows(values: dict[str, dict[str, float]]) -> tuple[list[str], dict[str, np.ndarray], list[str]]:
    """(common case IDs, method -> values on them (C,), pair of each case (C,))."""
    from mimicbench.benchmark.intervals import pair_of

    common = sorted(set.intersection(*(set(v) for v in values.values())))
    return common, {m: np.array([v[c] for c in common]) for m, v in values.items()}, [pair_of(c) for c in common]


def pairs_lower(d: np.ndarray, pairs: list[str]) -> float:
    """Share of pairs whose mean difference ``d`` is below zero."""
    ids = np.asarray(pairs)
    means = np.array([d[ids == p].mean() for p in sorted(set(pairs))])
    return float((means < 0).mean())


def paired_table(results, methods: list[str], protocol: str, metric: str, versions: dict | None = None) -> str:
    """Lines: each method's mean over the common cases (pair-clustered SE), and its paired
    difference to methods[0]."""
    from mimicbench.benchmark.intervals import pair_clustered_se

    versions = versions or {}
    values = {}
    for m in methods:
        label, _, where = m.partition("=")
        folder, _, name = where.rpartition(":") if where else (results, None, label)
        values[label] = per_case(folder or results, name, protocol, metric, versions.get(label))
    methods = list(values)
    if not all(values.values()):
        missing = [m for m, v in values.items() if not v]
        return f"{protocol} {metric}: no value for {', '.join(missing)}"
    common, arr, pairs = paired_rows(values)
    if len(set(pairs)) < 2:
        return f"{protocol} {metric}: fewer than two pairs scored by every method"
    ref = methods[0]
    lines = [f"{protocol} {metric} over {len(common)} cases, {len(set(pairs))} pairs (mean +- pair-clustered SE; "
             f"difference to {ref} +- pair-clustered SE, z, relative, share of pairs lower):"]
    for m in methods:
        se = pair_clustered_se(arr[m], pairs)
        line = f"  {m:22s} {arr[m].mean():9.4f} +- {se:.4f}"
        if m != ref:
            d = arr[m] - arr[ref]
            sd = pair_clustered_se(d, pairs)
            z = d.mean() / sd if sd > 0 else float("nan")
            rel = 100 * d.mean() / abs(arr[ref].mean()) if arr[ref].mean() else float("nan")
            line += (f"   {m} - {ref}: {d.mean():+.4f} +- {sd:.4f} (z {z:+.1f}, {rel:+.1f}%, lower on "
                     f"{100 * pairs_lower(d, pairs):.0f}% of pairs)")
        lines.append(line)
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results")
    ap.add_argument("--methods", required=True, help="comma-separated; the first is the reference")
    ap.add_argument("--metrics", default=DEFAULT_METRICS, help="comma-separated protocol:metric")
    ap.add_argument("--versions", default="", help="comma-separated method=version (default: each one's newest)")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    versions = dict(kv.split("=", 1) for kv in args.versions.split(",") if kv)
    for spec in args.metrics.split(","):
        protocol, metric = spec.split(":")
        print(paired_table(args.results, methods, protocol, metric, versions))


if __name__ == "__main__":
    main()
