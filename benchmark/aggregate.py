"""Aggregate result rows into one line per (method, version, protocol) and per category.

A method with any failed or missing case gets no average (null), not a partial one: its row
shows how many cases failed and how many are missing instead.
"""
from __future__ import annotations

import numpy as np

from benchmark.results import method_versions, read_result_records, read_run_info
from pathlib import Path

METRICS = ("pmd", "pmd_squared", "els", "els_forward")


def _category_key(r) -> str:
    return f"{r.source_category}->{r.target_category}"


def _summarise(rows, expected: int | None) -> dict:
    ok = [r for r in rows if r.status == "ok"]
    failed = len(rows) - len(ok)
    missing = max(0, (expected if expected is not None else len(rows)) - len(rows))
    complete = failed == 0 and missing == 0 and len(rows) > 0
    entry = {"cases": len(rows), "ok": len(ok), "failed": failed, "missing": missing, "complete": complete,
             "seconds_per_case": float(np.mean([r.seconds for r in rows])) if rows else None}
    for m in METRICS:
        vals = [getattr(r, m) for r in ok if getattr(r, m) is not None]
        entry[m] = float(np.mean(vals)) if complete and vals else None
    errors = [r.error for r in rows if r.status != "ok"]
    entry["first_error"] = errors[0] if errors else None
    return entry


def aggregate(results) -> dict:
    """``{"protocols": {protocol: [entry per method version]}, "categories": {...}}``.

    Each entry: method, version, cases, ok, failed, missing, complete, pmd, pmd_squared, els,
    els_forward (means; null unless complete), seconds_per_case, first_error.
    """
    info = read_run_info(results)
    expected = info.get("protocols", {})
    out = {"protocols": {}, "categories": {}}
    for method, version in method_versions(results):
        rows = read_result_records(Path(results) / method / version)
        for protocol in sorted(set(expected) | {r.protocol for r in rows}):
            prow = [r for r in rows if r.protocol == protocol]
            entry = {"method": method, "version": version, **_summarise(prow, expected.get(protocol))}
            out["protocols"].setdefault(protocol, []).append(entry)
            cats = {}
            for r in prow:
                cats.setdefault(_category_key(r), []).append(r)
            for key, crow in sorted(cats.items()):
                centry = {"method": method, "version": version, "category": key, **_summarise(crow, None)}
                if entry["missing"]:
                    centry.update({m: None for m in METRICS}, complete=False)
                out["categories"].setdefault(protocol, []).append(centry)
    for entries in out["protocols"].values():
        entries.sort(key=lambda e: (e["pmd"] is None, e["pmd"] if e["pmd"] is not None else 0.0, e["method"]))
    return out
