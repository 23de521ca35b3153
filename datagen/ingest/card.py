"""CARD.md for an ingested dataset: the statistics table the zoo writes (per category:
characters, joints, clips, frames, faces), plus skeleton families, inferred categories and the
clips' reproduction error against the files."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

from mimicbench.datagen.zoo.card import CARD_HEADER, zoo_stats
from mimicbench.schemas.manifest import atomic_write_bytes


def render_card(characters, motions, config: dict) -> str:
    """The CARD.md text of ingested ``characters`` and ``motions`` (records)."""
    stats = zoo_stats(characters, motions)
    lines = ["# mimicbench ingested assets", "",
             f"Built by `mimicbench datagen ingest` through Blender: {len(characters)} characters, {len(motions)} clips. "
             "Metres, Y up, +Z forward; rest pose = the file's bind pose; every clip starts from the file's default pose.",
             "", CARD_HEADER, "|---|---:|---:|---:|---:|---:|---:|"]
    for cat, s in stats.items():
        j, f = s["joints"], s["faces"]
        name = f"**{cat}**" if cat == "all" else cat
        lines.append(f"| {name} | {s['characters']} | {j[0]} / {j[1]:.1f} / {j[2]} | {s['clips']} | {s['frames']} "
                     f"| {f[0]} / {f[1]:.0f} / {f[2]} | {s['vertices_mean']:.0f} |")
    families = Counter(c.skeleton_id for c in characters)
    shared = {sid: sorted(c.character_id for c in characters if c.skeleton_id == sid)
              for sid, n in families.items() if n > 1}
    lines += ["", f"Skeleton families (characters sharing bone names and parents, `skeleton_id`): {len(shared)}."]
    for sid, ids in sorted(shared.items()):
        lines.append(f"- `{sid}`: {', '.join(ids)}")
    inferred = [c for c in characters if (c.meta or {}).get("category", {}).get("source") == "inferred"]
    lines += ["", f"Categories inferred from bone names and the skeleton (no `--category-map` entry): {len(inferred)}."]
    for c in inferred:
        ev = c.meta["category"]["evidence"]
        lines.append(f"- {c.character_id}: {c.category} ({ev.get('rule')})")
    errs = [clip.get("reproduction_error", {}).get("max_pct") for c in characters
            for clip in (c.meta or {}).get("ingest", {}).get("clips", [])]
    errs = [e for e in errs if e is not None]
    if errs:
        lines += ["", f"Clips posed by linear blend skinning vs Blender's evaluation of the file: largest error "
                      f"{max(errs):.4f}% of height over {len(errs)} clips."]
    lines += ["", f"BVH scale: {config.get('bvh_scale')} (metres per file unit, or auto: chosen per file from its rest "
              "skeleton, recorded in each character's meta.ingest).",
              "Splits: " + ", ".join(f"{k} {v}" for k, v in sorted(Counter(c.split for c in characters).items())) + ".", ""]
    return "\n".join(lines)


def write_card(out_dir, characters, motions, config: dict) -> Path:
    """Write ``out_dir/CARD.md`` atomically; returns its path."""
    path = Path(out_dir) / "CARD.md"
    atomic_write_bytes(path, render_card(characters, motions, config).encode())
    return path
