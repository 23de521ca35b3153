"""A dataset's Table 1 (PokeAnimDB's dataset table) beside the paper's figures, and distribution plots.

PokeAnimDB (MimiCAT, 2025) reports 975 characters, 28,809 motions, 4.47 million frames, skeletons
of 11 to 241 joints and about 384k correspondence pairs; only these totals are reproduced here
(the paper's per-category split is not), so per-category rows show ours alone.

How ~384k pairs arise from 975 characters: the paper does not say; the count matches the
unordered pairs of its training characters under a 90/10 split, C(877, 2) = 384,126 (877 =
0.9 x 975), or equally the ordered pairs of 620 characters, 620 x 619 = 383,780. Our
``--all-pairs`` set is every *ordered* pair within each split (80/10/10 by category): at 975
characters about 780 x 779 + 2 x (98 x 97) = 626k, the unordered count being half of that.

Everything is read from the manifest-listed columns that count (IDs, categories, parents,
frame counts), never the transforms, so a 4.5-million-frame table costs seconds and little memory.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.compute as pc

from mimicbench.datagen.zoo.card import put_card_section
from mimicbench.schemas.shards import has_table, read_table

PAPER = {"characters": 975, "motions": 28_809, "frames": 4_470_000, "joints_min": 11, "joints_max": 241,
         "pairs": 384_000}
BEGIN, END = "<!-- table1 -->", "<!-- /table1 -->"


def table1(dataset) -> dict:
    """``{"all": row, category: row...}`` with characters, motions, frames, joints min/mean/max, plus
    ``pairs`` and ``cases`` totals; and ``_joints``/``_frames``/``_clips`` arrays for the plots."""
    root = Path(dataset)
    chars = read_table(root, "characters", columns=["character_id", "category", "parents"])
    ids = chars.column("character_id").to_pylist()
    cats = chars.column("category").to_pylist()
    joints = np.asarray(pc.list_value_length(chars.column("parents")).to_numpy(zero_copy_only=False), int)
    clip_frames: dict[str, list[int]] = {c: [] for c in ids}
    if has_table(root, "motions"):
        mot = read_table(root, "motions", columns=["character_id", "num_frames"])
        for cid, f in zip(mot.column("character_id").to_pylist(), mot.column("num_frames").to_pylist()):
            clip_frames.setdefault(cid, []).append(int(f))

    def row(sel):
        own = [f for i in sel for f in clip_frames.get(ids[i], [])]
        j = joints[sel] if len(sel) else np.zeros(1, int)
        return {"characters": len(sel), "motions": len(own), "frames": int(sum(own)),
                "joints_min": int(j.min()), "joints_mean": float(j.mean()), "joints_max": int(j.max())}

    out = {"all": row(list(range(len(ids))))}
    for cat in dict.fromkeys(cats):
        out[cat] = row([i for i, c in enumerate(cats) if c == cat])
    out["pairs"] = read_table(root, "pairs", columns=["pair_id"]).num_rows if has_table(root, "pairs") else 0
    out["cases"] = read_table(root, "cases", columns=["case_id"]).num_rows if has_table(root, "cases") else 0
    out["_joints"] = {cat: joints[[i for i, c in enumerate(cats) if c == cat]].tolist() for cat in dict.fromkeys(cats)}
    out["_clips"] = {cat: [len(clip_frames.get(ids[i], [])) for i, c in enumerate(cats) if c == cat]
                     for cat in dict.fromkeys(cats)}
    out["_frames"] = [f for fs in clip_frames.values() for f in fs]
    return out


def render_table1(t: dict, plots: dict[str, str] | None = None) -> str:
    """The CARD.md section: ours beside the paper's totals, per-category rows, the plots."""
    a = t["all"]
    lines = [BEGIN, "## Table 1: this dataset beside PokeAnimDB", "",
             "| | characters | motions | frames | joints min | joints max | correspondence pairs |",
             "|---|---:|---:|---:|---:|---:|---:|",
             f"| PokeAnimDB (paper) | {PAPER['characters']:,} | {PAPER['motions']:,} | 4.47M | {PAPER['joints_min']} "
             f"| {PAPER['joints_max']} | ~384k |",
             f"| this dataset | {a['characters']:,} | {a['motions']:,} | {a['frames'] / 1e6:.2f}M ({a['frames']:,}) "
             f"| {a['joints_min']} | {a['joints_max']} | {t['pairs']:,} |", "",
             "Per category (the paper's per-category figures are not reproduced here):", "",
             "| category | characters | motions | frames | joints min / mean / max |", "|---|---:|---:|---:|---:|"]
    for cat, r in t.items():
        if cat in ("all", "pairs", "cases") or cat.startswith("_"):
            continue
        lines.append(f"| {cat} | {r['characters']:,} | {r['motions']:,} | {r['frames']:,} | "
                     f"{r['joints_min']} / {r['joints_mean']:.1f} / {r['joints_max']} |")
    lines += ["", f"Benchmark cases: {t['cases']:,}. Pairs: every ordered pair within each split (see "
              "`datagen/zoo/table1.py` for how the paper's ~384k count arises).", ""]
    for title, rel in (plots or {}).items():
        lines += [f"![{title}]({rel})", ""]
    lines.append(END)
    return "\n".join(lines) + "\n"


def plot_distributions(t: dict, folder: Path) -> dict[str, str]:
    """Histograms of joints per character and clips per character (by category) and of frames per
    clip, as PNGs in ``folder``; returns {title: path relative to the dataset}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for key, title, xlabel in (("_joints", "joints per character", "joints"),
                               ("_clips", "clips per character", "clips")):
        fig, ax = plt.subplots(figsize=(7, 3.2))
        data = [v for v in t[key].values()]
        ax.hist(data, bins=30, stacked=True, label=list(t[key]))
        ax.set_xlabel(xlabel)
        ax.set_ylabel("characters")
        ax.set_title(title + " (stacked by category)")
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = folder / f"{key[1:]}.png"
        fig.savefig(path, dpi=100, metadata={"Software": None})
        plt.close(fig)
        out[title] = f"{folder.name}/{path.name}"
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.hist(t["_frames"] or [0], bins=30)
    ax.set_xlabel("frames (30 fps)")
    ax.set_ylabel("clips")
    ax.set_title("frames per clip")
    fig.tight_layout()
    path = folder / "frames.png"
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)
    out["frames per clip"] = f"{folder.name}/{path.name}"
    return out


def add_table1(dataset) -> dict:
    """Compute Table 1 of ``dataset``, plot the distributions into ``card/`` and put both in CARD.md
    (replacing an earlier Table 1 section); returns the table."""
    root = Path(dataset)
    t = table1(root)
    section = render_table1(t, plot_distributions(t, root / "card"))
    put_card_section(root / "CARD.md", BEGIN, END, section)
    return t
