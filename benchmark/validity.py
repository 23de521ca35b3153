"""The validity table: can each score tell a corrupted transfer from its uncorrupted method?

Each probe (:mod:`mimicbench.baselines.probes`) corrupts a right transfer in one known way. For every
protocol column and probe, the table gives the paired difference ``probe - uncorrupted`` over the
cases both scored, its standard error clustered by (source, target) pair
(:func:`mimicbench.benchmark.intervals.pair_clustered_se`), ``z = difference / SE`` signed so that positive
means "the probe scores worse", and whether the column **detects** the corruption (``z > 2``).
"""
from __future__ import annotations

import json
from pathlib import Path

from mimicbench.benchmark.intervals import pair_clustered_se, paired_values
from mimicbench.benchmark.results import method_versions, method_dir, read_results

PROBES = (
    ("probe_role_transfer", "probe_mirror", "left/right mirror"),
    ("probe_role_transfer", "probe_fore_hind", "fore/hind swap"),
    ("probe_role_transfer", "probe_frozen_limb", "a frozen limb"),
    ("probe_role_transfer", "probe_noise15", "15 degree rotation noise"),
    ("probe_role_transfer", "probe_half_angle", "half the rotation angle"),
    ("probe_role_transfer", "probe_rest", "the target at rest"),
    ("nearest_joint", "nearest_joint_mirrored", "nearest_joint, target mirrored"),
    ("nearest_joint", "nearest_joint_fore_hind", "nearest_joint, target reflected fore-hind"),
)
"""(uncorrupted method, probe, corruption in words)."""

COLUMNS = {
    "h2h": (("pmd", "lower"), ("els", "higher"), ("semantic_deg", "lower"), ("out_of_range", "lower")),
    "h2h_xskel": (("pmd", "lower"), ("els", "higher"), ("semantic_deg", "lower"), ("out_of_range", "lower")),
    "cct": (("pmd", "lower"), ("pmd_aligned", "lower"), ("els_forward", "higher"), ("semantic_deg", "lower"),
            ("out_of_range", "lower")),
}
"""Per protocol, the columns judged and which direction is better."""

DETECTS_Z = 2.0


def methods_to_run() -> list[str]:
    """Every uncorrupted method and probe of :data:`PROBES`, each once."""
    out = []
    for base, probe, _ in PROBES:
        out += [m for m in (base, probe) if m not in out]
    return out


def _column_values(results: Path, method: str) -> dict:
    """{protocol: {column: {case_id: value or None}}} of a method's ok rows (newest version stored)."""
    versions = [v for m, v in method_versions(results) if m == method]
    if not versions:
        return {}
    table = read_results(method_dir(results, method, versions[-1])).to_pylist()
    out: dict = {}
    for row in table:
        if row.get("status") != "ok":
            continue
        cols = out.setdefault(row["protocol"], {})
        for col, _ in COLUMNS.get(row["protocol"], ()):
            cols.setdefault(col, {})[row["case_id"]] = row.get(col)
    return out


def validity_table(results) -> list[dict]:
    """One row per (protocol, probe, column): ``diff``, ``se``, ``z``, ``detects``, ``cases``, ``pairs``.

    ``z`` is positive when the probe scores worse than its uncorrupted method; ``detects`` is
    ``z > 2``. A column with no common case, or fewer than two pairs, has ``z`` None.
    """
    results = Path(results)
    cache: dict = {}
    rows = []
    for base, probe, words in PROBES:
        for name in (base, probe):
            if name not in cache:
                cache[name] = _column_values(results, name)
        for protocol, columns in COLUMNS.items():
            for col, better in columns:
                a = cache[probe].get(protocol, {}).get(col, {})
                b = cache[base].get(protocol, {}).get(col, {})
                va, vb, pairs = paired_values(a, b)
                row = {"protocol": protocol, "probe": probe, "base": base, "corruption": words, "column": col,
                       "cases": int(len(va)), "pairs": len(set(pairs)), "diff": None, "se": None, "z": None,
                       "detects": False}
                if len(va):
                    d = va - vb
                    se = pair_clustered_se(d, pairs)
                    worse = d.mean() if better == "lower" else -d.mean()
                    row.update(diff=float(d.mean()), se=se)
                    if se == se and se > 0:
                        row.update(z=float(worse / se), detects=bool(worse / se > DETECTS_Z))
                rows.append(row)
    return rows


def markdown_validity(rows: list[dict]) -> str:
    """The table as Markdown: one block per protocol, a row per probe, a cell per column
    (``difference (z)``, with a check mark where the column detects the corruption)."""
    out = []
    for protocol, columns in COLUMNS.items():
        mine = [r for r in rows if r["protocol"] == protocol and r["cases"]]
        if not mine:
            continue
        names = [c for c, _ in columns]
        out += [f"### {protocol}", "", "| corruption | cases (pairs) | " + " | ".join(names) + " |",
                "|---|---|" + "---|" * len(names)]
        for base, probe, words in PROBES:
            cells = {r["column"]: r for r in mine if r["probe"] == probe}
            if not cells:
                continue
            n = max(r["cases"] for r in cells.values())
            p = max(r["pairs"] for r in cells.values())
            shown = []
            for c in names:
                r = cells.get(c)
                if r is None or r["diff"] is None:
                    shown.append("—")
                elif r["z"] is None:
                    shown.append(f"{r['diff']:+.3g} (z n/a)")
                else:
                    shown.append(f"{r['diff']:+.3g} (z {r['z']:+.1f}){' ✓' if r['detects'] else ' ✗'}")
            out.append(f"| {words} (`{probe}` vs `{base}`) | {n} ({p}) | " + " | ".join(shown) + " |")
        out.append("")
    out.append("Cell: mean paired difference probe - uncorrupted (column units), z = difference / SE clustered by "
               "(source, target) pair, signed so that z > 0 means the probe scores worse; ✓ detects (z > 2), "
               "✗ does not.")
    return "\n".join(out)


def write_validity(results, rows: list[dict]) -> Path:
    """``validity.md`` and ``validity.json`` in the results folder; returns the Markdown's path."""
    results = Path(results)
    (results / "validity.json").write_text(json.dumps(rows, indent=1))
    path = results / "validity.md"
    path.write_text(markdown_validity(rows) + "\n")
    return path
