"""Write the leaderboard: Markdown, CSV, JSON and a self-contained HTML page with plots."""
from __future__ import annotations

import base64
import csv
import html
import io
import json
from pathlib import Path

from benchmark.aggregate import aggregate

COLUMNS = (("method", "method"), ("version", "version"), ("cases", "cases"), ("failed", "failed"),
           ("missing", "missing"), ("pmd", "PMD x100"), ("pmd_squared", "PMD² x100"), ("els", "ELS"),
           ("els_forward", "ELS fwd"), ("seconds_per_case", "s/case"))
PROTOCOL_TITLES = {"h2h": "h2h: humanoid to humanoid, ground truth (PMD lower is better, ELS 1 is perfect)",
                   "cct": "cct: cross-category cycle src -> tgt -> src (PMD of the return; ELS fwd on the target)"}


def _fmt(value, key) -> str:
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.4f}" if key in ("seconds_per_case",) else f"{value:.3f}"
    return str(value)


def markdown_tables(agg: dict) -> str:
    """One Markdown table per protocol."""
    lines = []
    for protocol, entries in agg["protocols"].items():
        lines.append(f"### {PROTOCOL_TITLES.get(protocol, protocol)}\n")
        lines.append("| " + " | ".join(t for _, t in COLUMNS) + " |")
        lines.append("|" + "---|" * len(COLUMNS))
        for e in entries:
            lines.append("| " + " | ".join(_fmt(e.get(k), k) for k, _ in COLUMNS) + " |")
        lines.append("")
    return "\n".join(lines)


def _plot_png(agg: dict, protocol: str) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cats = [c for c in agg["categories"].get(protocol, [])]
    methods = sorted({c["method"] for c in cats})
    keys = sorted({c["category"] for c in cats})
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.6))
    width = 0.8 / max(1, len(methods))
    for mi, m in enumerate(methods):
        for ax, metric in zip(axes, ("pmd", "els")):
            vals = [next((c[metric] for c in cats if c["method"] == m and c["category"] == k), None) for k in keys]
            xs = [i + mi * width for i in range(len(keys))]
            ax.bar(xs, [v if v is not None else 0 for v in vals], width, label=m)
    els_values = [c["els"] for c in cats if c["els"] is not None]
    if els_values:
        axes[1].set_ylim(max(0.0, min(els_values) - 0.02), 1.0)
    for ax, title in zip(axes, ("PMD x100 (lower is better)", "ELS (1 is perfect)")):
        ax.set_xticks([i + 0.4 - width / 2 for i in range(len(keys))])
        ax.set_xticklabels(keys, rotation=30, ha="right", fontsize=7)
        ax.set_title(f"{protocol}: {title}", fontsize=9)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def html_page(agg: dict) -> str:
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>mimicbench leaderboard</title>",
             "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
             "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}"
             "td:first-child{text-align:left}</style></head><body><h1>mimicbench leaderboard</h1>",
             "<p>PMD x100: mean vertex distance in percent of the target's height. ELS: 1 - mean |edge "
             "length ratio - 1|. A method with failed or missing cases shows no average (—).</p>"]
    for protocol, entries in agg["protocols"].items():
        parts.append(f"<h2>{html.escape(PROTOCOL_TITLES.get(protocol, protocol))}</h2><table><tr>")
        parts.append("".join(f"<th>{html.escape(t)}</th>" for _, t in COLUMNS) + "</tr>")
        for e in entries:
            parts.append("<tr>" + "".join(f"<td>{html.escape(_fmt(e.get(k), k))}</td>" for k, _ in COLUMNS) + "</tr>")
        parts.append("</table>")
        parts.append(f"<h3>per category</h3><img alt='{protocol} per category' "
                     f"src='data:image/png;base64,{_plot_png(agg, protocol)}'>")
        parts.append("<table><tr><th>method</th><th>category</th><th>cases</th><th>failed</th>"
                     "<th>PMD x100</th><th>ELS</th></tr>")
        for c in agg["categories"].get(protocol, []):
            parts.append("<tr>" + "".join(f"<td>{html.escape(_fmt(c.get(k), k))}</td>"
                                          for k in ("method", "category", "cases", "failed", "pmd", "els")) + "</tr>")
        parts.append("</table>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_leaderboard(results, out_dir=None) -> dict[str, Path]:
    """Write leaderboard.md/.csv/.json/.html into ``out_dir`` (default: the results folder)."""
    agg = aggregate(results)
    out = Path(out_dir or results)
    out.mkdir(parents=True, exist_ok=True)
    paths = {ext: out / f"leaderboard.{ext}" for ext in ("md", "csv", "json", "html")}
    paths["md"].write_text("# mimicbench leaderboard\n\n" + markdown_tables(agg))
    paths["json"].write_text(json.dumps(agg, indent=2) + "\n")
    with open(paths["csv"], "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["protocol"] + [k for k, _ in COLUMNS] + ["complete", "first_error"])
        for protocol, entries in agg["protocols"].items():
            for e in entries:
                w.writerow([protocol] + [e.get(k) for k, _ in COLUMNS] + [e["complete"], e["first_error"]])
    paths["html"].write_text(html_page(agg))
    return paths
