"""The per-step loss log of a stage: ``loss.csv`` (one row a step) and ``loss.png`` (matplotlib)."""
from __future__ import annotations

import csv
import math
from pathlib import Path


def read_rows(path: Path) -> list[dict]:
    """Rows of a loss.csv as dicts with ``epoch``/``step`` ints and float losses ([] if absent)."""
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        rows = []
        for r in csv.DictReader(f):
            row = {k: (int(v) if k in ("epoch", "step") else float(v) if v != "" else math.nan)
                   for k, v in r.items()}
            rows.append(row)
    return rows


def write_rows(path: Path, rows: list[dict]) -> None:
    """Write ``rows`` (epoch, step, then loss keys: ``total`` first, others sorted) to ``path``."""
    keys = sorted({k for r in rows for k in r} - {"epoch", "step", "total"})
    fields = ["epoch", "step", "total"] + keys
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.8g}" if isinstance(v, float) else v) for k, v in r.items()})
    tmp.replace(path)


def plot(rows: list[dict], path: Path, title: str) -> None:
    """loss.png: every loss key against the global step (thin) with its epoch means (dots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["total"] + sorted({k for r in rows for k in r} - {"epoch", "step", "total"})
    fig, axes = plt.subplots(len(keys), 1, figsize=(7, 2.2 * len(keys)), squeeze=False, sharex=True)
    for ax, key in zip(axes[:, 0], keys):
        pts = [(i, r[key]) for i, r in enumerate(rows) if key in r and math.isfinite(r[key])]
        if not pts:
            continue
        xs, ys = zip(*pts)
        ax.plot(xs, ys, lw=0.8, alpha=0.6, label="step")
        by_epoch: dict[int, list] = {}
        for i, r in enumerate(rows):
            if key in r and math.isfinite(r[key]):
                by_epoch.setdefault(r["epoch"], []).append((i, r[key]))
        ex = [sum(i for i, _ in v) / len(v) for v in by_epoch.values()]
        ey = [sum(y for _, y in v) / len(v) for v in by_epoch.values()]
        ax.plot(ex, ey, "o-", ms=3, lw=1.2, label="epoch mean")
        if min(ys) > 0 and max(ys) / min(ys) > 20:
            ax.set_yscale("log")
        ax.set_ylabel(key)
        ax.grid(alpha=0.3)
    axes[0, 0].set_title(title)
    axes[0, 0].legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel("step")
    fig.tight_layout()
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)
