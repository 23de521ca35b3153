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
- Every row is checked first (:mod:`mimicbench.benchmark.result_checks`: its folder's method and version,
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

from mimicbench.benchmark.intervals import DRAWS, LEVEL, SEED, cluster_bootstrap_means, pair_of, paired_difference, tie_ranks
from mimicbench.benchmark.result_checks import row_problem
from mimicbench.benchmark.results import method_versions, read_result_records, read_run_info
from mimicbench.schemas.character import HUMANOID_LIKE
from mimicbench.schemas.result import ResultRecord

# Headline metric per protocol, first column present wins: h2h keeps the paper's unit height,
# cross-category views use the largest extent (a flat snake is a few centimetres tall).
HEADLINE_PREFERENCE = {"h2h": ("pmd_height", "pmd"), "cct": ("pmd_extent", "pmd")}
DEFAULT_HEADLINE = ("pmd_extent", "pmd")
ALL = "all"
DEFAULT_REFERENCE = "nearest_joint"
"""The method every paired difference of the ranking is taken against (``--reference``)."""
VIEW_COLUMNS = {"cct": ("semantic_deg", "{headline}", "out_of_range", "els_forward")}
"""Columns of a protocol's ranking, the first present one sorting it. cct sorts by the semantic
score: its cycle round-trips any one-to-one mapping, so a mirrored transfer costs the cycle PMD
nothing."""
DEFAULT_VIEW_COLUMNS = ("{headline}", "semantic_deg", "out_of_range", "els_forward", "penetration_share",
                        "accel_error")
PROTOCOL_ORDER = ("h2h", "h2h_xskel", "cct", "apparel")  # shown in this order, others after them by name


def _protocol_order(protocol: str):
    return (PROTOCOL_ORDER.index(protocol) if protocol in PROTOCOL_ORDER else len(PROTOCOL_ORDER), protocol)


def metric_columns() -> list[str]:
    """Every float metric column of the results table, in schema order (``seconds`` excluded)."""
    return [c.name for c in ResultRecord.COLUMNS if c.kind == "scalar" and c.dtype.startswith("float")
            and c.name != "seconds"]


def _protocol(name: str):
    """The registered protocol object, or None for a name no longer registered."""
    try:
        from mimicbench.benchmark.protocols import get_protocol

        return get_protocol(name)
    except ValueError:
        return None


def headline_metric(protocol: str, columns=None) -> str:
    """The metric a protocol ranks by: its ``headline_column`` when it names one (``pmd_aligned`` for
    the h2h protocols), else ``pmd_<headline>`` for a registered protocol that names its
    headline normalisation (``height`` or ``extent``), else the first of
    :data:`HEADLINE_PREFERENCE` present in the results table, else ``pmd``."""
    columns = list(columns or metric_columns())
    proto = _protocol(protocol)
    declared = None
    if proto is not None:
        declared = getattr(proto, "headline_column", None) or (
            f"pmd_{proto.headline}" if getattr(proto, "headline", None) else None)
    if declared in columns:
        return declared
    for name in HEADLINE_PREFERENCE.get(protocol, DEFAULT_HEADLINE):
        if name in columns:
            return name
    return "pmd" if "pmd" in columns else columns[0]


def lower_is_better(metric: str) -> bool:
    return not metric.startswith("els")


def view_columns(protocol: str, headline: str, present) -> list[str]:
    """The ranking's columns of a protocol (:data:`VIEW_COLUMNS`) among ``present``, the headline always."""
    order = [c.format(headline=headline) for c in VIEW_COLUMNS.get(protocol, DEFAULT_VIEW_COLUMNS)]
    return [c for c in order if c in present or c == headline]


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
            "protocols": None, "reads_rig": None, "toolkit_version": None, "dataset": None, "fingerprints": {}, "created": None,
            "source": "unknown"}
    path = Path(results) / method / version / "meta.json"
    if path.exists():
        try:
            meta = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            info["source"] = f"unreadable meta.json ({exc})"
            return info
        md = meta.get("method") or {}
        info.update({k: md.get(k) for k in ("licence", "citation", "description", "protocols", "reads_rig")})
        info.update({k: meta.get(k) for k in ("toolkit_version", "dataset", "created")})
        info["fingerprints"] = meta.get("fingerprints") or {}
        info["source"] = "meta.json"
        return info
    try:
        from mimicbench.benchmark.registry import get_method

        md = get_method(method).metadata
    except Exception:  # an unknown or broken method still gets its results shown
        return info
    info.update(licence=md.licence, citation=md.citation, description=md.description,
                protocols=getattr(md, "protocols", None), reads_rig=getattr(md, "reads_rig", None), source="registry")
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


