"""Leaderboard plots (matplotlib, PNG bytes): one figure per protocol.

Left: the headline metric per category for every method, on a log axis when the values span more
than a factor of 10 (one far-off category, like a flat snake under unit-height PMD, then no
longer squashes the others). Right: the protocol's edge-length score per category (1 is perfect).
Missing cells (failed, missing or unsupported cases) are left out, never drawn as zero.
"""
from __future__ import annotations

import io

MARKERS = "osD^vP*Xh<>p"
LOG_SPAN = 10.0  # log axis when max / min exceeds this


def _values(matrix: dict) -> list[float]:
    return [v for row in matrix["rows"] for v in row["cells"].values() if v is not None]


def uses_log_axis(values) -> bool:
    """Whether values (all > 0) span more than :data:`LOG_SPAN`."""
    vals = [v for v in values if v is not None]
    return bool(vals) and min(vals) > 0 and max(vals) / min(vals) > LOG_SPAN


def protocol_figure_png(protocol: str, matrix: dict, categories: list[dict], els_metric: str | None,
                        dpi: int = 100) -> bytes:
    """PNG of the protocol's figure.

    Args:
        protocol: its name (titles).
        matrix: ``aggregate(...)["matrix"][protocol]``.
        categories: ``aggregate(...)["categories"][protocol]`` (per method and column).
        els_metric: the ELS column to plot on the right, or None for the left panel alone.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = matrix["columns"]
    head = matrix["headline"]
    panels = 2 if els_metric else 1
    fig, axes = plt.subplots(1, panels, figsize=(max(6.0, 0.9 * len(cols) + 3) * panels / 1.4, 4.0), squeeze=False)
    axes = axes[0]
    cmap = plt.get_cmap("tab10")
    for i, row in enumerate(matrix["rows"]):
        name = f"{row['method']} v{row['version']}"
        xs = [j for j, c in enumerate(cols) if row["cells"].get(c) is not None]
        ys = [row["cells"][cols[j]] for j in xs]
        axes[0].plot(xs, ys, marker=MARKERS[i % len(MARKERS)], color=cmap(i % 10), linestyle="-", linewidth=0.8,
                     alpha=0.9, label=name)
    if uses_log_axis(_values(matrix)):
        axes[0].set_yscale("log")
        axes[0].grid(True, which="both", axis="y", alpha=0.3)
    else:
        axes[0].grid(True, axis="y", alpha=0.3)
    better = "lower" if matrix["lower_is_better"] else "higher"
    axes[0].set_title(f"{protocol}: {head} per category ({better} is better)", fontsize=10)
    if els_metric:
        ecols = [c for c in cols if c != "all"]
        for i, row in enumerate(matrix["rows"]):
            by = {c["category"]: c.get(els_metric) for c in categories
                  if c["method"] == row["method"] and c["version"] == row["version"]}
            xs = [j for j, c in enumerate(ecols) if by.get(c) is not None]
            axes[1].plot(xs, [by[ecols[j]] for j in xs], marker=MARKERS[i % len(MARKERS)], color=cmap(i % 10),
                         linestyle="-", linewidth=0.8, alpha=0.9)
        axes[1].axhline(1.0, color="grey", linewidth=0.6, linestyle=":")
        axes[1].set_title(f"{protocol}: {els_metric} per category (1 is perfect)", fontsize=10)
        axes[1].set_xticks(range(len(ecols)))
        axes[1].set_xticklabels(ecols, rotation=30, ha="right", fontsize=8)
        axes[1].grid(True, axis="y", alpha=0.3)
    axes[0].set_xticks(range(len(cols)))
    axes[0].set_xticklabels(cols, rotation=30, ha="right", fontsize=8)
    if "all" in cols:
        axes[0].axvline(len(cols) - 1.5, color="grey", linewidth=0.6, linestyle=":")
    if matrix["rows"]:
        axes[0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()
