"""Paired differences of the ``apparel`` protocol's columns between methods of one results folder.

For each method against the reference (the first listed) and each apparel column (PMD_a and
PMD_b in cm at 1.70 m, ``accel_error``, ``penetration_share``), the mean of the per-case
difference ``method - reference`` over the cases both scored, with its standard error clustered by
(source, target) pair (:func:`mimicbench.benchmark.intervals.paired_difference`) and the difference in those
standard errors. The issue-52 check: ``probe_apparel_jitter`` (``lbs_kinematic`` with 1 mm of
frame-to-frame noise on its apparel) against ``lbs_kinematic`` must move ``accel_error`` by more
than 2 SE while PMD_a barely moves.

    python analyses/apparel_paired.py RESULTS --methods lbs_kinematic,probe_apparel_jitter,mmdmc

A method written ``NAME@V`` reads its stored version V (default: the newest), so two versions of one
method pair up: ``--methods mmdmc@9,mmdmc@10``.
"""
from __future__ import annotations

import argparse

import numpy as np

from mimicbench.benchmark.intervals import paired_difference

COLUMNS = ("pmd_apparel_cm", "pmd_body_cm", "accel_error", "penetration_share")


def per_case(results, method: str, metric: str, protocol: str = "apparel") -> dict[str, float | None]:
    """case ID -> ``metric`` of the ``ok`` rows of the method's newest stored version, or of version V
    when ``method`` is ``NAME@V``."""
    from mimicbench.benchmark.results import method_dir, method_versions, read_result_records

    name, _, wanted = method.partition("@")
    versions = [str(v) for m, v in method_versions(results) if m == name]
    if not versions or (wanted and wanted not in versions):
        raise SystemExit(f"{results}: no results of method {method!r} (stored versions: {versions or 'none'})")
    version = wanted or sorted(versions, key=lambda v: (len(v), v))[-1]
    rows = read_result_records(method_dir(results, name, version))
    return {r.case_id: getattr(r, metric) for r in rows if r.protocol == protocol and r.status == "ok"}


def paired_rows(results, methods: list[str], columns=COLUMNS) -> list[dict]:
    """One row per (method, column): the reference's mean, the paired difference (also as a share of
    that mean), its pair-clustered SE and the difference in SEs, over the cases both scored."""
    ref = methods[0]
    rows = []
    for column in columns:
        base = per_case(results, ref, column)
        for m in methods[1:]:
            d = paired_difference(per_case(results, m, column), base)
            if d is None:
                continue
            ref_mean = float(np.mean([v for v in base.values() if v is not None]))
            rows.append({"method": m, "column": column, **d, "reference_mean": ref_mean,
                         "relative": d["diff"] / ref_mean if ref_mean else float("nan"),
                         "in_se": d["diff"] / d["se"] if d["se"] else float("nan")})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results")
    ap.add_argument("--methods", required=True, help="comma-separated; the first is the reference")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    print(f"| method - {methods[0]} | column | {methods[0]} mean | difference | relative | pair SE | in SE | cases "
          f"| pairs |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in paired_rows(args.results, methods):
        print(f"| {r['method']} | {r['column']} | {r['reference_mean']:.4f} | {r['diff']:+.4f} | {100 * r['relative']:+.1f} % "
              f"| {r['se']:.4f} | {r['in_se']:+.1f} | {r['cases']} | {r['pairs']} |")


if __name__ == "__main__":
    main()