def _reference_key(reference: str | None, keys: list[str], complete: dict[str, bool]) -> str | None:
    """``method/version`` of ``reference`` (a name, or ``name/version``) among ``keys``: its
    complete version with the highest number, else its highest; None when absent."""
    if not reference:
        return None
    if reference in keys:
        return reference
    found = [k for k in keys if k.split("/", 1)[0] == reference]

    def version(key):
        v = key.split("/", 1)[1]
        return (complete.get(key, False), (0, int(v), "") if v.isdigit() else (1, 0, v))

    return max(found, key=version) if found else None


def _cell(values: dict, pairs_of: dict) -> dict:
    """Mean, 95% pair-clustered bootstrap interval and counts of one method on one column."""
    keys = sorted(k for k, v in values.items() if v is not None)
    unscored = len(values) - len(keys)
    if not keys:
        return {"mean": None, "lo": None, "hi": None, "cases": 0, "pairs": 0, "unscored": unscored}
    x = np.array([values[k] for k in keys])
    pairs = [pairs_of[k] for k in keys]
    means = cluster_bootstrap_means(x, pairs)
    lo, hi = np.quantile(means, [(1 - LEVEL) / 2, 1 - (1 - LEVEL) / 2])
    return {"mean": float(x.mean()), "lo": float(lo), "hi": float(hi), "cases": len(keys),
            "pairs": len(set(pairs)), "unscored": unscored}


def _surely_better(values: dict[str, dict], lower: bool) -> dict[tuple[str, str], bool]:
    """``(a, b) -> True`` when the 95% interval of the paired difference ``a - b`` (pair-clustered
    bootstrap over the cases both have a value for) excludes 0 on ``a``'s side.

    Methods with the same cases share one bootstrap (the draws of :func:`cluster_bootstrap_means`
    on their stacked values: the same as bootstrapping each difference); others are paired one by one.
    """
    out = {}
    by_cases: dict[tuple, list[str]] = {}
    for key, vals in values.items():
        by_cases.setdefault(tuple(sorted(k for k, v in vals.items() if v is not None)), []).append(key)
    lo_q, hi_q = (1 - LEVEL) / 2, 1 - (1 - LEVEL) / 2

    def decide(a, b, lo, hi):
        out[(a, b)] = hi < 0 if lower else lo > 0
        out[(b, a)] = lo > 0 if lower else hi < 0

    for cases, group in by_cases.items():
        if len(group) > 1 and cases:
            means = cluster_bootstrap_means(np.array([[values[m][k] for m in group] for k in cases]),
                                            [pair_of(k) for k in cases])
            for i, a in enumerate(group):
                for j in range(i + 1, len(group)):
                    lo, hi = np.quantile(means[:, i] - means[:, j], [lo_q, hi_q])
                    decide(a, group[j], lo, hi)
    keys = list(values)
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            if (a, b) not in out:
                d = paired_difference(values[a], values[b])
                if d is not None:
                    decide(a, b, d["lo"], d["hi"])
    return out


