"""CARD.md: the zoo's statistics table (like the dataset table of the PokeAnimDB paper)."""
from __future__ import annotations

import numpy as np

CARD_HEADER = "| category | characters | joints min / mean / max | clips | frames | faces min / mean / max | vertices mean |"


def character_summary(record) -> dict:
    """What the card needs of a CharacterRecord (no arrays): ID, category, split, skeleton, sizes."""
    return {"character_id": record.character_id, "category": record.category, "split": record.split,
            "skeleton_id": record.skeleton_id, "joints": int(record.num_joints), "faces": int(len(record.faces)),
            "vertices": int(len(record.vertices))}


def zoo_stats(characters, motions) -> dict:
    """Per-category and total statistics from CharacterRecords and MotionRecords."""
    return zoo_stats_from_summaries([character_summary(c) for c in characters],
                                    [(m.character_id, int(m.num_frames)) for m in motions])


def zoo_stats_from_summaries(characters: list[dict], clips: list[tuple[str, int]]) -> dict:
    """Per-category and total statistics from :func:`character_summary` dicts and (character ID,
    frames) of every clip, in the order the characters come (categories in first-seen order)."""
    clips_of: dict[str, list[int]] = {}
    for cid, frames in clips:
        clips_of.setdefault(cid, []).append(frames)

    def row(chars):
        j = np.array([c["joints"] for c in chars])
        f = np.array([c["faces"] for c in chars])
        v = np.array([c["vertices"] for c in chars])
        own = [n for c in chars for n in clips_of.get(c["character_id"], [])]
        return {"characters": len(chars), "joints": [int(j.min()), float(j.mean()), int(j.max())],
                "faces": [int(f.min()), float(f.mean()), int(f.max())], "vertices_mean": float(v.mean()),
                "clips": len(own), "frames": int(sum(own))}

    cats = list(dict.fromkeys(c["category"] for c in characters))
    out = {cat: row([c for c in characters if c["category"] == cat]) for cat in cats}
    if characters:
        out["all"] = row(list(characters))
    return out


def render_card(stats: dict, config: dict, splits: dict[str, int], family: int) -> str:
    """The CARD.md text."""
    lines = ["# mimicbench procedural zoo", "",
             f"Built by `mimicbench zoo` (zoo version {config['zoo_version']}, seed {config['seed']}): "
             f"{config['num_characters']} characters, "
             + (f"{config['motions']} clips spread evenly over them" if config.get("motions") else
                f"{config['clips_per_character']} clips each") + " at "
             f"{config['fps']:g} fps, {config['frames_per_clip']} frames a clip, frame 0 the rest pose.",
             "Metres, Y up, +Z forward. Meshes are closed capsules, one per bone; skin weights from distances "
             "to bone segments (at most 8 influences, rows sum to 1).", "",
             CARD_HEADER, "|---|---:|---:|---:|---:|---:|---:|"]
    for cat, s in stats.items():
        j, f = s["joints"], s["faces"]
        name = f"**{cat}**" if cat == "all" else cat
        lines.append(f"| {name} | {s['characters']} | {j[0]} / {j[1]:.1f} / {j[2]} | {s['clips']} | {s['frames']} "
                     f"| {f[0]} / {f[1]:.0f} / {f[2]} | {s['vertices_mean']:.0f} |")
    lines += ["", f"H2H family: {family} humanoids sharing one skeleton (`skeleton_id` "
              f"`{config['h2h_skeleton_id']}`, same bone names and parents, T-pose), different proportions.",
              "", "Splits: " + ", ".join(f"{k} {v}" for k, v in splits.items()) + ".",
              config["split_rule"], "",
              "Hidden bone roles (`bone_roles`) are ground truth for correspondences only, never a method input.", ""]
    return "\n".join(lines)


SHEET_BEGIN, SHEET_END = "<!-- contact-sheet -->", "<!-- /contact-sheet -->"


def contact_sheet_section(rel_path: str | None, note: str = "") -> str:
    """The CARD.md block that shows the contact sheet (or says why there is none)."""
    body = f"![every character at rest]({rel_path})" if rel_path else f"No contact sheet: {note}"
    extra = f"\n\n{note}" if rel_path and note else ""
    return f"{SHEET_BEGIN}\n## Characters\n\n{body}{extra}\n{SHEET_END}\n"


def add_contact_sheet(dataset, characters=None, timeout: float | None = None) -> dict:
    """Render ``DATASET/card/contact_sheet.png`` through Blender and show it in ``DATASET/CARD.md``.

    Any card (the zoo's, the ingest's) can call this after writing CARD.md: the section between
    the ``contact-sheet`` markers is replaced (or appended), so calling it again is harmless. When
    Blender is missing or fails, the card says so and nothing already written is lost.

    Args:
        dataset: dataset folder holding CARD.md (created if missing) and the characters table.
        characters: CharacterRecords to show instead of reading the table.

    Returns:
        ``{"path": Path | None, "error": str | None}``.
    """
    from pathlib import Path

    from mimicbench.datagen.render.contact_sheet import DEFAULT_PATH, write_contact_sheet
    from mimicbench.datagen.render.render import RenderError

    root = Path(dataset)
    try:
        path, error = write_contact_sheet(root, root / DEFAULT_PATH, characters, timeout=timeout), None
        section = contact_sheet_section(DEFAULT_PATH.as_posix(), "Rendered with Blender's Workbench engine "
                                        "(`mimicbench render DATASET --contact-sheet`); each panel is framed on its own.")
    except (RenderError, ValueError) as exc:
        path, error = None, str(exc)
        section = contact_sheet_section(None, error)
    put_card_section(root / "CARD.md", SHEET_BEGIN, SHEET_END, section)
    return {"path": path, "error": error}


def put_card_section(card, begin: str, end: str, section: str) -> None:
    """Write ``section`` (which starts with ``begin`` and ends with ``end``) into the Markdown file
    ``card``: it replaces the text between an earlier ``begin``/``end`` pair, or is appended (the file
    is created when missing), so a card's generated sections can be rewritten any number of times."""
    from pathlib import Path

    from mimicbench.schemas.manifest import atomic_write_bytes

    card = Path(card)
    text = card.read_text() if card.exists() else ""
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        # the old end marker's own line break goes; the blank line before the next section stays
        text = head + section + rest.split(end, 1)[1].removeprefix("\n")
    else:
        text = text.rstrip("\n") + ("\n\n" if text else "") + section
    atomic_write_bytes(card, text.encode())
