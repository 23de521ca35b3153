"""Checks on result rows before the leaderboard averages them.

A results folder is plain files a user can edit or copy: a row written by hand with ``pmd = -1``,
one method's rows copied into another's folder, a case that is not among the benchmark's cases,
or an ``ok`` row whose metric is NaN would otherwise be averaged like any other. Each row is
checked against its folder (method and version), the run's cases (``run.json``: the protocols
and, when recorded, each protocol's case IDs) and the metric ranges below; a row that fails is
shown with the reason and never averaged, and its method version gets no average.

Metric ranges (see :mod:`mimicbench.schemas.result`): every PMD (``pmd*``, x100 or centimetres) is a mean
of distances, finite and >= 0; ``els*`` is 1 - a mean of |ratio - 1|, finite and <= 1;
``seconds`` finite and >= 0.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from mimicbench.schemas.result import STATUSES


def metric_range_problem(name: str, value) -> str | None:
    """Why ``value`` is not a valid ``name`` metric (None when it is, or when it is null)."""
    if value is None:
        return None
    values = list(np.ravel(value)) if isinstance(value, (list, tuple, np.ndarray)) else [value]  # per-frame lists
    for v in values:
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            return f"{name} = {v!r} is not a number"
        if math.isnan(v):
            return f"{name} is NaN"
        if math.isinf(v):
            return f"{name} is {'+' if v > 0 else '-'}infinite"
        if name.startswith("pmd") and v < 0:
            return f"{name} = {v:g} is negative (a PMD is a mean distance, >= 0)"
        if name.startswith("els") and v > 1:
            return f"{name} = {v:g} is above 1 (ELS is 1 - mean |edge ratio - 1|, at most 1)"
    return None


def row_problem(row, method: str, version: str, metrics, case_ids: set | None = None,
                protocols=None) -> str | None:
    """Why a result row cannot be averaged (None when it can).

    Args:
        row: a :class:`~mimicbench.schemas.result.ResultRecord`.
        method, version: the folder it was read from (``RESULTS/<method>/<version>``).
        metrics: the metric columns to range-check (scalar or per-frame list columns).
        case_ids: the protocol's case IDs (None: not recorded, not checked).
        protocols: the run's protocols (None: not recorded, not checked).
    """
    if row.method != method or row.method_version != version:
        return (f"a row of {row.method} v{row.method_version} in the folder of {method} v{version} (copied from "
                f"another method's results?)")
    if row.status not in STATUSES:
        return f"status {row.status!r}; expected one of {', '.join(STATUSES)}"
    if protocols is not None and row.protocol not in protocols:
        return f"protocol {row.protocol!r} is not among the run's protocols ({', '.join(sorted(protocols)) or 'none'})"
    if case_ids is not None and row.case_id not in case_ids:
        return f"case {row.case_id!r} is not among the {len(case_ids)} {row.protocol} cases of the run"
    problem = metric_range_problem("seconds", row.seconds)
    if problem or row.seconds is None:
        return problem or "seconds is null"
    if row.seconds < 0:
        return f"seconds = {row.seconds:g} is negative"
    if row.status != "ok":
        return None
    for name in metrics:
        problem = metric_range_problem(name, getattr(row, name, None))
        if problem:
            return problem
    return None
