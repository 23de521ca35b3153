"""Aggregate result rows: one summary per (protocol, method version) and one method x category
matrix per protocol.

- Metrics are every float column of the results table except ``seconds`` (so a metric column the
  protocols add shows up without a change here). Means are over cases.
- A method with any failed, missing or not-supported case gets no average (null), not a partial
  one: its row shows the counts instead. Rows whose status is neither ``ok`` nor ``failed``
  (e.g. ``not_supported``) count as not supported; so does a whole protocol that the method's
  metadata leaves out of its ``protocols``.
- The matrix: rows are method versions, columns are categories, cells the mean of the protocol's
  headline metric over the cases of that category, plus an ``all`` column. A case's column is its
  target category when both sides are humanoid-like (h2h), else the side that is not humanoid-like
  (cct: ``bird`` holds humanoid->bird and bird->humanoid), else ``source->target``.
- Every row is checked first (:mod:`benchmark.result_checks`: its folder's method and version,
  the run's protocols and case IDs, metric ranges, no NaN); a row that fails is listed in
  ``refused`` with the reason, counted as ``invalid``, never averaged, and its method version gets
  no average.
- Method information (licence, citation, toolkit version, fingerprints) comes from
  ``<method>/<version>/meta.json`` when the run wrote one, else from the method registry.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from benchmark.result_checks import row_problem
from benchmark.results import method_versions, read_result_records, read_run_info
from schemas.character import HUMANOID_LIKE
from schemas.result import ResultRecord

# Headline metric per protocol, first column present wins: h2h keeps the paper's unit height,
# cross-category views use the largest extent (a flat snake is a few centimetres tall).
HEADLINE_PREFERENCE = {"h2h": ("pmd_height", "pmd"), "cct": ("pmd_extent", "pmd")}
DEFAULT_HEADLINE = ("pmd_extent", "pmd")
ALL = "all"
PROTOCOL_ORDER = ("h2h", "cct", "apparel")  # shown in this order, others after them by name


def _protocol_order(protocol: str):
    return (PROTOCOL_ORDER.index(protocol) if protocol in PROTOCOL_ORDER else len(PROTOCOL_ORDER), protocol)


def metric_columns() -> list[str]:
    """Every float metric column of the results table, in schema order (``seconds`` excluded)."""
    return [c.name for c in ResultRecord.COLUMNS if c.kind == "scalar" and c.dtype.startswith("float")
            and c.name != "seconds"]


def _protocol(name: str):
    """The registered protocol object, or None for a name no longer registered."""
    try:
        from benchmark.protocols import get_protocol

        return get_protocol(name)
    except ValueError:
        return None


def headline_metric(protocol: str, columns=None) -> str:
    """The metric a protocol ranks by: ``pmd_<headline>`` for a registered protocol that names its
    headline normalisation (``height`` or ``extent``), else the first of
    :data:`HEADLINE_PREFERENCE` present in the results table, else ``pmd``."""
    columns = list(columns or metric_columns())
    proto = _protocol(protocol)
    declared = f"pmd_{proto.headline}" if proto is not None and getattr(proto, "headline", None) else None
    if declared in columns:
        return declared
    for name in HEADLINE_PREFERENCE.get(protocol, DEFAULT_HEADLINE):
        if name in columns:
            return name
    return "pmd" if "pmd" in columns else columns[0]


def lower_is_better(metric: str) -> bool:
    return not metric.startswith("els")


def category_column(source_category: str, target_category: str) -> str:
    """The matrix column of a case (see the module docstring)."""
    s_h, t_h = source_category in HUMANOID_LIKE, target_category in HUMANOID_LIKE
    if s_h and t_h:
        return target_category
    if s_h != t_h:
        return source_category if t_h else target_category
    return source_category if source_category == target_category else f"{source_category}->{target_category}"


def _status_kind(status: str) -> str:
    return status if status in ("ok", "failed") else "not_supported"


def _summarise(rows, expected: int | None, metrics: list[str], invalid: int = 0) -> dict:
    kinds = [_status_kind(r.status) for r in rows]
    ok = [r for r, k in zip(rows, kinds) if k == "ok"]
    failed, unsupported = kinds.count("failed"), kinds.count("not_supported")
    missing = max(0, (expected if expected is not None else len(rows)) - len(rows))
    complete = failed == 0 and missing == 0 and unsupported == 0 and invalid == 0 and len(rows) > 0
    entry = {"cases": len(rows), "ok": len(ok), "failed": failed, "missing": missing, "not_supported": unsupported,
             "invalid": invalid, "complete": complete,
             "seconds_per_case": float(np.mean([r.seconds for r in rows])) if rows else None}
    for m in metrics:
        vals = [getattr(r, m, None) for r in ok]
        vals = [v for v in vals if v is not None]
        entry[m] = float(np.mean(vals)) if complete and vals else None
    errors = [r.error for r in rows if r.status != "ok"]
    entry["first_error"] = errors[0] if errors else None
    return entry


def method_info(results, method: str, version: str) -> dict:
    """Licence, citation, description and provenance of a method version.

    Read from ``RESULTS/<method>/<version>/meta.json`` (``{"method": MethodMetadata fields,
    "toolkit_version", "dataset", "fingerprints", "created"}``) when present (``source``
    ``meta.json``); else from the registry (``source`` ``registry``; provenance unknown); else
    ``source`` ``unknown``.
    """
    info = {"method": method, "version": version, "licence": None, "citation": None, "description": None,
            "protocols": None, "toolkit_version": None, "dataset": None, "fingerprints": {}, "created": None,
            "source": "unknown"}
    path = Path(results) / method / version / "meta.json"
    if path.exists():
        try:
            meta = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            info["source"] = f"unreadable meta.json ({exc})"
            return info
        md = meta.get("method") or {}
        info.update({k: md.get(k) for k in ("licence", "citation", "description", "protocols")})
        info.update({k: meta.get(k) for k in ("toolkit_version", "dataset", "created")})
        info["fingerprints"] = meta.get("fingerprints") or {}
        info["source"] = "meta.json"
        return info
    try:
        from benchmark.registry import get_method

        md = get_method(method).metadata
    except Exception:  # an unknown or broken method still gets its results shown
        return info
    info.update(licence=md.licence, citation=md.citation, description=md.description,
                protocols=getattr(md, "protocols", None), source="registry")
    return info


def _matrix(protocol: str, per_method: list[tuple[dict, list]], headline: str) -> dict:
    """Rows of method versions, columns of categories (+ ``all``), cells the headline mean."""
    columns = sorted({category_column(r.source_category, r.target_category) for _, rows in per_method for r in rows})
    out_rows = []
    for entry, rows in per_method:
        by_col: dict[str, list] = {}
        for r in rows:
            by_col.setdefault(category_column(r.source_category, r.target_category), []).append(r)
        cells, counts = {}, {}
        for col in columns:
            crow = by_col.get(col, [])
            s = _summarise(crow, None, [headline])
            cells[col] = s[headline] if not entry["missing"] else None
            counts[col] = {k: s[k] for k in ("cases", "ok", "failed", "not_supported")}
            if entry["invalid"]:
                cells[col] = None
        cells[ALL] = entry[headline]
        out_rows.append({"method": entry["method"], "version": entry["version"], "cells": cells, "counts": counts,
                         "ok": entry["ok"], "failed": entry["failed"], "missing": entry["missing"],
                         "not_supported": entry["not_supported"], "invalid": entry["invalid"],
                         "complete": entry["complete"]})
    return {"headline": headline, "lower_is_better": lower_is_better(headline), "columns": columns + [ALL],
            "rows": out_rows}


def aggregate(results) -> dict:
    """The leaderboard's data.

    Returns:
        ``{"protocols": {protocol: [entry per method version]}, "categories": {protocol: [entry per
        method version and matrix column]}, "matrix": {protocol: {"headline", "lower_is_better",
        "columns", "rows"}}, "headline": {protocol: metric}, "titles": {protocol: what it measures},
        "metrics": [metric columns],
        "methods": {"method/version": method_info}, "run": run.json, "refused": [{"method", "version",
        "protocol", "case_id", "reason"} per row not averaged]}``. Each entry: method, version,
        cases, ok, failed, missing, not_supported, invalid, complete, every metric (means; null
        unless complete), seconds_per_case, first_error.
    """
    info = read_run_info(results)
    expected = info.get("protocols", {})
    metrics = metric_columns()
    checked = metrics + [c.name for c in ResultRecord.COLUMNS if c.kind == "list" and c.dtype.startswith("float")]
    recorded_ids = {p: set(ids) for p, ids in (info.get("case_ids") or {}).items()}
    out = {"protocols": {}, "categories": {}, "matrix": {}, "headline": {}, "titles": {}, "metrics": metrics,
           "methods": {}, "run": {k: v for k, v in info.items() if k != "case_ids"}, "refused": []}
    grouped: dict[str, list] = {}
    for method, version in method_versions(results):
        minfo = method_info(results, method, version)
        out["methods"][f"{method}/{version}"] = minfo
        rows, refused = [], {}
        for r in read_result_records(Path(results) / method / version):
            problem = row_problem(r, method, version, checked, recorded_ids.get(r.protocol),
                                  set(expected) if expected else None)
            if problem is None:
                rows.append(r)
                continue
            refused[r.protocol] = refused.get(r.protocol, 0) + 1
            out["refused"].append({"method": method, "version": version, "protocol": r.protocol,
                                   "case_id": r.case_id, "reason": problem})
        for protocol in sorted(set(expected) | {r.protocol for r in rows} | set(refused)):
            prow = [r for r in rows if r.protocol == protocol]
            extra = len(prow) - expected[protocol] if protocol in expected else 0
            if extra > 0:  # more cases than the run asked for, and no case IDs recorded to tell which
                refused[protocol] = refused.get(protocol, 0) + extra
                out["refused"].append({"method": method, "version": version, "protocol": protocol, "case_id": None,
                                       "reason": f"{len(prow)} rows for the run's {expected[protocol]} {protocol} "
                                                 f"cases: {extra} not among them"})
            entry = {"method": method, "version": version,
                     **_summarise(prow, expected.get(protocol), metrics, refused.get(protocol, 0))}
            supported = minfo.get("protocols")
            if supported is not None and protocol not in supported and not prow:
                entry.update(not_supported=entry["missing"], missing=0)
            out["protocols"].setdefault(protocol, []).append(entry)
            grouped.setdefault(protocol, []).append((entry, prow))
            cats: dict[str, list] = {}
            for r in prow:
                cats.setdefault(category_column(r.source_category, r.target_category), []).append(r)
            for key, crow in sorted(cats.items()):
                centry = {"method": method, "version": version, "category": key, **_summarise(crow, None, metrics)}
                if entry["missing"] or entry["invalid"]:
                    centry.update({m: None for m in metrics}, complete=False)
                out["categories"].setdefault(protocol, []).append(centry)
    for key in ("protocols", "categories"):
        out[key] = {p: out[key][p] for p in sorted(out[key], key=_protocol_order)}
    for protocol, entries in out["protocols"].items():
        head = headline_metric(protocol, metrics)
        out["headline"][protocol] = head
        proto = _protocol(protocol)
        out["titles"][protocol] = getattr(proto, "title", None) or protocol
        sign = 1.0 if lower_is_better(head) else -1.0
        entries.sort(key=lambda e: (e[head] is None, sign * e[head] if e[head] is not None else 0.0, e["method"]))
        order = [(e["method"], e["version"]) for e in entries]
        pm = sorted(grouped[protocol], key=lambda er: order.index((er[0]["method"], er[0]["version"])))
        out["matrix"][protocol] = _matrix(protocol, pm, head)
    return out