def _ranking(protocol: str, per_method: list[tuple[dict, list]], headline: str, methods: dict,
             reference: str | None) -> dict:
    """A protocol's ranking: per method and column the mean with its interval, the paired
    difference against the reference, and the rank with ties (see :func:`aggregate`)."""
    ok_rows = {f"{e['method']}/{e['version']}": (e, [r for r in rows if r.status == "ok"]) for e, rows in per_method}
    present = {c for _, rows in ok_rows.values() for r in rows for c in metric_columns()
               if getattr(r, c, None) is not None}
    columns = view_columns(protocol, headline, present)
    complete = {k: e["complete"] for k, (e, _) in ok_rows.items()}
    ref = _reference_key(reference, list(ok_rows), complete)
    values = {k: {c: {r.case_id: getattr(r, c, None) for r in rows} for c in columns}
              for k, (_, rows) in ok_rows.items() if complete[k]}
    pairs_of = {r.case_id: pair_of(r.case_id) for _, rows in ok_rows.values() for r in rows}
    cells: dict[str, dict] = {k: {} for k in ok_rows}
    ranks: dict[str, dict] = {}
    for c in columns:
        lower = lower_is_better(c)
        for k in ok_rows:
            cells[k][c] = _cell(values[k][c], pairs_of) if k in values else \
                {"mean": None, "lo": None, "hi": None, "cases": 0, "pairs": 0, "unscored": 0}
            d = paired_difference(values[k][c], values[ref][c]) if k in values and ref in values and k != ref else None
            cells[k][c].update({"diff": None, "diff_lo": None, "diff_hi": None, "diff_se": None, "diff_cases": None}
                               if d is None else {"diff": d["diff"], "diff_lo": d["lo"], "diff_hi": d["hi"],
                                                  "diff_se": d["se"], "diff_cases": d["cases"]})
        scored = [k for k in values if cells[k][c]["mean"] is not None]
        sign = 1.0 if lower else -1.0
        scored.sort(key=lambda k: (sign * cells[k][c]["mean"], k))
        ranks[c] = tie_ranks(scored, _surely_better({k: values[k][c] for k in scored}, lower))
    for c in columns:
        shared = {}
        for k, r in ranks[c].items():
            shared[r] = shared.get(r, 0) + 1
        for k in ok_rows:
            r = ranks[c].get(k)
            cells[k][c].update(rank=r, tied=r is not None and shared[r] > 1)
    sort = columns[0]
    sign = 1.0 if lower_is_better(sort) else -1.0
    order = sorted(ok_rows, key=lambda k: (cells[k][sort]["mean"] is None,
                                           sign * (cells[k][sort]["mean"] or 0.0), k))
    rows = []
    for k in order:
        e = ok_rows[k][0]
        reads = (methods.get(k) or {}).get("reads_rig")
        rows.append({"method": e["method"], "version": e["version"], "key": k, "complete": e["complete"],
                     "reads_rig": True if reads is None else bool(reads), "cells": cells[k]})
    return {"columns": columns, "sort": sort, "reference": ref, "reference_asked": reference,
            "lower_is_better": {c: lower_is_better(c) for c in columns}, "level": LEVEL, "draws": DRAWS,
            "seed": SEED, "rows": rows}


def aggregate(results, reference: str | None = DEFAULT_REFERENCE) -> dict:
    """The leaderboard's data.

    Returns:
        ``{"protocols": {protocol: [entry per method version]}, "categories": {protocol: [entry per
        method version and matrix column]}, "matrix": {protocol: {"headline", "lower_is_better",
        "columns", "rows"}}, "headline": {protocol: metric}, "titles": {protocol: what it measures},
        "metrics": [metric columns],
        "methods": {"method/version": method_info}, "run": run.json, "refused": [{"method", "version",
        "protocol", "case_id", "reason"} per row not averaged], "ranking": {protocol: ranking}}``.
        Each entry: method, version, cases, ok, failed, missing, not_supported, invalid, complete,
        every metric (means; null unless complete), seconds_per_case, first_error.

    A ranking (how sure the order is): ``{"columns", "sort", "reference", "reference_asked",
    "lower_is_better", "level", "draws", "seed", "rows"}``; ``columns`` the protocol's
    :func:`view_columns` present in the results (the first sorts), ``reference`` the
    ``method/version`` differences are taken against (None when ``reference`` is not in the
    results). Each row: method, version, key, complete, reads_rig (True when the method's metadata
    does not say: its requests carried the rig) and per column ``{"mean", "lo", "hi"`` (95%
    percentile interval of a bootstrap clustered by (source, target) pair, :mod:`mimicbench.benchmark.intervals`),
    ``"cases", "pairs"`` (with a value), ``"unscored"`` (ok cases without a value, e.g. no role
    labels: never counted as zero), ``"diff", "diff_lo", "diff_hi", "diff_se", "diff_cases"``
    (mean of method - reference over the cases both have a value for, its interval and
    pair-clustered SE), ``"rank", "tied"}``: the rank is 1 + the number of methods surely better
    (the interval of their paired difference excludes 0), so methods with the same rank are tied.
    Only complete methods get values, as in the means.
    """
    info = read_run_info(results)
    expected = info.get("protocols", {})
    metrics = metric_columns()
    checked = metrics + [c.name for c in ResultRecord.COLUMNS if c.kind == "list" and c.dtype.startswith("float")]
    recorded_ids = {p: set(ids) for p, ids in (info.get("case_ids") or {}).items()}
    out = {"protocols": {}, "categories": {}, "matrix": {}, "headline": {}, "titles": {}, "metrics": metrics,
           "methods": {}, "run": {k: v for k, v in info.items() if k != "case_ids"}, "refused": [], "ranking": {}}
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
        out["ranking"][protocol] = _ranking(protocol, pm, head, out["methods"], reference)
    return out
