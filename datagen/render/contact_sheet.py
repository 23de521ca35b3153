"""A contact sheet: the dataset's characters at rest on one labelled PNG (one Blender process)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mimicbench.datagen.render.panel import Panel
from mimicbench.datagen.render.render import render_sheet
from mimicbench.schemas.shards import read_records

DEFAULT_PATH = Path("card") / "contact_sheet.png"
MAX_CHARACTERS = 60


def pick_characters(characters, limit: int = MAX_CHARACTERS) -> list:
    """Up to ``limit`` characters with a mesh, taken round-robin over categories (each in ID order),
    so every category shows even when one dominates; returned grouped by category."""
    by_cat: dict[str, list] = {}
    for c in sorted((c for c in characters if len(c.faces)), key=lambda c: c.character_id):
        by_cat.setdefault(c.category, []).append(c)
    picked, i = [], 0
    while len(picked) < limit and any(i < len(v) for v in by_cat.values()):
        picked += [v[i] for v in by_cat.values() if i < len(v)][: limit - len(picked)]
        i += 1
    order = list(by_cat)
    return sorted(picked, key=lambda c: (order.index(c.category), c.character_id))


def contact_sheet_panels(characters) -> list[Panel]:
    """One rest-pose panel a character, labelled with its ID, category, joint count and height (each
    panel is framed on its own, so the height gives the scale)."""
    return [Panel(c.vertices, c.faces, f"{c.character_id}\n{c.category}, {len(c.parents)} joints, "
                  f"{float(np.ptp(np.asarray(c.vertices)[:, 1])):.2f} m tall", role="rest") for c in characters]


def write_contact_sheet(dataset, out_png=None, characters=None, limit: int = MAX_CHARACTERS, panel_px: int = 240,
                        timeout: float | None = None) -> Path:
    """Render the contact sheet of ``dataset`` (default ``DATASET/card/contact_sheet.png``); returns its path.

    Args:
        dataset: dataset folder (its ``characters`` table is read unless ``characters`` is given).
        characters: CharacterRecords to show instead of reading them.
        limit: at most this many characters (see :func:`pick_characters`).
        panel_px: pixels of each square panel.

    Raises:
        ValueError: no character has a mesh.
        mimicbench.datagen.render.RenderError: Blender is missing, crashed or timed out.
    """
    chars = read_records(dataset, "characters") if characters is None else list(characters)
    total = sum(1 for c in chars if len(c.faces))
    shown = pick_characters(chars, limit)
    if not shown:
        raise ValueError(f"{dataset}: no character with a mesh to put on a contact sheet")
    columns = min(len(shown), max(4, math.ceil(math.sqrt(len(shown) * 1.6))))
    title = f"{Path(dataset).name}: {len(shown)} of {total} characters at rest" if len(shown) < total else \
        f"{Path(dataset).name}: {total} characters at rest"
    out = Path(out_png) if out_png is not None else Path(dataset) / DEFAULT_PATH
    return render_sheet(contact_sheet_panels(shown), out, columns=columns, title=title, width=panel_px,
                        height=panel_px, timeout=timeout)
